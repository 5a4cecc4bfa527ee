// How well one capture's camera poses agree with another's (an import against published poses, or a
// recovered scene against the truth): views matched by image file name (stem), the similarity transform
// (scale, rotation, translation) that best maps the second capture onto the first (least squares, Horn's
// closed form: the rotation from the cameras' orientations, scale and translation from their centres), and
// each view's remaining rotation and position error.
#pragma once
#include <array>
#include <string>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

struct Similarity {
  double scale = 1;
  double R[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::array<double, 3> t{0, 0, 0};
  std::array<double, 3> apply(const std::array<double, 3>& p) const;  // scale * R p + t
};

// The similarity with sum_i |a_i - (s R b_i + t)|^2 smallest (needs 3 or more points not all on a line).
Similarity fit_similarity(const std::vector<std::array<double, 3>>& a, const std::vector<std::array<double, 3>>& b);

struct PoseAgreement {
  int matched = 0;
  std::vector<std::string> only_in_reference, only_in_other;  // image stems without a partner
  Similarity similarity;                                      // other -> reference
  std::vector<double> rotation_deg;                           // per matched view, sorted by name
  std::vector<double> position;                               // per matched view, in reference units
  double reference_size = 0;  // the diagonal of the reference camera centres' bounding box
  double median_rotation_deg() const;
  double max_rotation_deg() const;
  double median_position() const;  // / reference_size
  double max_position() const;     // / reference_size
  std::string describe() const;
};

// Both scenes' train and test views, matched by file stem; a stem in both splits (Blender's train/r_0.png and
// test/r_0.png) stands for its train view. Throws when fewer than 3 views match.
PoseAgreement compare_poses(const Scene& reference, const Scene& other);

}  // namespace stylerf::scene
