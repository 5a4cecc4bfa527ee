// COLMAP sparse models (cameras, images, points3D; .bin or .txt, COLMAP's documented formats), read and
// written. Reading validates everything a loader relies on and refuses bad files with a host::Error naming
// the file and what is wrong (truncated, counts that do not match the file, unknown camera models, images
// of missing cameras, non-finite poses).
//
// COLMAP stores world-to-camera poses: x_cam = R(q) x_world + t with q = (qw, qx, qy, qz), in the OpenCV
// camera frame (x right, y down, z forward). colmap_c2w() turns one into our camera-to-world matrix in the
// OpenGL frame (x right, y up, looking down -z). Pixel centres are at +0.5 in both.
#pragma once
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "lib/scene/poses.hpp"

namespace stylerf::scene {

struct ColmapCamera {
  uint32_t id = 0;
  int model_id = 1;            // COLMAP's id: 0 SIMPLE_PINHOLE, 1 PINHOLE, 2 SIMPLE_RADIAL, 3 RADIAL, 4 OPENCV, ...
  uint64_t width = 0, height = 0;
  std::vector<double> params;  // as COLMAP orders them for the model
  double fx() const;
  double fy() const;
  double cx() const;
  double cy() const;
  // Distortion parameters (everything that is not focal length or principal point), in COLMAP's order.
  std::vector<double> distortion() const;
  // True when the model projects as a pinhole: a pinhole model, or a distorted one with zero distortion.
  bool is_pinhole() const;
  std::string model_name() const;
};

struct ColmapImage {
  uint32_t id = 0;
  std::array<double, 4> qvec{1, 0, 0, 0};  // w, x, y, z
  std::array<double, 3> tvec{0, 0, 0};
  uint32_t camera_id = 0;
  std::string name;
  std::vector<std::array<double, 2>> xys;  // 2D points
  std::vector<int64_t> point3d_ids;        // one per 2D point, -1 where none
};

struct ColmapPoint {
  uint64_t id = 0;
  std::array<double, 3> xyz{0, 0, 0};
  std::array<uint8_t, 3> rgb{128, 128, 128};
  double error = 0;
  std::vector<std::pair<uint32_t, uint32_t>> track;  // (image id, 2D point index)
};

struct ColmapModel {
  std::string dir;
  std::map<uint32_t, ColmapCamera> cameras;
  std::vector<ColmapImage> images;
  std::vector<ColmapPoint> points;
};

// COLMAP's model id for a name ("PINHOLE" -> 1) and its parameter count; -1 / 0 when unknown.
int colmap_model_id(const std::string& name);
int colmap_param_count(int model_id);

// The three files of a model (cameras, images, points3D), each .bin or .txt (.bin preferred when a folder
// has both). Each reader checks only its own file; read_colmap_model also checks that every image's camera
// exists and that every observation names a point that exists (or -1).
std::map<uint32_t, ColmapCamera> read_colmap_cameras(const std::string& path);
std::vector<ColmapImage> read_colmap_images(const std::string& path);
std::vector<ColmapPoint> read_colmap_points(const std::string& path);
ColmapModel read_colmap_model(const std::string& dir);
// The folder of a model under a scene: <dir>/sparse/0 or <dir>/sparse (the first holding cameras.bin/.txt);
// "" when neither does.
std::string find_colmap_model(const std::string& dir);

// Writes the model in COLMAP's binary or text format (cameras, images, points3D).
void write_colmap_model(const ColmapModel& m, const std::string& dir, bool binary);

// COLMAP world-to-camera (qvec wxyz, tvec; OpenCV axes) -> camera-to-world in OpenGL axes; and back.
// The quaternion is normalised first; `what` names it in the error when it is zero or not finite.
Pose colmap_c2w(const std::array<double, 4>& qvec, const std::array<double, 3>& tvec, const std::string& what);
void c2w_to_colmap(const Pose& c2w, std::array<double, 4>& qvec, std::array<double, 3>& tvec);

}  // namespace stylerf::scene
