// The background shell (lib/render/background_shell.hpp, kernels/background_shell.cl): the map read where
// each ray leaves the sphere, composited behind it, against a double reference; its gradients w.r.t. the
// opacity and the map against central differences of that reference; and the hard cases: rays straight up
// and down (the poles), rays across the map's seam, an origin at the centre and one outside the sphere,
// opaque rays, many rays on one texel, and no rays at all.
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <vector>

#include "host/tensor.hpp"
#include "lib/render/background_shell.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Rays {
  std::vector<float> origins, dirs, acc;
  int count() const { return int(acc.size()); }
  void add(std::array<float, 3> o, std::array<float, 3> d, float a) {
    origins.insert(origins.end(), o.begin(), o.end());
    dirs.insert(dirs.end(), d.begin(), d.end());
    acc.push_back(a);
  }
};

// The background of ray r in double: the exit point's direction, its latitude-longitude position, the
// four texels (rows clamped, columns wrapped) and their bilinear weights.
std::vector<double> reference_background(const Rays& rays, int r, const std::vector<double>& map, int H, int W, int C,
                                         double radius, std::array<int, 4>* texels = nullptr,
                                         std::array<double, 4>* weights = nullptr) {
  double o[3], d[3], len = 0;
  for (int k = 0; k < 3; ++k) o[k] = rays.origins[3 * r + k], d[k] = rays.dirs[3 * r + k], len += d[k] * d[k];
  len = std::sqrt(len);
  for (double& x : d) x /= len;
  const double b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
  const double c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - radius * radius;
  double u[3] = {d[0], d[1], d[2]};
  if (c < 0) {
    const double t = -b + std::sqrt(b * b - c);
    for (int k = 0; k < 3; ++k) u[k] = (o[k] + t * d[k]) / radius;
  }
  const double n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  const double theta = std::acos(std::clamp(u[2] / n, -1.0, 1.0)), phi = std::atan2(u[1], u[0]);
  const double y = theta / kPi * H - 0.5, x = (phi + kPi) / (2 * kPi) * W - 0.5;
  const double y0 = std::floor(y), x0 = std::floor(x), fy = y - y0, fx = x - x0;
  const int r0 = std::clamp(int(y0), 0, H - 1), r1 = std::clamp(int(y0) + 1, 0, H - 1);
  const int c0 = ((int(x0) % W) + W) % W, c1 = (c0 + 1) % W;
  const std::array<int, 4> t{r0 * W + c0, r0 * W + c1, r1 * W + c0, r1 * W + c1};
  const std::array<double, 4> w{(1 - fy) * (1 - fx), (1 - fy) * fx, fy * (1 - fx), fy * fx};
  if (texels) *texels = t;
  if (weights) *weights = w;
  std::vector<double> bg(size_t(C), 0.0);
  for (int k = 0; k < 4; ++k)
    for (int ch = 0; ch < C; ++ch) bg[size_t(ch)] += w[size_t(k)] * map[size_t(t[size_t(k)]) * C + ch];
  return bg;
}

// out = value + (1 - acc) bg, all rays.
std::vector<double> reference_forward(const Rays& rays, const std::vector<double>& value, const std::vector<double>& acc,
                                      const std::vector<double>& map, int H, int W, int C, double radius) {
  std::vector<double> out = value;
  for (int r = 0; r < rays.count(); ++r) {
    const std::vector<double> bg = reference_background(rays, r, map, H, W, C, radius);
    for (int ch = 0; ch < C; ++ch) out[size_t(r) * C + ch] += (1 - acc[size_t(r)]) * bg[size_t(ch)];
  }
  return out;
}

