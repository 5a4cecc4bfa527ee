#include "lib/io/image.hpp"

#include <stb/stb_image.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <filesystem>
#include <memory>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::io {

using host::Error;

namespace {
// stb_image 2.27 (Debian's) writes past a 257-entry array when a JPEG Huffman table declares more than 256
// codes (found by fuzz/fuzz_image; fixed upstream in 2.28). Such tables are refused here before stb sees
// them. Every DHT segment is checked: in entropy-coded data 0xFF is always followed by 0x00 or a restart
// marker, so FF C4 only ever starts a real segment.
std::string jpeg_huffman_problem(const std::string& b) {
  // What stb takes for a JPEG: fill bytes 0xFF, then the SOI marker D8.
  size_t soi = 0;
  while (soi < b.size() && static_cast<unsigned char>(b[soi]) == 0xFF) ++soi;
  if (soi == 0 || soi >= b.size() || static_cast<unsigned char>(b[soi]) != 0xD8) return "";
  auto at = [&](size_t i) { return static_cast<unsigned char>(b[i]); };
  for (size_t i = 0; i + 3 < b.size(); ++i) {
    if (at(i) != 0xFF || at(i + 1) != 0xC4) continue;
    const size_t len = size_t(at(i + 2)) << 8 | at(i + 3);
    size_t p = i + 4;
    const size_t end = std::min(b.size(), i + 2 + len);
    while (p < end) {
      // stb reads missing bytes at the end of a file as zeros: count what is there.
      int n = 0;
      for (size_t k = 1; k <= 16 && p + k < b.size(); ++k) n += at(p + k);
      if (n > 256) return "a JPEG Huffman table declares " + std::to_string(n) + " codes (at most 256)";
      p += 17 + size_t(n);
    }
  }
  return "";
}

const stbi_uc* bytes_of(const std::string& b) { return reinterpret_cast<const stbi_uc*>(b.data()); }
int size_of(const std::string& b) { return int(std::min<size_t>(b.size(), size_t(INT32_MAX))); }
}  // namespace

std::string image_unreadable_reason(const std::string& path, std::array<int, 2>* size) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return "file does not exist";
  if (std::filesystem::is_directory(path, ec)) return "a folder, not an image file";
  std::string b;
  try {
    b = host::read_file(path);
  } catch (const Error&) {
    return "not readable";
  }
  if (const std::string why = jpeg_huffman_problem(b); !why.empty()) return "corrupt JPEG (" + why + ")";
  int w = 0, h = 0, comp = 0;
  if (stbi_info_from_memory(bytes_of(b), size_of(b), &w, &h, &comp)) {
    if (size) *size = {w, h};
    return (w > 0 && h > 0) ? "" : "zero size";
  }
  if (b.size() >= 12 && b.compare(0, 4, "RIFF") == 0 && b.compare(8, 4, "WEBP") == 0)
    return "a WebP image (whatever its extension); PNG, JPEG, BMP and TGA are supported";
  const char* why = stbi_failure_reason();
  return std::string("not a supported image (") + (why ? why : "unknown format") + ")";
}

// JPEG markers up to the first APP1 "Exif" segment, then its TIFF header and IFD0's tag 0x0112.
int exif_orientation(const std::string& path) {
  std::string b;
  try {
    b = host::read_file(path);
  } catch (const Error&) {
    return 0;
  }
  auto u8 = [&](size_t i) { return i < b.size() ? unsigned(static_cast<unsigned char>(b[i])) : 0u; };
  if (u8(0) != 0xFF || u8(1) != 0xD8) return 0;
  size_t i = 2;
  while (i + 4 <= b.size() && u8(i) == 0xFF) {
    const unsigned marker = u8(i + 1), len = (u8(i + 2) << 8) | u8(i + 3);
    if (marker == 0xDA || len < 2) return 0;  // image data: no EXIF before it
    if (marker == 0xE1 && len >= 16 && b.compare(i + 4, 6, std::string("Exif\0\0", 6)) == 0) {
      const size_t t = i + 10;  // the TIFF header
      const bool le = u8(t) == 'I';
      auto rd16 = [&](size_t o) { return le ? u8(o) | (u8(o + 1) << 8) : (u8(o) << 8) | u8(o + 1); };
      auto rd32 = [&](size_t o) { return le ? rd16(o) | (rd16(o + 2) << 16) : (rd16(o) << 16) | rd16(o + 2); };
      const size_t ifd = t + rd32(t + 4);
      const unsigned entries = rd16(ifd);
      for (unsigned e = 0; e < entries && ifd + 2 + 12 * (e + 1) <= b.size(); ++e) {
        const size_t en = ifd + 2 + 12 * e;
        if (rd16(en) == 0x0112) {
          const unsigned v = rd16(en + 8);
          return v >= 1 && v <= 8 ? int(v) : 0;
        }
      }
      return 0;
    }
    i += 2 + len;
  }
  return 0;
}

