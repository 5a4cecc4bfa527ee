#include "lib/scene/colmap_import.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/io/process.hpp"
#include "lib/scene/colmap_model.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;


std::string join_some(const std::vector<std::string>& names, size_t most = 8) {
  std::string out;
  for (size_t i = 0; i < names.size() && i < most; ++i) out += (i ? ", " : "") + names[i];
  if (names.size() > most) out += " and " + std::to_string(names.size() - most) + " more";
  return out;
}

// Every file of the folder (dot-files aside) must be an image, all of one size.
std::vector<std::string> check_images(const std::string& dir, ImportReport& report) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw host::SettingError("images", dir + " is not a folder");
  std::vector<std::string> names, bad;
  std::map<std::string, std::array<int, 2>> sizes;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || name[0] == '.' || !e.is_regular_file()) continue;
    const std::string why = io::image_unreadable_reason(e.path().string(), &sizes[name]);
    if (why.empty()) names.push_back(name);
    else bad.push_back(name + " (" + why + ")");
  }
  if (ec) throw Error("import: cannot list " + dir + ": " + ec.message());
  if (!bad.empty())
    throw Error("import: " + dir + " holds files that are not images: " + join_some(bad) +
                "; move them out of the folder");
  if (int(names.size()) < kMinImages)
    throw Error("import: " + dir + " holds " + std::to_string(names.size()) + " images; structure from motion needs " +
                std::to_string(kMinImages) + " or more (20+ overlapping photos work well)");
  std::sort(names.begin(), names.end());
  std::map<std::string, std::vector<std::string>> by_size;
  std::map<int, int> orientations;
  for (const auto& n : names) {
    const auto& wh = sizes.at(n);  // from the header read above
    by_size[std::to_string(wh[0]) + "x" + std::to_string(wh[1])].push_back(n);
    if (const int o = io::exif_orientation((fs::path(dir) / n).string()); o > 1) ++orientations[o];
  }
  if (by_size.size() > 1) {
    std::string sizes;
    for (const auto& [size, files] : by_size)
      sizes += (sizes.empty() ? "" : "; ") + std::to_string(files.size()) + " at " + size + " (" + join_some(files, 3) + ")";
    throw Error("import: the images of " + dir + " have different sizes: " + sizes +
                ". Resize or crop them to one size first");
  }
  for (const auto& [o, count] : orientations)
    report.notes.push_back(std::to_string(count) + " images carry EXIF orientation " + std::to_string(o) +
                           " (not upright as stored); they are used as stored, as COLMAP reads them, so renders "
                           "come out as the sensor saw them");
  return names;
}

std::string find_colmap(const std::string& name) {
  const std::string path = io::find_program(name);
  if (path.empty())
    throw Error("import: COLMAP was not found ('" + name + "' is not " +
                (name.find('/') == std::string::npos ? "on PATH" : "an executable") +
                "). Install it with `sudo apt-get install colmap` (Debian, Ubuntu; scripts/setup.sh does), or see "
                "https://colmap.github.io/install.html, or pass --colmap PATH");
  return path;
}

// One COLMAP phase: its output to work/logs/<phase>.log, progress from the lines that count something.
class PhaseRunner {
 public:
  PhaseRunner(std::string colmap, fs::path logs, const std::function<void(const std::string&)>& progress,
              ImportReport& report)
      : colmap_(std::move(colmap)), logs_(std::move(logs)), progress_(progress), report_(report) {}

  void run(const std::string& phase, const std::string& command, const std::vector<std::string>& args) {
    static const std::regex counted(R"((Processed file|Matching block|Matching image|Undistorting image) \[(\d+)/(\d+))");
    static const std::regex registering(R"(Registering image #\d+ \((\d+)\))");
    const auto start = Clock::now();
    auto last = start;
    const std::string log = (logs_ / (phase + ".log")).string();
    std::vector<std::string> tail;
    std::vector<std::string> argv{command};
    argv.insert(argv.end(), args.begin(), args.end());
    const io::ProcessResult r = io::run_process(colmap_, argv, [&](const std::string& line) {
      tail.push_back(line);
      if (tail.size() > 6) tail.erase(tail.begin());
      std::smatch m;
      std::string what;
      if (std::regex_search(line, m, counted)) what = m[2].str() + "/" + m[3].str();
      else if (std::regex_search(line, m, registering)) what = m[1].str() + " images registered";
      const auto now = Clock::now();
      if (!what.empty() && now - last >= std::chrono::seconds(2)) {
        last = now;
        progress_("  " + phase + ": " + what + ", " + seconds(start) + " s");
      }
    }, log);
    const double secs = std::chrono::duration<double>(Clock::now() - start).count();
    report_.phase_seconds.emplace_back(phase, secs);
    if (r.status != 0) {
      std::string last_lines;
      for (const auto& l : tail) last_lines += "\n    " + l;
      throw Error("import: COLMAP's " + command + " failed (exit " + std::to_string(r.status) + ") after " +
                  seconds(start) + " s; its last lines:" + last_lines);
    }
    progress_("  " + phase + " done in " + seconds(start) + " s");
  }

 private:
  static std::string seconds(Clock::time_point since) {
    std::ostringstream s;
    s.precision(1);
    s << std::fixed << std::chrono::duration<double>(Clock::now() - since).count();
    return s.str();
  }
  std::string colmap_;
  fs::path logs_;
  const std::function<void(const std::string&)>& progress_;
  ImportReport& report_;
};