// Rays from inside the sphere in general directions, and the hard ones.
Rays test_rays(uint64_t seed, int general) {
  Rays rays;
  const std::vector<float> o = testing::random_uniform(size_t(3) * general, seed, -0.9f, 0.9f);
  const std::vector<float> d = testing::random_normal(size_t(3) * general, seed + 1);
  const std::vector<float> a = testing::random_uniform(size_t(general), seed + 2, 0.0f, 1.0f);
  for (int r = 0; r < general; ++r)
    rays.add({o[3 * r], o[3 * r + 1], o[3 * r + 2]}, {d[3 * r], d[3 * r + 1], d[3 * r + 2]}, a[size_t(r)]);
  rays.add({0, 0, 0}, {0, 0, 1}, 0.3f);          // from the centre, straight up: the north pole
  rays.add({0.2f, -0.1f, 0}, {0, 0, -2}, 0.0f);  // straight down, a direction that is not unit
  rays.add({0, 0, 0.1f}, {-1, 1e-7f, 0}, 0.5f);  // along the seam (phi just below +pi)
  rays.add({0, 0, 0.1f}, {-1, -1e-7f, 0}, 0.5f); // ... and just above -pi
  rays.add({5, 0, 0}, {0.3f, 0.4f, 0.5f}, 0.2f); // from outside the sphere: read by the direction
  rays.add({0.1f, 0.2f, 0.3f}, {1, 1, 0}, 1.0f); // opaque: no background
  return rays;
}

}  // namespace

TEST_CASE("the background shell reads the map where each ray leaves the sphere, as a double reference") {
  const int H = 8, W = 16, C = 5;
  const float radius = 2.5f;
  const Rays rays = test_rays(11, 40);
  const int R = rays.count();
  const std::vector<float> map = testing::random_normal(size_t(H) * W * C, 3);
  const std::vector<float> value = testing::random_normal(size_t(R) * C, 4);
  const Tensor origins = Tensor::from_host(rays.origins, {R, 3}), dirs = Tensor::from_host(rays.dirs, {R, 3});
  const render::ShellTaps taps = render::background_shell_taps(origins, dirs, radius, H, W);
  Tensor out = Tensor::from_host(value, {R, C});
  render::background_shell_forward(out, Tensor::from_host(rays.acc, {R}), Tensor::from_host(map, {H * W, C}), taps);
  const std::vector<double> want = reference_forward(rays, testing::to_double(value), testing::to_double(rays.acc),
                                                     testing::to_double(map), H, W, C, radius);
  check_close(out.to_host(), want, 1e-4, 1e-5, "shell forward");

  // The weights are a partition of unity, and the opaque ray is unchanged.
  const std::vector<float> w = taps.w.to_host();
  for (int r = 0; r < R; ++r) CHECK(std::fabs(w[4 * r] + w[4 * r + 1] + w[4 * r + 2] + w[4 * r + 3] - 1.0f) < 1e-5f);
  const std::vector<float> got = out.to_host();
  for (int ch = 0; ch < C; ++ch) CHECK(got[size_t(R - 1) * C + ch] == value[size_t(R - 1) * C + ch]);

  // The pole ray reads the top row only (its rows clamp to 0), the seam rays the columns on both sides of
  // the seam (W - 1 and 0), the two sides agreeing to the map's continuity.
  std::array<int, 4> t;
  reference_background(rays, R - 6, testing::to_double(map), H, W, C, radius, &t);
  const std::vector<int32_t> idx = taps.idx.to_host_i32();
  for (int k = 0; k < 4; ++k) CHECK(idx[size_t(4 * (R - 6) + k)] / W == 0);
  for (int r : {R - 4, R - 3}) {
    bool first = false, last = false;
    for (int k = 0; k < 4; ++k)
      if (w[4 * r + k] > 0.01f) first |= idx[size_t(4 * r + k)] % W == 0, last |= idx[size_t(4 * r + k)] % W == W - 1;
    CHECK(first);
    CHECK(last);
  }
  for (int ch = 0; ch < C; ++ch) {
    const size_t a = size_t(R - 4) * C + ch, b = size_t(R - 3) * C + ch;
    CHECK(std::fabs((got[a] - value[a]) - (got[b] - value[b])) < 1e-3f);
  }
}

