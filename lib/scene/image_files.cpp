#include "lib/scene/image_files.hpp"

#include <stb/stb_image.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <memory>

#include "host/error.hpp"

namespace stylerf::scene {

using host::Error;

std::vector<std::string> list_images(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") names.push_back(e.path().filename().string());
  }
  // Byte-wise order: COLMAP/LLFF store the poses of images sorted by name this way ("1", "10", "11", ...).
  std::sort(names.begin(), names.end());
  for (auto& n : names) n = (fs::path(dir) / n).string();
  return names;
}

RgbaImage load_rgba(const std::string& path, const std::array<float, 3>& background) {
  RgbaImage out;
  out.rgb = io::load_image(path, &background, &out.alpha);
  return out;
}

void image_size(const std::string& path, int& width, int& height) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error("image " + path + " does not exist");
  int comp = 0;
  if (!stbi_info(path.c_str(), &width, &height, &comp)) {
    const char* why = stbi_failure_reason();
    throw Error("cannot read image " + path + ": " + (why ? why : "unknown format"));
  }
}

std::vector<float> interleave(const io::Image& img) {
  const size_t n = size_t(img.width) * img.height;
  std::vector<float> out(3 * n);
  for (size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) out[3 * i + c] = img.data[c * n + i];
  return out;
}

std::vector<float> resize_plane(const std::vector<float>& plane, int width, int height, int new_width,
                                int new_height) {
  io::Image tmp;
  tmp.width = width;
  tmp.height = height;
  tmp.data.resize(3 * plane.size());
  // Only channel 0 matters; io::resize works on three planes, so the other two are left at zero.
  std::copy(plane.begin(), plane.end(), tmp.data.begin());
  io::Image r = io::resize(tmp, new_width, new_height);
  return std::vector<float>(r.data.begin(), r.data.begin() + size_t(new_width) * new_height);
}

}  // namespace stylerf::scene
