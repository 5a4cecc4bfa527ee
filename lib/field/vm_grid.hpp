// A TensoRF vector-matrix (VM) grid on the device: 3 planes + 3 lines, one flat parameter tensor.
//
// Layout of `params` (kernels/grid.cl relies on it; so may an optimiser, which sees one tensor):
//   [plane0][plane1][plane2][line0][line1][line2]
//   mode m = 0, 1, 2: plane axes (u, v) = (x,y), (x,z), (y,z); line axis w = z, y, x (TensoRF's order);
//   plane m is [n_v][n_u][R_m], line m is [n_w][R_m] — the rank innermost, so one bilinear tap reads R
//   contiguous floats (vectorised over the rank inside a work-item).
// Points are normalised to [-1,1]^3 by the scene box; sampling is grid_sample(align_corners=True)
// (-1 -> index 0, +1 -> index n-1); points outside [-1,1]^3 get zero density / features and no gradient.
//
// Density: sigma = act(sum_m sum_r plane_m[r] * line_m[r]); act relu, or softplus(x - 10) (TensoRF's shift).
// Appearance features: concat_m(plane_m[r] * line_m[r]), sum(R_m) values per point.
#pragma once
#include <array>
#include <cstdint>
#include <string>

#include "host/device.hpp"
#include "host/tensor.hpp"

namespace stylerf::field {

using host::Tensor;

enum class DensityActivation { Relu = 0, Softplus = 1 };
DensityActivation parse_density_activation(const std::string& s);  // "relu" | "softplus"

// How backward scatters into the grid gradient.
// Private: one gradient copy per compute unit, each over a fixed chunk of points in order, summed in a
//   fixed order — deterministic for a given device, best on CPUs (few compute units, large caches).
// Fixed: one work-item per (point, component), 64-bit fixed-point integer atomics
//   (kernels/grid_fixed.cl) — deterministic bit for bit on any device and chunking, for devices with many
//   compute units; needs cl_khr_int64_base_atomics.
// Auto: Private on CPU devices, Fixed elsewhere where the device has 64-bit atomics, else Private.
// (A third mode, one work-item per point with compare-and-swap float adds, lost on both kinds of device
// and was retired: docs/experiments.md.)
enum class ScatterMode { Auto, Private, Fixed };
ScatterMode parse_scatter_mode(const std::string& s);  // "auto" | "private" | "fixed"
// The mode Auto resolves to on a device; the mode a call with `mode` runs on the current device (Fixed on
// a device without 64-bit atomics throws).
ScatterMode auto_scatter_mode(const host::DeviceInfo& dev);
ScatterMode resolved_scatter_mode(ScatterMode mode);
const char* scatter_mode_name(ScatterMode mode);

struct VMGrid {
  std::array<int, 3> res{};   // grid points along x, y, z (each >= 2)
  std::array<int, 3> rank{};  // components per mode (plane/line pair)
  Tensor params;              // flat, layout above

  // Random init N(0, scale^2), seeded (TensoRF initialises its factors with 0.1 * randn).
  static VMGrid create(std::array<int, 3> res, std::array<int, 3> rank, float scale, uint64_t seed);
  // Wraps existing parameters (shape checked).
  static VMGrid from_params(std::array<int, 3> res, std::array<int, 3> rank, Tensor params);

  int features() const { return rank[0] + rank[1] + rank[2]; }
  int64_t numel() const { return numel_of(res, rank); }
  static int64_t numel_of(std::array<int, 3> res, std::array<int, 3> rank);
  // Element offsets of plane m and line m in params.
  int64_t plane_offset(int m) const;
  int64_t line_offset(int m) const;
};

// ---- sampling ------------------------------------------------------------------------------------------
// pts [N,3] normalised -> sigma [N].
Tensor density_forward(const VMGrid& g, const Tensor& pts, DensityActivation act);
// The build options of kernels/grid.cl for a grid of these ranks (-DRANKn: constant rank loops); also
// used by programs that include grid.cl (the early-termination march).
std::string rank_build_options(const std::array<int, 3>& rank);
// dgrid += d(sum dsigma * sigma)/d(params), from the forward output sigma (activation derivative is a function
// of sigma). dgrid has params' shape; zero it before the first backward of a step.
void density_backward(const VMGrid& g, const Tensor& pts, const Tensor& sigma, const Tensor& dsigma, Tensor& dgrid,
                      DensityActivation act, ScatterMode mode = ScatterMode::Auto);

// pts [N,3] -> features [N, features()].
Tensor features_forward(const VMGrid& g, const Tensor& pts);
// dgrid += d(sum dfeat * feat)/d(params).
void features_backward(const VMGrid& g, const Tensor& pts, const Tensor& dfeat, Tensor& dgrid,
                       ScatterMode mode = ScatterMode::Auto);

// ---- regularisers ------------------------------------------------------------------------------------
// TV over the planes: sum_m [mean over (v,u,r) of (P[v+1,u,r]-P[v,u,r])^2 + mean of (P[v,u+1,r]-P[v,u,r])^2]
// (no factor 2; the trainer's weight absorbs it). Forward returns the value (host sums in double).
double tv_forward(const VMGrid& g);
void tv_backward(const VMGrid& g, float weight, Tensor& dgrid);  // dgrid += weight * dTV/dparams
// L1: sum over the 3 planes and 3 lines of mean |x| (TensoRF's density L1). sign(0) = 0 in backward.
double l1_forward(const VMGrid& g);
void l1_backward(const VMGrid& g, float weight, Tensor& dgrid);

// ---- resampling ------------------------------------------------------------------------------------------
// The grid resampled (bilinear planes, linear lines, align_corners=True) to new_res, over the sub-box
// [lo, hi] of the old normalised coordinates (default: the whole box, i.e. plain upsampling; a sub-box
// is TensoRF's shrink to the occupied region — the caller shrinks its world box to match).
VMGrid resample(const VMGrid& g, std::array<int, 3> new_res, std::array<float, 3> lo = {-1.f, -1.f, -1.f},
                std::array<float, 3> hi = {1.f, 1.f, 1.f});

// TensoRF's grid size for a voxel budget: n_voxels^(1/3) per unit of the box's geometric mean side,
// i.e. res_a = round(size_a / cbrt(size_x size_y size_z / n_voxels)), at least 2.
std::array<int, 3> grid_res_for_voxels(std::array<float, 3> box_size, int64_t n_voxels);

}  // namespace stylerf::field
