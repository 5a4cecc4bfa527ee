// Image files of a scene: listing an image folder in the order LLFF/COLMAP use (file names sorted
// byte-wise), and loading RGB with the alpha channel kept apart. Built on lib/io/image.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "lib/io/image.hpp"

namespace stylerf::scene {

// Regular files with an image extension (png, jpg, jpeg; any case), sorted by name. Empty if none.
std::vector<std::string> list_images(const std::string& dir);

struct RgbaImage {
  io::Image rgb;             // composited over the background when the file has alpha
  std::vector<float> alpha;  // [H*W], empty when the file has no alpha channel
};

// Loads an image; with alpha it is composited over `background` and alpha is returned too.
// Errors name the file (missing, unreadable).
RgbaImage load_rgba(const std::string& path, const std::array<float, 3>& background);

// Width and height from the file header, without decoding. Errors name the file.
void image_size(const std::string& path, int& width, int& height);

// Planar io::Image -> interleaved [H][W][3].
std::vector<float> interleave(const io::Image& img);

// Resize a single-channel [H*W] plane with io::resize's filter.
std::vector<float> resize_plane(const std::vector<float>& plane, int width, int height, int new_width,
                                int new_height);

}  // namespace stylerf::scene
