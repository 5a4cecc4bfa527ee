#include "lib/io/video.hpp"

#include <stdlib.h>

#include <cmath>
#include <deque>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"
#include "lib/io/process.hpp"

namespace stylerf::io {

namespace fs = std::filesystem;
using host::Error;

namespace {

constexpr double kMaxFps = 1000;

std::string fps_text(double fps) {
  std::ostringstream o;
  o << std::setprecision(10) << fps;  // 30 -> "30", 29.97 -> "29.97": ffmpeg reads either
  return o.str();
}

void check_fps(double fps) {
  if (!(fps > 0 && fps <= kMaxFps))
    throw Error("video: fps must be a positive number of frames a second, at most " + fps_text(kMaxFps) + " (got " +
                fps_text(fps) + ")");
}

// A fresh folder under the system's temporary directory, removed with everything in it when this goes.
class TempFolder {
 public:
  TempFolder() {
    std::string pattern = (fs::temp_directory_path() / "stylerf-video-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw Error("video: cannot create a temporary folder for the frames in " +
                                              fs::temp_directory_path().string());
    path_ = pattern;
  }
  ~TempFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempFolder(const TempFolder&) = delete;
  TempFolder& operator=(const TempFolder&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

}  // namespace

bool have_ffmpeg() { return !find_program("ffmpeg").empty(); }

void encode_png_sequence(const std::string& dir, const std::string& pattern, const std::string& mp4, double fps) {
  check_fps(fps);
  const std::string ffmpeg = find_program("ffmpeg");
  if (ffmpeg.empty()) throw Error("video: ffmpeg is not on PATH; install it (apt-get install ffmpeg) to write " + mp4);
  host::write_atomic_with(mp4, [&](const std::string& tmp) {
    // -nostdin: ffmpeg would otherwise read keystrokes from the caller's terminal or pipe.
    const std::vector<std::string> args = {"-nostdin", "-loglevel", "error", "-y", "-framerate", fps_text(fps),
                                           "-i", (fs::path(dir) / pattern).string(),
                                           "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p",
                                           "-f", "mp4", tmp};
    std::deque<std::string> last;  // the end of ffmpeg's output, for the error message
    const ProcessResult r = run_process(ffmpeg, args, [&](const std::string& line) {
      last.push_back(line);
      if (last.size() > 8) last.pop_front();
    });
    if (r.status != 0) {
      std::string said;
      for (const auto& l : last) said += "\n  " + l;
      throw Error("video: ffmpeg failed (exit status " + std::to_string(r.status) + ") encoding " +
                  (fs::path(dir) / pattern).string() + " into " + mp4 + (said.empty() ? "" : ":" + said));
    }
  });
}

bool write_video(const std::string& dir, const std::string& pattern, const std::string& name, int fps,
                 std::ostream& log) {
  if (!have_ffmpeg()) {
    log << "ffmpeg not on PATH: frames only (ffmpeg -y -framerate " << fps << " -i " << dir << "/" << pattern
        << " -pix_fmt yuv420p " << name << ")\n";
    return false;
  }
  const std::string mp4 = (fs::path(dir) / name).string();
  encode_png_sequence(dir, pattern, mp4, fps);
  log << "video: " << mp4 << "\n";
  return true;
}

void save_video(const std::string& mp4, int count, const std::function<Image(int index)>& frame, double fps) {
  if (count < 1) throw Error("video: no frames to write to " + mp4);
  check_fps(fps);
  const fs::path parent = fs::path(mp4).has_parent_path() ? fs::path(mp4).parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(parent, ec)) throw Error("video: cannot write " + mp4 + ": the folder " + parent.string() +
                                                 " does not exist");
  if (!have_ffmpeg()) throw Error("video: ffmpeg is not on PATH; install it (apt-get install ffmpeg) to write " + mp4);
  const TempFolder frames;
  int width = 0, height = 0;
  for (int i = 0; i < count; ++i) {
    const Image img = frame(i);
    if (i == 0) {
      width = img.width, height = img.height;
    } else if (img.width != width || img.height != height) {
      throw Error("video: frame " + std::to_string(i) + " is " + std::to_string(img.width) + " x " +
                  std::to_string(img.height) + " pixels, frame 0 " + std::to_string(width) + " x " +
                  std::to_string(height) + "; every frame must have the same size");
    }
    std::ostringstream name;
    name << "frame_" << std::setw(6) << std::setfill('0') << i << ".png";
    save_png((frames.path() / name.str()).string(), img);
  }
  encode_png_sequence(frames.path().string(), "frame_%06d.png", mp4, fps);
}

}  // namespace stylerf::io