Image load_image(const std::string& path, const std::array<float, 3>* background, std::vector<float>* alpha) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec)) throw Error("image " + path + " does not exist");
  if (fs::is_directory(path, ec)) throw Error("image " + path + " is a directory, not an image file");
  if (fs::file_size(path, ec) == 0) throw Error("image " + path + " is an empty file (0 bytes)");

  // One read of the file; every stb call below decodes from these bytes.
  const std::string b = host::read_file(path);
  if (const std::string why = jpeg_huffman_problem(b); !why.empty())
    throw Error("cannot read image " + path + ": corrupt JPEG (" + why + ")");
  int w = 0, h = 0, comp = 0;
  // The header's size before any pixel is allocated: a few bytes can claim gigapixels.
  if (stbi_info_from_memory(bytes_of(b), size_of(b), &w, &h, &comp) &&
      (w > kMaxImageSide || h > kMaxImageSide || int64_t(w) * h > kMaxImagePixels))
    throw Error("image " + path + " is " + std::to_string(w) + "x" + std::to_string(h) + ", beyond the " +
                std::to_string(kMaxImageSide) + " px per side and " + std::to_string(kMaxImagePixels / 1000000) +
                " megapixels read here; resize it first");
  // 16-bit PNGs keep their precision; everything else decodes to 8 bits. Always ask for 4 channels and
  // use `comp` (the file's own count) to know whether the alpha is real.
  const bool sixteen = stbi_is_16_bit_from_memory(bytes_of(b), size_of(b));
  void* pixels = sixteen ? static_cast<void*>(stbi_load_16_from_memory(bytes_of(b), size_of(b), &w, &h, &comp, 4))
                         : static_cast<void*>(stbi_load_from_memory(bytes_of(b), size_of(b), &w, &h, &comp, 4));
  if (!pixels) {
    const char* why = stbi_failure_reason();
    throw Error("cannot read image " + path + ": " + (why ? why : "unknown format") +
                " (PNG, JPEG, BMP, TGA are supported)");
  }
  std::unique_ptr<void, void (*)(void*)> guard(pixels, stbi_image_free);
  if (w <= 0 || h <= 0) throw Error("image " + path + " has zero size");

  Image img;
  img.width = w;
  img.height = h;
  img.data.resize(size_t(3) * w * h);
  const float scale = sixteen ? 1.0f / 65535.0f : 1.0f / 255.0f;
  const bool has_alpha = comp == 2 || comp == 4;
  if (alpha) alpha->assign(has_alpha ? size_t(w) * h : 0, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      size_t p = (size_t(y) * w + x) * 4;
      auto value = [&](int c) {
        return sixteen ? static_cast<const uint16_t*>(pixels)[p + c] * scale
                       : static_cast<const unsigned char*>(pixels)[p + c] * scale;
      };
      if (has_alpha && alpha) (*alpha)[size_t(y) * w + x] = value(3);
      float a = has_alpha && background ? value(3) : 1.0f;
      for (int c = 0; c < 3; ++c) img.at(c, y, x) = a * value(c) + (background ? (1.0f - a) * (*background)[c] : 0.0f);
    }
  return img;
}

namespace {

struct Tap {
  int index;
  float weight;
};

// For each output position, the source pixels and their normalised weights along one axis.
//  - shrinking: area averaging, each output pixel is the mean of the source interval it covers,
//    [o * scale, (o + 1) * scale), partially covered pixels weighted by their coverage (no aliasing);
//  - enlarging: bilinear between the two nearest source pixel centres, edges repeated.
std::vector<std::vector<Tap>> filter_taps(int src, int dst) {
  const double scale = double(src) / dst;
  std::vector<std::vector<Tap>> taps(dst);
  for (int o = 0; o < dst; ++o) {
    if (scale > 1.0) {
      const double lo = o * scale, hi = (o + 1) * scale;
      for (int i = int(std::floor(lo)); i < int(std::ceil(hi)) && i < src; ++i) {
        double cover = std::min(hi, i + 1.0) - std::max(lo, double(i));
        if (cover > 0) taps[o].push_back({i, float(cover / scale)});
      }
    } else {
      const double centre = (o + 0.5) * scale - 0.5;  // pixel centres aligned
      const int i0 = int(std::floor(centre));
      const double f = centre - i0;
      taps[o].push_back({std::clamp(i0, 0, src - 1), float(1.0 - f)});
      taps[o].push_back({std::clamp(i0 + 1, 0, src - 1), float(f)});
    }
  }
  return taps;
}

}  // namespace

