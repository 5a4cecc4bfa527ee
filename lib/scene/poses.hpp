// Small camera-pose algebra in double precision for the loaders and camera paths: 3x4 camera-to-world
// matrices [R | t], the LLFF "average pose", look-at frames, and the point nearest to many lines.
#pragma once
#include <array>
#include <vector>

#include "lib/scene/scene.hpp"

namespace stylerf::scene {

using Vec3 = std::array<double, 3>;
struct Pose {
  double m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
  Vec3 axis(int c) const { return {m[0][c], m[1][c], m[2][c]}; }  // column c (3 = position)
};

Vec3 add(Vec3 a, Vec3 b);
Vec3 sub(Vec3 a, Vec3 b);
Vec3 scale(Vec3 a, double s);
double dot(Vec3 a, Vec3 b);
Vec3 cross(Vec3 a, Vec3 b);
double norm(Vec3 a);
Vec3 normalize(Vec3 a);

// A camera's camera-to-world matrix as a pose, and a camera with another pose (its intrinsics kept).
Pose pose_of(const Camera& c);
Camera with_pose(Camera intrinsics, const Pose& p);

// Camera frame with z axis (backwards, OpenGL) along `z`, y close to `up`, at `position`.
Pose view_matrix(Vec3 z, Vec3 up, Vec3 position);
// A camera at `eye` looking at `target` with the given up direction (OpenGL: looks down -z).
Pose look_at(Vec3 eye, Vec3 target, Vec3 up);
// LLFF's average pose: mean position, summed z axes and summed y axes orthonormalised.
Pose average_pose(const std::vector<Pose>& poses);
// a^-1 * b for rigid poses (a's rotation orthonormal).
Pose relative(const Pose& a, const Pose& b);
// The point minimising the summed squared distance to the lines (origin o_i, direction d_i).
Vec3 nearest_point_to_lines(const std::vector<Vec3>& origins, const std::vector<Vec3>& directions);

}  // namespace stylerf::scene
