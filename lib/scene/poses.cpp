#include "lib/scene/poses.hpp"

#include <cmath>

#include "host/error.hpp"

namespace stylerf::scene {

Vec3 add(Vec3 a, Vec3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec3 sub(Vec3 a, Vec3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec3 scale(Vec3 a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(Vec3 a, Vec3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 cross(Vec3 a, Vec3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double norm(Vec3 a) { return std::sqrt(dot(a, a)); }
Vec3 normalize(Vec3 a) {
  double n = norm(a);
  return n > 0 ? scale(a, 1.0 / n) : a;
}

Pose pose_of(const Camera& c) {
  Pose p;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) p.m[r][k] = c.c2w[r][k];
  return p;
}

Camera with_pose(Camera c, const Pose& p) {
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 4; ++k) c.c2w[r][k] = float(p.m[r][k]);
  return c;
}

Pose view_matrix(Vec3 z, Vec3 up, Vec3 position) {
  Vec3 zz = normalize(z);
  Vec3 x = normalize(cross(up, zz));
  Vec3 y = normalize(cross(zz, x));
  Pose p;
  for (int r = 0; r < 3; ++r) {
    p.m[r][0] = x[r];
    p.m[r][1] = y[r];
    p.m[r][2] = zz[r];
    p.m[r][3] = position[r];
  }
  return p;
}

Pose look_at(Vec3 eye, Vec3 target, Vec3 up) { return view_matrix(sub(eye, target), up, eye); }

Pose average_pose(const std::vector<Pose>& poses) {
  Vec3 centre{0, 0, 0}, z{0, 0, 0}, y{0, 0, 0};
  for (const Pose& p : poses) {
    centre = add(centre, p.axis(3));
    z = add(z, p.axis(2));
    y = add(y, p.axis(1));
  }
  return view_matrix(z, y, scale(centre, 1.0 / double(poses.size())));
}

Pose relative(const Pose& a, const Pose& b) {
  // a^-1 = [R^T | -R^T t]; a^-1 b = [R^T Rb | R^T (tb - t)].
  Pose out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      double v = 0;
      for (int k = 0; k < 3; ++k) v += a.m[k][r] * (c < 3 ? b.m[k][c] : b.m[k][3] - a.m[k][3]);
      out.m[r][c] = v;
    }
  return out;
}

Vec3 nearest_point_to_lines(const std::vector<Vec3>& origins, const std::vector<Vec3>& directions) {
  // sum_i (I - d_i d_i^T) p = sum_i (I - d_i d_i^T) o_i, solved by Cramer's rule (3x3).
  double A[3][3] = {}, b[3] = {};
  for (size_t i = 0; i < origins.size(); ++i) {
    Vec3 d = normalize(directions[i]);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        double m = (r == c ? 1.0 : 0.0) - d[r] * d[c];
        A[r][c] += m;
        b[r] += m * origins[i][c];
      }
  }
  auto det3 = [](double M[3][3]) {
    return M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) - M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
           M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
  };
  double D = det3(A);
  if (std::fabs(D) < 1e-12) throw host::Error("nearest_point_to_lines: the optical axes are (nearly) parallel");
  Vec3 p;
  for (int k = 0; k < 3; ++k) {
    double M[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) M[r][c] = c == k ? b[r] : A[r][c];
    p[k] = det3(M) / D;
  }
  return p;
}

}  // namespace stylerf::scene
