#include "lib/field/vm_grid.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"
#include "lib/field/vm_scatter.hpp"

namespace stylerf::field {

using host::Error;
using host::launch;
using host::launch_with_local;
using host::Range;

DensityActivation parse_density_activation(const std::string& s) {
  if (s == "relu") return DensityActivation::Relu;
  if (s == "softplus") return DensityActivation::Softplus;
  throw Error("unknown density activation '" + s + "' (relu, softplus)");
}

int64_t VMGrid::numel_of(std::array<int, 3> res, std::array<int, 3> rank) {
  const int64_t x = res[0], y = res[1], z = res[2];
  return y * x * rank[0] + z * x * rank[1] + z * y * rank[2] + z * rank[0] + y * rank[1] + x * rank[2];
}

int64_t VMGrid::plane_offset(int m) const {
  const int64_t x = res[0], y = res[1], z = res[2];
  const int64_t p[3] = {y * x * rank[0], z * x * rank[1], z * y * rank[2]};
  int64_t off = 0;
  for (int i = 0; i < m; ++i) off += p[i];
  return off;
}

int64_t VMGrid::line_offset(int m) const {
  const int64_t l[3] = {int64_t(res[2]) * rank[0], int64_t(res[1]) * rank[1], int64_t(res[0]) * rank[2]};
  int64_t off = plane_offset(3);
  for (int i = 0; i < m; ++i) off += l[i];
  return off;
}

static void check_layout(std::array<int, 3> res, std::array<int, 3> rank) {
  for (int a = 0; a < 3; ++a) {
    if (res[a] < 2) throw Error("VM grid: resolution " + std::to_string(res[a]) + " along axis " + std::to_string(a) +
                                " (need at least 2 points per axis)");
    if (rank[a] < 1) throw Error("VM grid: rank " + std::to_string(rank[a]) + " for mode " + std::to_string(a));
  }
  if (VMGrid::numel_of(res, rank) >= (int64_t(1) << 31)) throw Error("VM grid: more than 2^31 parameters");
}

VMGrid VMGrid::create(std::array<int, 3> res, std::array<int, 3> rank, float scale, uint64_t seed) {
  check_layout(res, rank);
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> nd(0.0f, scale);
  std::vector<float> v(static_cast<size_t>(numel_of(res, rank)));
  for (auto& x : v) x = nd(rng);
  VMGrid g;
  g.res = res;
  g.rank = rank;
  g.params = Tensor::from_host(v, {static_cast<int64_t>(v.size())}, "VM grid parameters");
  return g;
}

VMGrid VMGrid::from_params(std::array<int, 3> res, std::array<int, 3> rank, Tensor params) {
  check_layout(res, rank);
  if (params.numel() != numel_of(res, rank))
    throw Error("VM grid: parameter tensor has " + std::to_string(params.numel()) + " values, layout needs " +
                std::to_string(numel_of(res, rank)));
  VMGrid g;
  g.res = res;
  g.rank = rank;
  g.params = params;
  return g;
}

// Build options that fix the ranks at compile time (see kernels/grid.cl, vm_layout).
std::string rank_build_options(const std::array<int, 3>& rank) {
  return "-DRANK0=" + std::to_string(rank[0]) + " -DRANK1=" + std::to_string(rank[1]) +
         " -DRANK2=" + std::to_string(rank[2]);
}

template <class... Args>
static void grid_launch(const std::array<int, 3>& rank, const char* kernel, size_t global, const Args&... args) {
  launch_with_local("grid", kernel, rank_build_options(rank), {global}, {kPointGroup}, args...);
}

static void check_points(const Tensor& pts, const char* op) {
  if (pts.ndim() != 2 || pts.dim(1) != 3)
    throw Error(std::string(op) + ": points have shape " + host::shape_str(pts.shape()) + ", expected [N, 3]");
}

Tensor density_forward(const VMGrid& g, const Tensor& pts, DensityActivation act) {
  check_points(pts, "density_forward");
  const int n = static_cast<int>(pts.dim(0));
  Tensor sigma({n}, "density");
  grid_launch(g.rank, "vm_density_forward", size_t(n), pts, g.params, sigma, n, g.res[0], g.res[1], g.res[2], g.rank[0],
         g.rank[1], g.rank[2], int(act));
  return sigma;
}

Tensor features_forward(const VMGrid& g, const Tensor& pts) {
  check_points(pts, "features_forward");
  const int n = static_cast<int>(pts.dim(0));
  Tensor feat({n, g.features()}, "grid features");
  grid_launch(g.rank, "vm_features_forward", size_t(n), pts, g.params, feat, n, g.res[0], g.res[1], g.res[2], g.rank[0],
         g.rank[1], g.rank[2]);
  return feat;
}

void density_backward(const VMGrid& g, const Tensor& pts, const Tensor& sigma, const Tensor& dsigma, Tensor& dgrid,
                      DensityActivation act, ScatterMode mode) {
  check_points(pts, "density_backward");
  host::expect_shape(sigma, {pts.dim(0)}, "density_backward", "sigma");
  host::expect_shape(dsigma, {pts.dim(0)}, "density_backward", "dsigma");
  scatter_into_grid(g, pts, dsigma, sigma, dgrid, 0, act, mode);
}

void features_backward(const VMGrid& g, const Tensor& pts, const Tensor& dfeat, Tensor& dgrid, ScatterMode mode) {
  check_points(pts, "features_backward");
  host::expect_shape(dfeat, {pts.dim(0), g.features()}, "features_backward", "dfeat");
  scatter_into_grid(g, pts, dfeat, dfeat, dgrid, 1, DensityActivation::Relu, mode);
}

// ---- regularisers ------------------------------------------------------------------------------------
static double host_sum(const Tensor& t) {
  double s = 0.0;
  for (float v : t.to_host()) s += v;
  return s;
}

double tv_forward(const VMGrid& g) {
  const int rows = g.res[1] + g.res[2] + g.res[2];  // n_v of the three planes: y, z, z
  Tensor partial({rows}, "TV partial sums");
  launch("grid", "vm_tv_forward", {size_t(rows)}, g.params, partial, rows, g.res[0], g.res[1], g.res[2], g.rank[0],
         g.rank[1], g.rank[2]);
  return host_sum(partial);
}

void tv_backward(const VMGrid& g, float weight, Tensor& dgrid) {
  if (dgrid.numel() != g.numel())
    throw Error("tv_backward: gradient has " + std::to_string(dgrid.numel()) + " values, grid has " +
                std::to_string(g.numel()));
  static const int kU[3] = {0, 0, 1}, kV[3] = {1, 2, 2};  // plane axes of each mode (grid.cl: mode_u, mode_v)
  for (int m = 0; m < 3; ++m) {
    const int nu = g.res[kU[m]], nv = g.res[kV[m]], R = g.rank[m];
    if (R == 0) continue;
    const float cu = 2.0f / float(R * nv * (nu - 1)), cv = 2.0f / float(R * (nv - 1) * nu);
    // Rows of 64 elements along u: group (64, 1), global rounded up (the kernel guards its index).
    const size_t gx = (size_t(nu) * R + 63) / 64 * 64;
    host::launch_with_local("grid", "vm_tv_backward", "", {gx, size_t(nv)}, {64, 1}, g.params, dgrid, weight,
                            int(g.plane_offset(m)), nu, nv, R, cu, cv);
  }
}

double l1_forward(const VMGrid& g) {
  const int block = 4096;
  const int blocks = static_cast<int>((g.numel() + block - 1) / block);
  Tensor partial({blocks}, "L1 partial sums");
  launch("grid", "vm_l1_forward", {size_t(blocks)}, g.params, partial, blocks, block, g.res[0], g.res[1], g.res[2],
         g.rank[0], g.rank[1], g.rank[2]);
  return host_sum(partial);
}

void l1_backward(const VMGrid& g, float weight, Tensor& dgrid) {
  launch("grid", "vm_l1_backward", {size_t(g.numel())}, g.params, dgrid, weight, g.res[0], g.res[1], g.res[2],
         g.rank[0], g.rank[1], g.rank[2]);
}

// ---- resampling ------------------------------------------------------------------------------------------
VMGrid resample(const VMGrid& g, std::array<int, 3> new_res, std::array<float, 3> lo, std::array<float, 3> hi) {
  check_layout(new_res, g.rank);
  VMGrid out;
  out.res = new_res;
  out.rank = g.rank;
  out.params = Tensor({VMGrid::numel_of(new_res, g.rank)}, "VM grid parameters");
  const int64_t x = new_res[0], y = new_res[1], z = new_res[2];
  const int64_t cells = y * x + z * x + z * y + z + y + x;
  launch("grid", "vm_resample", {size_t(cells)}, g.params, out.params, int(cells), g.res[0], g.res[1], g.res[2],
         new_res[0], new_res[1], new_res[2], g.rank[0], g.rank[1], g.rank[2], lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  return out;
}

std::array<int, 3> grid_res_for_voxels(std::array<float, 3> box_size, int64_t n_voxels) {
  const double vol = double(box_size[0]) * box_size[1] * box_size[2];
  const double voxel = std::cbrt(vol / double(n_voxels));
  std::array<int, 3> r{};
  for (int a = 0; a < 3; ++a) r[a] = std::max(2, static_cast<int>(std::lround(box_size[a] / voxel)));
  return r;
}

}  // namespace stylerf::field