TEST_CASE("the background shell's gradients w.r.t. the opacity and the map match central differences") {
  const int H = 6, W = 10, C = 3;
  const float radius = 1.7f;
  const Rays rays = test_rays(21, 30);
  const int R = rays.count();
  const std::vector<float> map = testing::random_normal(size_t(H) * W * C, 5);
  const std::vector<float> g = testing::random_normal(size_t(R) * C, 6);
  const Tensor acc = Tensor::from_host(rays.acc, {R}), map_t = Tensor::from_host(map, {H * W, C});
  const render::ShellTaps taps =
      render::background_shell_taps(Tensor::from_host(rays.origins, {R, 3}), Tensor::from_host(rays.dirs, {R, 3}), radius, H, W);
  Tensor dacc = Tensor::full({R}, 0.25f), dmap = Tensor::full({H * W, C}, 0.5f);
  render::background_shell_backward(Tensor::from_host(g, {R, C}), acc, map_t, taps, &dacc, true, &dmap);

  const std::vector<double> gd = testing::to_double(g), zero(size_t(R) * C, 0.0);
  auto loss_of_acc = [&](const std::vector<double>& a) {
    return testing::dot(gd, reference_forward(rays, zero, a, testing::to_double(map), H, W, C, radius));
  };
  auto loss_of_map = [&](const std::vector<double>& m) {
    return testing::dot(gd, reference_forward(rays, zero, testing::to_double(rays.acc), m, H, W, C, radius));
  };
  std::vector<double> want_acc = testing::finite_difference(loss_of_acc, testing::to_double(rays.acc));
  for (double& x : want_acc) x += 0.25;  // accumulated onto what was there
  std::vector<double> want_map = testing::finite_difference(loss_of_map, testing::to_double(map));
  for (double& x : want_map) x += 0.5;
  check_close(dacc.to_host(), want_acc, 1e-4, 1e-5, "shell dacc");
  check_close(dmap.to_host(), want_map, 1e-4, 1e-5, "shell dmap");

  // Written rather than accumulated, and the map's gradient alone.
  Tensor dacc2;
  render::background_shell_backward(Tensor::from_host(g, {R, C}), acc, map_t, taps, &dacc2, true, nullptr);
  for (double& x : want_acc) x -= 0.25;
  check_close(dacc2.to_host(), want_acc, 1e-4, 1e-5, "shell dacc, written");
}

TEST_CASE("many rays on one texel sum into it, and no rays change nothing") {
  const int H = 4, W = 4, C = 2, R = 500;
  Rays rays;
  for (int r = 0; r < R; ++r) rays.add({0, 0, 0}, {0, 0, 1}, 0.0f);  // all at the north pole
  const render::ShellTaps taps =
      render::background_shell_taps(Tensor::from_host(rays.origins, {R, 3}), Tensor::from_host(rays.dirs, {R, 3}), 2.0f, H, W);
  Tensor dmap = Tensor::zeros({H * W, C});
  render::background_shell_backward(Tensor::full({R, C}, 1.0f), Tensor::from_host(rays.acc, {R}), Tensor::zeros({H * W, C}),
                                    taps, nullptr, false, &dmap);
  const std::vector<float> d = dmap.to_host();
  double total = 0;
  for (float x : d) total += x;
  CHECK(total == doctest::Approx(double(R) * C).epsilon(1e-5));
  for (int t = W; t < H * W; ++t) CHECK(d[size_t(t) * C] == 0.0f);  // only the top row

  const render::ShellTaps none = render::background_shell_taps(Tensor::zeros({0, 3}), Tensor::zeros({0, 3}), 2.0f, H, W);
  Tensor empty = Tensor::zeros({0, C});
  render::background_shell_forward(empty, Tensor::zeros({0}), Tensor::zeros({H * W, C}), none);
  CHECK(empty.numel() == 0);
}

TEST_CASE("the background shell refuses a bad radius, map size or ray shape by name") {
  const Tensor o = Tensor::zeros({2, 3}), d = Tensor::full({2, 3}, 1.0f);
  CHECK(testing::error_of([&] { render::background_shell_taps(o, d, 0.0f, 4, 8); }).find("radius") != std::string::npos);
  CHECK(testing::error_of([&] { render::background_shell_taps(o, d, 1.0f, 0, 8); }).find("texel") != std::string::npos);
  CHECK(testing::error_of([&] { render::background_shell_taps(Tensor::zeros({2, 2}), d, 1.0f, 4, 8); }).find("origins") !=
        std::string::npos);
  const render::ShellTaps taps = render::background_shell_taps(o, d, 1.0f, 4, 8);
  Tensor v = Tensor::zeros({3, 2});
  CHECK(testing::error_of([&] { render::background_shell_forward(v, Tensor::zeros({3}), Tensor::zeros({32, 2}), taps); })
            .find("taps") != std::string::npos);
}
