#include "lib/scene/pose_alignment.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "host/error.hpp"

namespace stylerf::scene {

using host::Error;
using P3 = std::array<double, 3>;

std::array<double, 3> Similarity::apply(const P3& p) const {
  P3 out{};
  for (int r = 0; r < 3; ++r) out[r] = scale * (R[r][0] * p[0] + R[r][1] * p[1] + R[r][2] * p[2]) + t[r];
  return out;
}

namespace {

// The unit eigenvector of the largest eigenvalue of a symmetric 4x4 matrix (cyclic Jacobi rotations).
std::array<double, 4> top_eigenvector(double a[4][4]) {
  double v[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};
  for (int sweep = 0; sweep < 60; ++sweep) {
    double off = 0;
    for (int p = 0; p < 4; ++p)
      for (int q = p + 1; q < 4; ++q) off += a[p][q] * a[p][q];
    if (off < 1e-30) break;
    for (int p = 0; p < 4; ++p)
      for (int q = p + 1; q < 4; ++q) {
        if (std::abs(a[p][q]) < 1e-300) continue;
        const double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const double t = (theta >= 0 ? 1 : -1) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 4; ++k) {  // A <- J^T A J, V <- V J
          const double akp = a[k][p], akq = a[k][q];
          a[k][p] = c * akp - s * akq;
          a[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < 4; ++k) {
          const double apk = a[p][k], aqk = a[q][k];
          a[p][k] = c * apk - s * aqk;
          a[q][k] = s * apk + c * aqk;
        }
        for (int k = 0; k < 4; ++k) {
          const double vkp = v[k][p], vkq = v[k][q];
          v[k][p] = c * vkp - s * vkq;
          v[k][q] = s * vkp + c * vkq;
        }
      }
  }
  int best = 0;
  for (int i = 1; i < 4; ++i)
    if (a[i][i] > a[best][best]) best = i;
  return {v[0][best], v[1][best], v[2][best], v[3][best]};
}

P3 centroid(const std::vector<P3>& pts) {
  P3 c{0, 0, 0};
  for (const auto& p : pts)
    for (int k = 0; k < 3; ++k) c[k] += p[k] / double(pts.size());
  return c;
}

// The angle of M = a^T b from atan2(sin, cos): |(M32 - M23, M13 - M31, M21 - M12)| = 2 sin, tr M = 1 + 2 cos.
// acos of the trace alone loses half the digits near 0 (float matrices: ~0.01 degrees of noise).
double angle_between_deg(const double a[3][3], const double b[3][3]) {
  double M[3][3] = {};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) M[i][j] += a[k][i] * b[k][j];
  const double vx = M[2][1] - M[1][2], vy = M[0][2] - M[2][0], vz = M[1][0] - M[0][1];
  const double sin2 = std::sqrt(vx * vx + vy * vy + vz * vz), cos2 = M[0][0] + M[1][1] + M[2][2] - 1;
  return std::atan2(sin2, cos2) * 180.0 / M_PI;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::map<std::string, const Camera*> cameras_by_stem(const Scene& s) {
  std::map<std::string, const Camera*> out;
  for (const auto* views : {&s.train, &s.test})
    for (const View& v : *views) out.emplace(std::filesystem::path(v.image_path).stem().string(), &v.camera);
  return out;
}


// Horn (1987): the rotation R with sum a_i . R b_i largest is the quaternion of the largest eigenvalue of N(S),
// S = sum b_i a_i^T.
void horn_rotation(const double S[3][3], double R[3][3]) {
  double N[4][4] = {{S[0][0] + S[1][1] + S[2][2], S[1][2] - S[2][1], S[2][0] - S[0][2], S[0][1] - S[1][0]},
                    {S[1][2] - S[2][1], S[0][0] - S[1][1] - S[2][2], S[0][1] + S[1][0], S[2][0] + S[0][2]},
                    {S[2][0] - S[0][2], S[0][1] + S[1][0], -S[0][0] + S[1][1] - S[2][2], S[1][2] + S[2][1]},
                    {S[0][1] - S[1][0], S[2][0] + S[0][2], S[1][2] + S[2][1], -S[0][0] - S[1][1] + S[2][2]}};
  const auto q = top_eigenvector(N);
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  const double r[3][3] = {{w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)},
                          {2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)},
                          {2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z}};
  std::copy(&r[0][0], &r[0][0] + 9, &R[0][0]);
}

// Given R: the scale and translation that fit the centred points best.
void fit_scale_translation(const std::vector<P3>& a, const std::vector<P3>& b, Similarity& sim) {
  const P3 ca = centroid(a), cb = centroid(b);
  double num = 0, den = 0;
  for (size_t i = 0; i < a.size(); ++i)
    for (int r = 0; r < 3; ++r) {
      double rb = 0;
      for (int c = 0; c < 3; ++c) rb += sim.R[r][c] * (b[i][c] - cb[c]);
      num += (a[i][r] - ca[r]) * rb;
      den += (b[i][r] - cb[r]) * (b[i][r] - cb[r]);
    }
  if (den <= 0) throw Error("fit_similarity: the points to align all coincide");
  sim.scale = num / den;
  for (int r = 0; r < 3; ++r)
    sim.t[r] = ca[r] - sim.scale * (sim.R[r][0] * cb[0] + sim.R[r][1] * cb[1] + sim.R[r][2] * cb[2]);
}

}  // namespace

