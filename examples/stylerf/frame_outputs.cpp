#include "examples/stylerf/frame_outputs.hpp"

#include <cstdlib>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::cli {

std::string numbered(const std::filesystem::path& dir, const std::string& stem, int i, int digits,
                     const std::string& ext) {
  std::ostringstream o;
  o << stem << std::setw(digits) << std::setfill('0') << i << ext;
  return (dir / o.str()).string();
}

io::Image interleaved_image(const std::vector<float>& rgb, int w, int h) {
  io::Image img;
  img.width = w;
  img.height = h;
  img.data.resize(size_t(3) * w * h);
  const size_t plane = size_t(w) * h;
  for (size_t i = 0; i < plane; ++i)
    for (int c = 0; c < 3; ++c) img.data[c * plane + i] = rgb[i * 3 + c];
  return img;
}

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

bool have_ffmpeg() { return std::system("command -v ffmpeg >/dev/null 2>&1") == 0; }

bool write_video(const std::string& dir, const std::string& pattern, const std::string& name, int fps,
                 std::ostream& log) {
  if (!have_ffmpeg()) {
    log << "ffmpeg not on PATH: frames only (ffmpeg -y -framerate " << fps << " -i " << dir << "/" << pattern
        << " -pix_fmt yuv420p " << name << ")\n";
    return false;
  }
  const std::string mp4 = (std::filesystem::path(dir) / name).string();
  host::write_atomic_with(mp4, [&](const std::string& tmp) {
    // Even sizes for yuv420p: pad by one pixel where needed.
    const std::string cmd = "ffmpeg -loglevel error -y -framerate " + std::to_string(fps) + " -i '" + dir + "/" +
                            pattern + "' -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -pix_fmt yuv420p -f mp4 '" + tmp + "'";
    if (std::system(cmd.c_str()) != 0) throw host::Error("ffmpeg failed: " + cmd);
  });
  log << "video: " << mp4 << "\n";
  return true;
}

}  // namespace stylerf::cli
