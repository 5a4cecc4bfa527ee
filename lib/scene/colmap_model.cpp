#include "lib/scene/colmap_model.hpp"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "host/error.hpp"
#include "host/files.hpp"

namespace stylerf::scene {

using host::Error;
namespace fs = std::filesystem;

namespace {

struct ModelInfo {
  const char* name;
  int params;
  bool separate_f;  // fx, fy, cx, cy (else f, cx, cy)
  bool fisheye;     // never a pinhole, whatever its parameters
};
// COLMAP's camera models by id (src/base/camera_models.h).
const ModelInfo kModels[] = {
    {"SIMPLE_PINHOLE", 3, false, false}, {"PINHOLE", 4, true, false},      {"SIMPLE_RADIAL", 4, false, false},
    {"RADIAL", 5, false, false},         {"OPENCV", 8, true, false},       {"OPENCV_FISHEYE", 8, true, true},
    {"FULL_OPENCV", 12, true, false},    {"FOV", 5, true, false},          {"SIMPLE_RADIAL_FISHEYE", 4, false, true},
    {"RADIAL_FISHEYE", 5, false, true},  {"THIN_PRISM_FISHEYE", 12, true, true},
};
constexpr int kModelCount = int(sizeof kModels / sizeof kModels[0]);

std::string model_list() {
  std::string s;
  for (int i = 0; i < kModelCount; ++i) s += (i ? ", " : "") + std::to_string(i) + " " + kModels[i].name;
  return s;
}

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

bool is_bin(const std::string& path) { return fs::path(path).extension() == ".bin"; }

std::string read_all(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw Error("COLMAP model: " + path + " is missing");
  return host::read_file(path);
}

// --- binary ---------------------------------------------------------------------------------------
class Bin {
 public:
  Bin(std::string path) : path_(std::move(path)), data_(read_all(path_)) {}
  template <class T>
  T get(const char* what) {
    T v;
    need(sizeof(T), what);
    std::memcpy(&v, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string cstring(const char* what) {
    const size_t end = data_.find('\0', pos_);
    if (end == std::string::npos) fail(std::string("truncated in ") + what + " (no terminating zero byte)");
    std::string s = data_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return s;
  }
  // A count of records of at least `min_bytes` each must fit in what is left of the file.
  uint64_t count(const char* what, size_t min_bytes) {
    const uint64_t n = get<uint64_t>(what);
    if (min_bytes > 0 && n > left() / min_bytes)
      fail(std::string("says it holds ") + std::to_string(n) + " " + what + " but only " + std::to_string(left()) +
           " bytes follow (each needs at least " + std::to_string(min_bytes) + "): truncated, or not a COLMAP " +
           fs::path(path_).filename().string());
    return n;
  }
  void finish() {
    if (pos_ != data_.size())
      fail(std::to_string(data_.size() - pos_) + " bytes are left over after the last record (the counts do not match the file size)");
  }
  [[noreturn]] void fail(const std::string& msg) const { throw Error(path_ + ": " + msg); }
  size_t left() const { return data_.size() - pos_; }
  size_t pos() const { return pos_; }

 private:
  void need(size_t n, const char* what) {
    if (n > left())
      fail(std::string("truncated at byte ") + std::to_string(pos_) + " (reading " + what + "; the file has " +
           std::to_string(data_.size()) + " bytes)");
  }
  std::string path_, data_;
  size_t pos_ = 0;
};

// --- text -----------------------------------------------------------------------------------------
struct Text {
  std::string path;
  std::vector<std::string> lines;
  size_t next = 0;
  explicit Text(std::string p) : path(std::move(p)) {
    std::istringstream in(read_all(path));
    std::string l;
    while (std::getline(in, l)) {
      if (!l.empty() && l.back() == '\r') l.pop_back();
      lines.push_back(l);
    }
  }
  // The next line that is neither empty nor a comment; false at the end.
  bool record(std::vector<std::string>& tokens, size_t& line_no) {
    while (next < lines.size()) {
      const std::string& l = lines[next++];
      const size_t first = l.find_first_not_of(" \t");
      if (first == std::string::npos || l[first] == '#') continue;
      line_no = next;
      tokens = split(l);
      return true;
    }
    return false;
  }
  // The line right after a record (COLMAP's images.txt: the 2D points, possibly empty).
  std::vector<std::string> raw(size_t& line_no) {
    line_no = next + 1;
    if (next >= lines.size()) return {};
    return split(lines[next++]);
  }
  static std::vector<std::string> split(const std::string& l) {
    std::istringstream in(l);
    std::vector<std::string> t;
    std::string w;
    while (in >> w) t.push_back(w);
    return t;
  }
  [[noreturn]] void fail(size_t line, const std::string& msg) const {
    throw Error(path + " line " + std::to_string(line) + ": " + msg);
  }
  double num(const std::string& tok, size_t line, const char* what) const {
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(tok.c_str(), &end);
    if (tok.empty() || *end != '\0') fail(line, std::string(what) + " '" + tok + "' is not a number");
    return v;
  }
  int64_t integer(const std::string& tok, size_t line, const char* what, int64_t lo, int64_t hi) const {
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(tok.c_str(), &end, 10);
    if (tok.empty() || *end != '\0' || errno == ERANGE) fail(line, std::string(what) + " '" + tok + "' is not an integer");
    if (v < lo || v > hi)
      fail(line, std::string(what) + " " + tok + " is outside " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }
};

void check_camera(const ColmapCamera& c, const std::string& where) {
  if (c.width == 0 || c.height == 0 || c.width > 1000000 || c.height > 1000000)
    throw Error(where + ": camera " + std::to_string(c.id) + " has image size " + std::to_string(c.width) + "x" +
                std::to_string(c.height));
  for (double p : c.params)
    if (!std::isfinite(p)) throw Error(where + ": camera " + std::to_string(c.id) + " has a non-finite parameter");
  if (!(c.fx() > 0 && c.fy() > 0))
    throw Error(where + ": camera " + std::to_string(c.id) + " has focal length " + fmt(c.fx()) + ", " + fmt(c.fy()) +
                " (must be positive)");
}

void check_image(const ColmapImage& im, const std::string& where) {
  for (double v : im.qvec)
    if (!std::isfinite(v)) throw Error(where + ": image " + std::to_string(im.id) + " (" + im.name + ") has a non-finite rotation");
  for (double v : im.tvec)
    if (!std::isfinite(v)) throw Error(where + ": image " + std::to_string(im.id) + " (" + im.name + ") has a non-finite translation");
  if (im.name.empty()) throw Error(where + ": image " + std::to_string(im.id) + " has an empty name");
}

}  // namespace

// --- cameras ---------------------------------------------------------------------------------------
int colmap_model_id(const std::string& name) {
  for (int i = 0; i < kModelCount; ++i)
    if (name == kModels[i].name) return i;
  return -1;
}
int colmap_param_count(int id) { return id >= 0 && id < kModelCount ? kModels[id].params : 0; }

double ColmapCamera::fx() const { return params.empty() ? 0 : params[0]; }
double ColmapCamera::fy() const { return params.size() < 2 ? 0 : kModels[model_id].separate_f ? params[1] : params[0]; }
double ColmapCamera::cx() const { return params.size() < 3 ? 0 : kModels[model_id].separate_f ? params[2] : params[1]; }
double ColmapCamera::cy() const { return params.size() < 4 ? params.size() == 3 ? params[2] : 0 : kModels[model_id].separate_f ? params[3] : params[2]; }
std::vector<double> ColmapCamera::distortion() const {
  const size_t skip = kModels[model_id].separate_f ? 4 : 3;
  return params.size() > skip ? std::vector<double>(params.begin() + skip, params.end()) : std::vector<double>{};
}
bool ColmapCamera::is_pinhole() const {
  if (kModels[model_id].fisheye) return false;
  for (double d : distortion())
    if (d != 0) return false;
  return true;
}
std::string ColmapCamera::model_name() const { return model_id >= 0 && model_id < kModelCount ? kModels[model_id].name : "?"; }

std::map<uint32_t, ColmapCamera> read_colmap_cameras(const std::string& path) {
  std::map<uint32_t, ColmapCamera> out;
  auto add = [&](ColmapCamera c, const std::string& where) {
    check_camera(c, where);
    if (!out.emplace(c.id, c).second) throw Error(where + ": camera id " + std::to_string(c.id) + " appears twice");
  };
  if (is_bin(path)) {
    Bin b(path);
    const uint64_t n = b.count("cameras", 4 + 4 + 8 + 8 + 3 * 8);
    for (uint64_t i = 0; i < n; ++i) {
      ColmapCamera c;
      c.id = b.get<uint32_t>("a camera id");
      const int32_t model = b.get<int32_t>("a camera model id");
      if (model < 0 || model >= kModelCount)
        b.fail("camera " + std::to_string(c.id) + " has unknown camera model id " + std::to_string(model) + " (known: " +
               model_list() + ")");
      c.model_id = model;
      c.width = b.get<uint64_t>("a camera width");
      c.height = b.get<uint64_t>("a camera height");
      for (int k = 0; k < kModels[model].params; ++k) c.params.push_back(b.get<double>("camera parameters"));
      add(c, path);
    }
    b.finish();
  } else {
    Text t(path);
    std::vector<std::string> tok;
    size_t line = 0;
    while (t.record(tok, line)) {
      if (tok.size() < 4) t.fail(line, "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...");
      ColmapCamera c;
      c.id = uint32_t(t.integer(tok[0], line, "camera id", 0, UINT32_MAX));
      c.model_id = colmap_model_id(tok[1]);
      if (c.model_id < 0) t.fail(line, "unknown camera model '" + tok[1] + "' (known: " + model_list() + ")");
      c.width = uint64_t(t.integer(tok[2], line, "width", 1, 1000000));
      c.height = uint64_t(t.integer(tok[3], line, "height", 1, 1000000));
      const int np = kModels[c.model_id].params;
      if (int(tok.size()) != 4 + np)
        t.fail(line, "camera model " + tok[1] + " takes " + std::to_string(np) + " parameters, the line has " +
                         std::to_string(tok.size() - 4));
      for (int k = 0; k < np; ++k) c.params.push_back(t.num(tok[4 + k], line, "camera parameter"));
      add(c, path + " line " + std::to_string(line));
    }
  }
  if (out.empty()) throw Error("COLMAP model: " + path + " holds no cameras");
  return out;
}

// --- images ----------------------------------------------------------------------------------------
std::vector<ColmapImage> read_colmap_images(const std::string& path) {
  std::vector<ColmapImage> out;
  std::set<uint32_t> ids;
  auto add = [&](ColmapImage im, const std::string& where) {
    check_image(im, where);
    if (!ids.insert(im.id).second) throw Error(where + ": image id " + std::to_string(im.id) + " appears twice");
    out.push_back(std::move(im));
  };
  if (is_bin(path)) {
    Bin b(path);
    const uint64_t n = b.count("images", 4 + 7 * 8 + 4 + 2 + 8);
    for (uint64_t i = 0; i < n; ++i) {
      ColmapImage im;
      im.id = b.get<uint32_t>("an image id");
      for (double& q : im.qvec) q = b.get<double>("an image rotation");
      for (double& v : im.tvec) v = b.get<double>("an image translation");
      im.camera_id = b.get<uint32_t>("an image's camera id");
      im.name = b.cstring("an image name");
      const uint64_t np = b.count("2D points", 24);
      im.xys.resize(np);
      im.point3d_ids.resize(np);
      for (uint64_t k = 0; k < np; ++k) {
        im.xys[k][0] = b.get<double>("a 2D point");
        im.xys[k][1] = b.get<double>("a 2D point");
        im.point3d_ids[k] = b.get<int64_t>("a 2D point's 3D point id");
      }
      add(std::move(im), path);
    }
    b.finish();
  } else {
    Text t(path);
    std::vector<std::string> tok;
    size_t line = 0;
    while (t.record(tok, line)) {
      if (tok.size() < 10) t.fail(line, "expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
      ColmapImage im;
      im.id = uint32_t(t.integer(tok[0], line, "image id", 0, UINT32_MAX));
      for (int k = 0; k < 4; ++k) im.qvec[k] = t.num(tok[1 + k], line, "rotation");
      for (int k = 0; k < 3; ++k) im.tvec[k] = t.num(tok[5 + k], line, "translation");
      im.camera_id = uint32_t(t.integer(tok[8], line, "camera id", 0, UINT32_MAX));
      // A name may hold spaces: the rest of the line.
      im.name = tok[9];
      for (size_t k = 10; k < tok.size(); ++k) im.name += " " + tok[k];
      size_t pline = 0;
      const std::vector<std::string> pts = t.raw(pline);
      if (pts.size() % 3 != 0)
        t.fail(pline, "the 2D points of image " + std::to_string(im.id) + " must be triples X Y POINT3D_ID (the line has " +
                          std::to_string(pts.size()) + " values)");
      for (size_t k = 0; k < pts.size(); k += 3) {
        im.xys.push_back({t.num(pts[k], pline, "2D point x"), t.num(pts[k + 1], pline, "2D point y")});
        im.point3d_ids.push_back(t.integer(pts[k + 2], pline, "3D point id", -1, INT64_MAX));
      }
      add(std::move(im), path + " line " + std::to_string(line));
    }
  }
  if (out.empty()) throw Error("COLMAP model: " + path + " holds no images");
  return out;
}

// --- points ----------------------------------------------------------------------------------------
std::vector<ColmapPoint> read_colmap_points(const std::string& path) {
  std::vector<ColmapPoint> out;
  auto check = [&](const ColmapPoint& p, const std::string& where) {
    for (double v : p.xyz)
      if (!std::isfinite(v)) throw Error(where + ": 3D point " + std::to_string(p.id) + " has a non-finite coordinate");
  };
  if (is_bin(path)) {
    Bin b(path);
    const uint64_t n = b.count("3D points", 8 + 24 + 3 + 8 + 8);
    for (uint64_t i = 0; i < n; ++i) {
      ColmapPoint p;
      p.id = b.get<uint64_t>("a 3D point id");
      for (double& v : p.xyz) v = b.get<double>("a 3D point");
      for (uint8_t& c : p.rgb) c = b.get<uint8_t>("a 3D point colour");
      p.error = b.get<double>("a 3D point error");
      const uint64_t nt = b.count("track entries", 8);
      p.track.resize(nt);
      for (auto& e : p.track) {
        e.first = b.get<uint32_t>("a track's image id");
        e.second = b.get<uint32_t>("a track's 2D point index");
      }
      check(p, path);
      out.push_back(std::move(p));
    }
    b.finish();
  } else {
    Text t(path);
    std::vector<std::string> tok;
    size_t line = 0;
    while (t.record(tok, line)) {
      if (tok.size() < 8 || (tok.size() - 8) % 2 != 0)
        t.fail(line, "expected POINT3D_ID X Y Z R G B ERROR and (IMAGE_ID POINT2D_IDX) pairs");
      ColmapPoint p;
      p.id = uint64_t(t.integer(tok[0], line, "3D point id", 0, INT64_MAX));
      for (int k = 0; k < 3; ++k) p.xyz[k] = t.num(tok[1 + k], line, "coordinate");
      for (int k = 0; k < 3; ++k) p.rgb[k] = uint8_t(t.integer(tok[4 + k], line, "colour", 0, 255));
      p.error = t.num(tok[7], line, "error");
      for (size_t k = 8; k < tok.size(); k += 2)
        p.track.push_back({uint32_t(t.integer(tok[k], line, "image id", 0, UINT32_MAX)),
                           uint32_t(t.integer(tok[k + 1], line, "2D point index", 0, UINT32_MAX))});
      check(p, path + " line " + std::to_string(line));
      out.push_back(std::move(p));
    }
  }
  return out;
}

// --- the model -------------------------------------------------------------------------------------
std::string find_colmap_model(const std::string& dir) {
  std::error_code ec;
  for (const fs::path& p : {fs::path(dir) / "sparse" / "0", fs::path(dir) / "sparse"})
    if (fs::exists(p / "cameras.bin", ec) || fs::exists(p / "cameras.txt", ec)) return p.string();
  return "";
}

ColmapModel read_colmap_model(const std::string& dir) {
  auto pick = [&](const std::string& stem) {
    std::error_code ec;
    const fs::path bin = fs::path(dir) / (stem + ".bin"), txt = fs::path(dir) / (stem + ".txt");
    if (fs::exists(bin, ec)) return bin.string();
    if (fs::exists(txt, ec)) return txt.string();
    throw Error("COLMAP model " + dir + ": " + stem + ".bin (or " + stem + ".txt) is missing");
  };
  ColmapModel m;
  m.dir = dir;
  const std::string cams = pick("cameras"), imgs = pick("images"), pts = pick("points3D");
  m.cameras = read_colmap_cameras(cams);
  m.images = read_colmap_images(imgs);
  m.points = read_colmap_points(pts);
  std::set<uint64_t> point_ids;
  for (const ColmapPoint& p : m.points)
    if (!point_ids.insert(p.id).second) throw Error(pts + ": 3D point id " + std::to_string(p.id) + " appears twice");
  std::set<std::string> names;
  for (const ColmapImage& im : m.images) {
    if (!m.cameras.count(im.camera_id))
      throw Error(imgs + ": image " + std::to_string(im.id) + " (" + im.name + ") refers to camera " +
                  std::to_string(im.camera_id) + ", which " + cams + " does not have");
    if (!names.insert(im.name).second) throw Error(imgs + ": image name " + im.name + " appears twice");
    for (int64_t id : im.point3d_ids)
      if (id != -1 && !point_ids.count(uint64_t(id)))
        throw Error(imgs + ": image " + std::to_string(im.id) + " (" + im.name + ") observes 3D point " +
                    std::to_string(id) + ", which " + pts + " does not have");
  }
  return m;
}

// --- writing ---------------------------------------------------------------------------------------
namespace {
template <class T>
void put(std::string& s, T v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}
}  // namespace

void write_colmap_model(const ColmapModel& m, const std::string& dir, bool binary) {
  fs::create_directories(dir);
  if (binary) {
    std::string c, i, p;
    put<uint64_t>(c, m.cameras.size());
    for (const auto& [id, cam] : m.cameras) {
      put<uint32_t>(c, id);
      put<int32_t>(c, cam.model_id);
      put<uint64_t>(c, cam.width);
      put<uint64_t>(c, cam.height);
      for (double v : cam.params) put<double>(c, v);
    }
    put<uint64_t>(i, m.images.size());
    for (const ColmapImage& im : m.images) {
      put<uint32_t>(i, im.id);
      for (double v : im.qvec) put<double>(i, v);
      for (double v : im.tvec) put<double>(i, v);
      put<uint32_t>(i, im.camera_id);
      i += im.name;
      i += '\0';
      put<uint64_t>(i, im.point3d_ids.size());
      for (size_t k = 0; k < im.point3d_ids.size(); ++k) {
        put<double>(i, k < im.xys.size() ? im.xys[k][0] : 0.0);
        put<double>(i, k < im.xys.size() ? im.xys[k][1] : 0.0);
        put<int64_t>(i, im.point3d_ids[k]);
      }
    }
    put<uint64_t>(p, m.points.size());
    for (const ColmapPoint& pt : m.points) {
      put<uint64_t>(p, pt.id);
      for (double v : pt.xyz) put<double>(p, v);
      for (uint8_t v : pt.rgb) put<uint8_t>(p, v);
      put<double>(p, pt.error);
      put<uint64_t>(p, pt.track.size());
      for (const auto& e : pt.track) put<uint32_t>(p, e.first), put<uint32_t>(p, e.second);
    }
    host::write_file_atomic((fs::path(dir) / "cameras.bin").string(), c);
    host::write_file_atomic((fs::path(dir) / "images.bin").string(), i);
    host::write_file_atomic((fs::path(dir) / "points3D.bin").string(), p);
    return;
  }
  std::ostringstream c, i, p;
  for (auto* o : {&c, &i, &p}) *o << std::setprecision(17);
  c << "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    << "# Number of cameras: " << m.cameras.size() << "\n";
  for (const auto& [id, cam] : m.cameras) {
    c << id << " " << cam.model_name() << " " << cam.width << " " << cam.height;
    for (double v : cam.params) c << " " << v;
    c << "\n";
  }
  i << "# Image list with two lines of data per image:\n"
    << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
    << "# Number of images: " << m.images.size() << "\n";
  for (const ColmapImage& im : m.images) {
    i << im.id;
    for (double v : im.qvec) i << " " << v;
    for (double v : im.tvec) i << " " << v;
    i << " " << im.camera_id << " " << im.name << "\n";
    for (size_t k = 0; k < im.point3d_ids.size(); ++k)
      i << (k ? " " : "") << (k < im.xys.size() ? im.xys[k][0] : 0.0) << " " << (k < im.xys.size() ? im.xys[k][1] : 0.0)
        << " " << im.point3d_ids[k];
    i << "\n";
  }
  p << "# 3D point list with one line of data per point:\n"
    << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
    << "# Number of points: " << m.points.size() << "\n";
  for (const ColmapPoint& pt : m.points) {
    p << pt.id << " " << pt.xyz[0] << " " << pt.xyz[1] << " " << pt.xyz[2] << " " << int(pt.rgb[0]) << " "
      << int(pt.rgb[1]) << " " << int(pt.rgb[2]) << " " << pt.error;
    for (const auto& e : pt.track) p << " " << e.first << " " << e.second;
    p << "\n";
  }
  host::write_file_atomic((fs::path(dir) / "cameras.txt").string(), c.str());
  host::write_file_atomic((fs::path(dir) / "images.txt").string(), i.str());
  host::write_file_atomic((fs::path(dir) / "points3D.txt").string(), p.str());
}

// --- poses -----------------------------------------------------------------------------------------
Pose colmap_c2w(const std::array<double, 4>& q_in, const std::array<double, 3>& t, const std::string& what) {
  const double len = std::sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
  if (!(len > 1e-12) || !std::isfinite(len))
    throw Error(what + ": the rotation quaternion (" + fmt(q_in[0]) + ", " + fmt(q_in[1]) + ", " + fmt(q_in[2]) + ", " +
                fmt(q_in[3]) + ") is zero or not finite");
  const double w = q_in[0] / len, x = q_in[1] / len, y = q_in[2] / len, z = q_in[3] / len;
  // World-to-camera rotation (COLMAP's qvec2rotmat).
  const double R[3][3] = {{1 - 2 * y * y - 2 * z * z, 2 * x * y - 2 * w * z, 2 * z * x + 2 * w * y},
                          {2 * x * y + 2 * w * z, 1 - 2 * x * x - 2 * z * z, 2 * y * z - 2 * w * x},
                          {2 * z * x - 2 * w * y, 2 * y * z + 2 * w * x, 1 - 2 * x * x - 2 * y * y}};
  Pose p;
  for (int r = 0; r < 3; ++r) {
    // c2w rotation is R^T; OpenCV -> OpenGL flips the camera's y and z axes (columns 1 and 2).
    p.m[r][0] = R[0][r];
    p.m[r][1] = -R[1][r];
    p.m[r][2] = -R[2][r];
    p.m[r][3] = -(R[0][r] * t[0] + R[1][r] * t[1] + R[2][r] * t[2]);
  }
  return p;
}

void c2w_to_colmap(const Pose& c2w, std::array<double, 4>& q, std::array<double, 3>& t) {
  // World-to-camera rotation in OpenCV axes: rows are the camera's x, -y, -z axes in world space.
  double R[3][3];
  for (int c = 0; c < 3; ++c) {
    R[0][c] = c2w.m[c][0];
    R[1][c] = -c2w.m[c][1];
    R[2][c] = -c2w.m[c][2];
  }
  for (int r = 0; r < 3; ++r) t[r] = -(R[r][0] * c2w.m[0][3] + R[r][1] * c2w.m[1][3] + R[r][2] * c2w.m[2][3]);
  // Rotation matrix -> quaternion (Shepperd), w >= 0 as COLMAP keeps it.
  const double tr = R[0][0] + R[1][1] + R[2][2];
  double w, x, y, z;
  if (tr > 0) {
    const double s = std::sqrt(tr + 1.0) * 2;
    w = 0.25 * s, x = (R[2][1] - R[1][2]) / s, y = (R[0][2] - R[2][0]) / s, z = (R[1][0] - R[0][1]) / s;
  } else if (R[0][0] > R[1][1] && R[0][0] > R[2][2]) {
    const double s = std::sqrt(1.0 + R[0][0] - R[1][1] - R[2][2]) * 2;
    w = (R[2][1] - R[1][2]) / s, x = 0.25 * s, y = (R[0][1] + R[1][0]) / s, z = (R[0][2] + R[2][0]) / s;
  } else if (R[1][1] > R[2][2]) {
    const double s = std::sqrt(1.0 + R[1][1] - R[0][0] - R[2][2]) * 2;
    w = (R[0][2] - R[2][0]) / s, x = (R[0][1] + R[1][0]) / s, y = 0.25 * s, z = (R[1][2] + R[2][1]) / s;
  } else {
    const double s = std::sqrt(1.0 + R[2][2] - R[0][0] - R[1][1]) * 2;
    w = (R[1][0] - R[0][1]) / s, x = (R[0][2] + R[2][0]) / s, y = (R[1][2] + R[2][1]) / s, z = 0.25 * s;
  }
  if (w < 0) w = -w, x = -x, y = -y, z = -z;
  q = {w, x, y, z};
}

}  // namespace stylerf::scene
