// Images on the host: load PNG/JPEG (stb_image), resize, save PNG (stb_image_write), and move them to and
// from device tensors. Pixels are float RGB in [0,1], stored planar [3,H,W] like a tensor.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "host/tensor.hpp"

namespace stylerf::io {

struct Image {
  int width = 0, height = 0;
  std::vector<float> data;  // [3][height][width], planar RGB

  float& at(int c, int y, int x) { return data[(size_t(c) * height + y) * width + x]; }
  float at(int c, int y, int x) const { return data[(size_t(c) * height + y) * width + x]; }
};

// Loads an 8-bit or 16-bit PNG/JPEG/BMP/TGA... as RGB in [0,1]. Grey images are replicated to RGB. An alpha
// channel is composited over `background` when one is given (Blender scenes: white), else dropped.
// When `alpha` is given it receives the alpha channel, [height * width] in [0,1], or is left empty when
// the file has none (scenes need both the composited colour and the mask).
// Errors name the file: missing, not an image / unreadable, zero size, or larger than kMaxImageSide per
// side or kMaxImagePixels in all (checked from the header, before decoding).
constexpr int kMaxImageSide = 32768;
constexpr int64_t kMaxImagePixels = 64000000;  // ~1 GB once decoded (RGBA bytes + planar floats)
Image load_image(const std::string& path, const std::array<float, 3>* background = nullptr,
                 std::vector<float>* alpha = nullptr);

// "" when `path` holds an image load_image can decode (header check only), else the reason (missing,
// an unsupported format such as WebP, corrupt): folders of images use it to skip what cannot be read.
// size, when given, gets the width and height from the same read of the header.
std::string image_unreadable_reason(const std::string& path, std::array<int, 2>* size = nullptr);
// A JPEG's EXIF orientation tag (1..8; 1 = as stored), or 0 when the file has none (or is not a JPEG).
int exif_orientation(const std::string& path);

// Resamples to width x height, each axis separately: shrinking averages the source area each output
// pixel covers (fractional coverage at the edges; no aliasing), enlarging is bilinear with pixel centres
// aligned (x_src = (x_dst + 0.5) * scale - 0.5) and edges repeated.
Image resize(const Image& img, int width, int height);

// The size whose longer side is `longer` (keeping the aspect ratio), each side rounded to a multiple of
// `multiple` (at least `multiple`).
std::array<int, 2> fit_size(int width, int height, int longer, int multiple);

// Writes an 8-bit RGB PNG, atomically. Values are clamped to [0,1] and rounded.
void save_png(const std::string& path, const Image& img);  // refuses a .jpg/.jpeg name (use save_image)
// By the name's extension: .png (PNG) or .jpg/.jpeg (JPEG, quality 95); anything else is an error naming
// the file, so PNG bytes never land in a file called .jpg.
void save_image(const std::string& path, const Image& img);

// An image from interleaved RGB [h][w][3] (what renderers return).
Image from_interleaved(const std::vector<float>& rgb, int w, int h);

// The same 8-bit RGB PNG as save_png's, as bytes (a server's answer).
std::string encode_png(const Image& img);

// Image -> device tensor [1,3,H,W]; tensor [N,3,H,W] (image n) -> Image, values as they are (unclamped).
host::Tensor to_tensor(const Image& img);
Image from_tensor(const host::Tensor& t, int n = 0);

}  // namespace stylerf::io