Similarity fit_similarity(const std::vector<P3>& a, const std::vector<P3>& b) {
  if (a.size() != b.size() || a.size() < 3) throw Error("fit_similarity: needs 3 or more matched points");
  const P3 ca = centroid(a), cb = centroid(b);
  double S[3][3] = {};
  for (size_t i = 0; i < a.size(); ++i)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) S[r][c] += (b[i][r] - cb[r]) * (a[i][c] - ca[c]);
  Similarity sim;
  horn_rotation(S, sim.R);
  fit_scale_translation(a, b, sim);
  return sim;
}

PoseAgreement compare_poses(const Scene& reference, const Scene& other) {
  const auto ref = cameras_by_stem(reference), oth = cameras_by_stem(other);
  PoseAgreement out;
  std::vector<P3> a, b;
  std::vector<std::pair<const Camera*, const Camera*>> pairs;
  for (const auto& [name, cam] : ref) {
    const auto it = oth.find(name);
    if (it == oth.end()) {
      out.only_in_reference.push_back(name);
      continue;
    }
    a.push_back({cam->c2w[0][3], cam->c2w[1][3], cam->c2w[2][3]});
    b.push_back({it->second->c2w[0][3], it->second->c2w[1][3], it->second->c2w[2][3]});
    pairs.emplace_back(cam, it->second);
  }
  for (const auto& [name, cam] : oth)
    if (!ref.count(name)) out.only_in_other.push_back(name);
  if (pairs.size() < 3)
    throw Error("compare poses: only " + std::to_string(pairs.size()) + " views of " + reference.root + " and " +
                other.root + " share an image name; 3 or more are needed");
  out.matched = int(pairs.size());
  // The rotation from the cameras' orientations (their axes as points: the R with sum_i tr(Ra_i^T R Rb_i)
  // largest), not from their centres: the centres of a forward-facing capture lie near a plane and pin its
  // tilt down poorly. Scale and translation then from the centres.
  double S[3][3] = {};
  for (const auto& [ca, cb] : pairs)
    for (int k = 0; k < 3; ++k)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) S[r][c] += double(cb->c2w[r][k]) * double(ca->c2w[c][k]);
  horn_rotation(S, out.similarity.R);
  fit_scale_translation(a, b, out.similarity);
  P3 lo = a[0], hi = a[0];
  for (const auto& p : a)
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  out.reference_size = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                 (hi[2] - lo[2]) * (hi[2] - lo[2]));
  for (size_t i = 0; i < pairs.size(); ++i) {
    double ra[3][3], rb[3][3];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        ra[r][c] = pairs[i].first->c2w[r][c];
        double s = 0;
        for (int k = 0; k < 3; ++k) s += out.similarity.R[r][k] * pairs[i].second->c2w[k][c];
        rb[r][c] = s;
      }
    out.rotation_deg.push_back(angle_between_deg(ra, rb));
    const P3 m = out.similarity.apply(b[i]);
    out.position.push_back(std::sqrt((m[0] - a[i][0]) * (m[0] - a[i][0]) + (m[1] - a[i][1]) * (m[1] - a[i][1]) +
                                     (m[2] - a[i][2]) * (m[2] - a[i][2])));
  }
  return out;
}

double PoseAgreement::median_rotation_deg() const { return median_of(rotation_deg); }
double PoseAgreement::max_rotation_deg() const {
  return rotation_deg.empty() ? 0 : *std::max_element(rotation_deg.begin(), rotation_deg.end());
}
double PoseAgreement::median_position() const { return reference_size > 0 ? median_of(position) / reference_size : 0; }
double PoseAgreement::max_position() const {
  return position.empty() || reference_size <= 0 ? 0 : *std::max_element(position.begin(), position.end()) / reference_size;
}

std::string PoseAgreement::describe() const {
  std::ostringstream s;
  s << matched << " views matched by image name";
  if (!only_in_reference.empty()) s << ", " << only_in_reference.size() << " only in the reference";
  if (!only_in_other.empty()) s << ", " << only_in_other.size() << " only in the other";
  s << "\n  after a similarity alignment (scale " << similarity.scale << "): rotation error median "
    << median_rotation_deg() << " deg, max " << max_rotation_deg() << " deg; position error median "
    << 100 * median_position() << "%, max " << 100 * max_position()
    << "% of the reference cameras' extent (" << reference_size << ")";
  return s.str();
}

}  // namespace stylerf::scene
