// `stylerf import`: a folder of photos to a scene folder the loaders read as it is, by running COLMAP
// (https://colmap.github.io; Debian's `colmap` runs headless on a CPU):
//   1. feature_extractor (SIFT on the CPU; one shared camera unless asked otherwise),
//   2. exhaustive_matcher up to kExhaustiveLimit images, sequential_matcher beyond (auto),
//   3. mapper; the model with the most registered images is kept,
//   4. image_undistorter, so that every image projects as a pinhole (what the COLMAP loader accepts).
// The scene folder gets images/ (undistorted) and sparse/0/ (the undistorted model), plus colmap/ with the
// database, the mapper's model and each phase's log. It is built beside OUT and renamed into place last,
// so a killed import leaves no half-written scene. Near/far bounds, the forward-facing (NDC) or 360
// decision and the box are then the COLMAP loader's (capture_geometry.hpp).
//
// Refused, each naming the files: fewer than kMinImages images, files that are not images, images of
// mixed sizes, colmap missing (with how to install it), and fewer than 80% of the images registered (the
// ones left out are named; at 80% or more the import goes on and names them).
#pragma once
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace stylerf::scene {

struct ImportOptions {
  std::string images;                      // the photos (PNG, JPEG, BMP, TGA), all one size
  std::string out;                         // the scene folder to write
  std::string camera_model = "SIMPLE_RADIAL";  // COLMAP's model (its default) for the extractor; undistorted after
  bool single_camera = true;               // one camera shared by every image
  std::string matcher = "auto";            // auto | exhaustive | sequential
  int max_image_size = 0;                  // the longest image side COLMAP works at and writes (0: as given)
  std::string colmap = "colmap";           // the executable (a name on PATH or a path)
  bool force = false;                      // replace an existing OUT
  int threads = 0;                         // COLMAP's --*.num_threads (0: all cores)
};

constexpr int kMinImages = 3;
constexpr int kExhaustiveLimit = 150;

struct ImportReport {
  int images = 0, registered = 0;
  std::vector<std::string> left_out;      // images COLMAP did not register
  std::vector<std::pair<std::string, double>> phase_seconds;  // in order
  std::string matcher;                    // the one that ran
  double mean_reprojection_error = 0;     // pixels, over the kept model's points
  std::vector<std::string> notes;         // EXIF orientations and the like
};

// Progress lines ("features 12/20 images, 14 s") go to `progress`.
ImportReport import_with_colmap(const ImportOptions& opts, const std::function<void(const std::string&)>& progress);

}  // namespace stylerf::scene