Image resize(const Image& img, int width, int height) {
  if (width <= 0 || height <= 0) throw Error("resize: target size must be positive");
  if (width == img.width && height == img.height) return img;
  auto tx = filter_taps(img.width, width), ty = filter_taps(img.height, height);
  Image tmp;  // horizontal pass first
  tmp.width = width;
  tmp.height = img.height;
  tmp.data.assign(size_t(3) * width * img.height, 0.0f);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < width; ++x) {
        float s = 0;
        for (const Tap& t : tx[x]) s += t.weight * img.at(c, y, t.index);
        tmp.at(c, y, x) = s;
      }
  Image out;
  out.width = width;
  out.height = height;
  out.data.assign(size_t(3) * width * height, 0.0f);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < height; ++y)
      for (const Tap& t : ty[y])
        for (int x = 0; x < width; ++x) out.at(c, y, x) += t.weight * tmp.at(c, t.index, x);
  return out;
}

std::array<int, 2> fit_size(int width, int height, int longer, int multiple) {
  if (width <= 0 || height <= 0 || longer <= 0 || multiple <= 0) throw Error("fit_size: sizes must be positive");
  double s = double(longer) / std::max(width, height);
  auto round_to = [&](double v) { return std::max(multiple, int(std::lround(v / multiple)) * multiple); };
  return {round_to(width * s), round_to(height * s)};
}

namespace {
std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}
std::vector<unsigned char> to_bytes(const std::string& path, const Image& img) {
  if (img.width <= 0 || img.height <= 0 || img.data.size() != size_t(3) * img.width * img.height)
    throw Error("cannot write " + path + ": the image has an invalid size");
  std::vector<unsigned char> rgb(size_t(3) * img.width * img.height);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c) {
        float v = img.at(c, y, x);
        v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
        rgb[(size_t(y) * img.width + x) * 3 + c] = static_cast<unsigned char>(std::lround(v * 255.0f));
      }
  return rgb;
}
}  // namespace

void save_image(const std::string& path, const Image& img) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") return save_png(path, img);
  if (ext != ".jpg" && ext != ".jpeg")
    throw Error("cannot write " + path + ": unknown image type '" + ext + "' (use .png or .jpg)");
  const auto rgb = to_bytes(path, img);
  host::write_atomic_with(path, [&](const std::string& tmp) {
    if (!stbi_write_jpg(tmp.c_str(), img.width, img.height, 3, rgb.data(), 95)) throw Error("cannot write JPEG " + path);
  });
}

void save_png(const std::string& path, const Image& img) {
  const std::string ext = lower_extension(path);
  if (ext == ".jpg" || ext == ".jpeg") throw Error("cannot write " + path + ": PNG data under a JPEG name (use .png)");
  const auto rgb = to_bytes(path, img);
  host::write_atomic_with(path, [&](const std::string& tmp) {
    if (!stbi_write_png(tmp.c_str(), img.width, img.height, 3, rgb.data(), img.width * 3))
      throw Error("cannot write PNG " + path);
  });
}

Image from_interleaved(const std::vector<float>& rgb, int w, int h) {
  if (w <= 0 || h <= 0 || rgb.size() != size_t(3) * w * h)
    throw Error("from_interleaved: " + std::to_string(rgb.size()) + " values for a " + std::to_string(w) + "x" +
                std::to_string(h) + " RGB image");
  Image img;
  img.width = w;
  img.height = h;
  img.data.resize(rgb.size());
  const size_t plane = size_t(w) * h;
  for (size_t i = 0; i < plane; ++i)
    for (size_t c = 0; c < 3; ++c) img.data[c * plane + i] = rgb[i * 3 + c];
  return img;
}

std::string encode_png(const Image& img) {
  const auto rgb = to_bytes("a PNG in memory", img);
  std::string out;
  auto append = [](void* ctx, void* data, int size) {
    static_cast<std::string*>(ctx)->append(static_cast<const char*>(data), size_t(size));
  };
  if (!stbi_write_png_to_func(append, &out, img.width, img.height, 3, rgb.data(), img.width * 3))
    throw Error("cannot encode a " + std::to_string(img.width) + "x" + std::to_string(img.height) + " PNG");
  return out;
}

host::Tensor to_tensor(const Image& img) {
  return host::Tensor::from_host(img.data, {1, 3, img.height, img.width}, "image");
}

Image from_tensor(const host::Tensor& t, int n) {
  if (t.ndim() != 4 || t.dim(1) != 3 || n < 0 || n >= t.dim(0))
    throw Error("from_tensor: expected [N,3,H,W] with n < N, got " + host::shape_str(t.shape()) + " and n = " +
                std::to_string(n));
  Image img;
  img.height = int(t.dim(2));
  img.width = int(t.dim(3));
  std::vector<float> all = t.to_host();
  size_t per = size_t(3) * img.width * img.height;
  img.data.assign(all.begin() + per * n, all.begin() + per * (n + 1));
  return img;
}

}  // namespace stylerf::io