// The mapper's model with the most registered images (it writes sparse/0, sparse/1, ... for disjoint parts).
fs::path largest_model(const fs::path& sparse, int& registered) {
  fs::path best;
  registered = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(sparse, ec)) {
    if (!e.is_directory()) continue;
    if (!fs::exists(e.path() / "cameras.bin") && !fs::exists(e.path() / "cameras.txt")) continue;
    const int n = int(read_colmap_model(e.path().string()).images.size());
    if (n > registered) registered = n, best = e.path();
  }
  if (best.empty()) throw Error("import: COLMAP's mapper registered no images (no model in " + sparse.string() + ")");
  return best;
}

void check_registered(const ColmapModel& model, const std::vector<std::string>& names, ImportReport& report) {
  std::set<std::string> in;
  for (const auto& im : model.images) in.insert(im.name);
  for (const auto& n : names)
    if (!in.count(n)) report.left_out.push_back(n);
  report.registered = int(in.size());
  double err = 0;
  for (const auto& p : model.points) err += p.error;
  report.mean_reprojection_error = model.points.empty() ? 0 : err / double(model.points.size());
  if (report.registered * 5 < report.images * 4)
    throw Error("import: COLMAP registered " + std::to_string(report.registered) + " of " +
                std::to_string(report.images) + " images, under the 80% needed; left out: " +
                join_some(report.left_out, 20) +
                ". More overlap between neighbouring photos, more texture, or --matcher exhaustive may help");
}

}  // namespace

ImportReport import_with_colmap(const ImportOptions& o, const std::function<void(const std::string&)>& progress) {
  ImportReport report;
  if (o.out.empty()) throw Error("import: no output folder (-o)");
  if (o.matcher != "auto" && o.matcher != "exhaustive" && o.matcher != "sequential")
    throw host::SettingError("matcher", "must be auto, exhaustive or sequential, got '" + o.matcher + "'");
  if (colmap_model_id(o.camera_model) < 0) throw Error("import: unknown COLMAP camera model '" + o.camera_model + "'");
  if (o.max_image_size < 0) throw host::SettingError("max_image_size", "must be 0 (as given) or positive");
  const fs::path out = fs::path(o.out).lexically_normal();
  std::error_code ec;
  if (fs::exists(out, ec) && !o.force) throw Error("import: " + out.string() + " exists (--force replaces it)");
  const std::vector<std::string> names = check_images(o.images, report);
  report.images = int(names.size());
  const std::string colmap = find_colmap(o.colmap);
  report.matcher = o.matcher != "auto" ? o.matcher : (report.images <= kExhaustiveLimit ? "exhaustive" : "sequential");

  const fs::path work = out.string() + ".importing-" + std::to_string(::getpid());
  fs::remove_all(work, ec);
  fs::create_directories(work / "colmap" / "logs");
  fs::create_directories(work / "colmap" / "mapper");
  setenv("QT_QPA_PLATFORM", "offscreen", 0);  // COLMAP links Qt; it must not look for a display
  try {
    PhaseRunner phases(colmap, work / "colmap" / "logs", progress, report);
    const std::string db = (work / "colmap" / "database.db").string();
    const std::string threads = std::to_string(o.threads > 0 ? o.threads : -1);
    std::vector<std::string> fe{"--database_path", db, "--image_path", o.images, "--ImageReader.camera_model",
                                o.camera_model, "--ImageReader.single_camera", o.single_camera ? "1" : "0",
                                "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", threads};
    if (o.max_image_size > 0) fe.insert(fe.end(), {"--SiftExtraction.max_image_size", std::to_string(o.max_image_size)});
    progress("import: " + std::to_string(report.images) + " images, COLMAP at " + colmap);
    phases.run("features", "feature_extractor", fe);
    phases.run("matching", report.matcher + "_matcher",
               {"--database_path", db, "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads", threads});
    phases.run("mapper", "mapper", {"--database_path", db, "--image_path", o.images, "--output_path",
                                    (work / "colmap" / "mapper").string(), "--Mapper.num_threads", threads});
    int registered = 0;
    const fs::path model = largest_model(work / "colmap" / "mapper", registered);
    check_registered(read_colmap_model(model.string()), names, report);
    std::vector<std::string> ud{"--image_path", o.images, "--input_path", model.string(), "--output_path",
                                (work / "dense").string(), "--output_type", "COLMAP"};
    if (o.max_image_size > 0) ud.insert(ud.end(), {"--max_image_size", std::to_string(o.max_image_size)});
    phases.run("undistort", "image_undistorter", ud);
    // The scene: images/ and sparse/0/ from the undistorter, colmap/ beside them; renamed into place last.
    const fs::path scene = work / "scene";
    fs::create_directories(scene / "sparse");
    fs::rename(work / "dense" / "images", scene / "images");
    fs::rename(work / "dense" / "sparse", scene / "sparse" / "0");
    fs::rename(work / "colmap", scene / "colmap");
    if (fs::exists(out, ec)) fs::remove_all(out);
    fs::rename(scene, out);
    fs::remove_all(work, ec);
  } catch (...) {
    fs::remove_all(work, ec);
    throw;
  }
  return report;
}

}  // namespace stylerf::scene
