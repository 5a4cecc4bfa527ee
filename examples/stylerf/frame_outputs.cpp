#include "examples/stylerf/frame_outputs.hpp"

#include <iomanip>
#include <sstream>

namespace stylerf::cli {

std::string numbered(const std::filesystem::path& dir, const std::string& stem, int i, int digits,
                     const std::string& ext) {
  std::ostringstream o;
  o << stem << std::setw(digits) << std::setfill('0') << i << ext;
  return (dir / o.str()).string();
}

io::Image interleaved_image(const std::vector<float>& rgb, int w, int h) { return io::from_interleaved(rgb, w, h); }

io::Image grey_image(const std::vector<float>& v, int w, int h) {
  io::Image img;
  img.width = w;
  img.height = h;
  img.data.resize(size_t(3) * w * h);
  const size_t plane = size_t(w) * h;
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = v[i];
  return img;
}

}  // namespace stylerf::cli
