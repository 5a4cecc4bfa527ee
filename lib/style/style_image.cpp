#include "lib/style/style_image.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "host/error.hpp"
#include "lib/io/image.hpp"

namespace stylerf::style {

using host::Error;

namespace {
// One message for both loaders; load_style_image checks before it decodes anything.
void check_crop(const std::string& path, int crop, int size) {
  if (size < 8 || crop > size || crop < 8 || crop % 8)
    throw Error("style image " + path + ": crop " + std::to_string(crop) + " must be a multiple of 8 in [8, " +
                std::to_string(size) + "] of a square image");
}
}  // namespace

io::Image load_style_source(const std::string& path, int size) {
  if (size < 8) throw Error("style image " + path + ": size " + std::to_string(size) + " must be >= 8");
  io::Image full = io::resize(io::load_image(path), size, size);
  for (float v : full.data)
    if (!std::isfinite(v)) throw Error("style image " + path + ": decoded to values that are not finite");
  return full;
}

host::Tensor crop_style_image(const io::Image& source, int crop, std::mt19937_64* rng, const std::string& path) {
  if (source.width != source.height)
    throw Error("style image " + path + ": its source is " + std::to_string(source.width) + "x" +
                std::to_string(source.height) + ", not square (load_style_source makes it square)");
  const int size = source.width;
  check_crop(path, crop, size);
  int x0 = (size - crop) / 2, y0 = (size - crop) / 2;
  if (rng && crop < size) {
    std::uniform_int_distribution<int> u(0, size - crop);
    x0 = u(*rng);
    y0 = u(*rng);
  }
  io::Image out;
  out.width = out.height = crop;
  out.data.resize(size_t(3) * crop * crop);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < crop; ++y)
      for (int x = 0; x < crop; ++x) out.at(c, y, x) = source.at(c, y0 + y, x0 + x);
  return io::to_tensor(out);
}

host::Tensor load_style_image(const std::string& path, int size, int crop, std::mt19937_64* rng) {
  check_crop(path, crop, size);
  return crop_style_image(load_style_source(path, size), crop, rng, path);
}

std::vector<std::string> style_images_in(const std::string& dir, std::ostream* log) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error("style folder " + dir + " does not exist or is not a folder");
  std::vector<std::string> all;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    if (ext == ".jpg" || ext == ".jpeg" || ext == ".png") all.push_back(e.path().string());
  }
  std::sort(all.begin(), all.end());
  std::vector<std::string> readable;
  for (const auto& p : all) {
    const std::string why = io::image_unreadable_reason(p);
    if (why.empty()) {
      readable.push_back(p);
    } else if (log) {
      *log << "style folder: skipping " << p << ": " << why << std::endl;
    }
  }
  return readable;
}

}  // namespace stylerf::style
