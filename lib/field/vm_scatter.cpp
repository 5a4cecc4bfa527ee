#include "lib/field/vm_scatter.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"

namespace stylerf::field {

using host::Error;
using host::launch;
using host::launch_with_local;

ScatterMode parse_scatter_mode(const std::string& s) {
  if (s == "auto") return ScatterMode::Auto;
  if (s == "private") return ScatterMode::Private;
  if (s == "fixed") return ScatterMode::Fixed;
  throw Error("unknown grid scatter mode '" + s + "' (auto, private, fixed)");
}

const char* scatter_mode_name(ScatterMode mode) {
  switch (mode) {
    case ScatterMode::Auto: return "auto";
    case ScatterMode::Private: return "private";
    case ScatterMode::Fixed: return "fixed";
  }
  return "?";
}

// The fixed-point scatter needs 64-bit integer atomics and work-groups of 256 (its bound's reduction).
static bool can_run_fixed(const host::DeviceInfo& dev) {
  return dev.has_extension("cl_khr_int64_base_atomics") && dev.max_work_group >= 256;
}

ScatterMode auto_scatter_mode(const host::DeviceInfo& dev) {
  // Measured (bench field, app features backward): on the 2-core PoCL CPU private 275 ms, fixed 7992 ms;
  // on an H100 private 180 ms, fixed 4.8 ms (docs/results.md).
  if (dev.type & CL_DEVICE_TYPE_CPU) return ScatterMode::Private;
  return can_run_fixed(dev) ? ScatterMode::Fixed : ScatterMode::Private;
}

ScatterMode resolved_scatter_mode(ScatterMode mode) {
  const auto& dev = host::Runtime::instance().device();
  if (mode == ScatterMode::Fixed && !can_run_fixed(dev))
    throw Error("grid scatter 'fixed' needs cl_khr_int64_base_atomics and work-groups of 256; " + dev.name +
                " does not offer both");
  if (mode != ScatterMode::Auto) return mode;
  // STYLERF_GRID_SCATTER overrides Auto (benches compare the modes on one device through whole steps).
  static const ScatterMode from_env = [] {
    const char* env = std::getenv("STYLERF_GRID_SCATTER");
    return env && *env ? parse_scatter_mode(env) : ScatterMode::Auto;
  }();
  if (from_env != ScatterMode::Auto) return resolved_scatter_mode(from_env);
  return auto_scatter_mode(dev);
}

// Scratch kept between calls (the queue is in order, so reuse after the previous call's last kernel is
// safe): the privatised scatter's extra gradient copies; the fixed-point accumulator (2 floats = one int64
// per element, left zeroed by each call) and its bounds and state.
static Tensor& scratch_of(Tensor& t, int64_t floats, const char* what) {
  if (!t.defined() || t.numel() < floats) t = Tensor({std::max<int64_t>(floats, 1)}, what);
  return t;
}

static void scatter_private(const VMGrid& g, const Tensor& pts, const Tensor& dsrc, const Tensor& sigma, Tensor& dgrid,
                            int n, int kind, DensityActivation act) {
  const auto& dev = host::Runtime::instance().device();
  // One copy per compute unit, but no copy for fewer than ~4096 points each (zeroing would dominate).
  const int copies = std::max(1, std::min<int>(static_cast<int>(dev.compute_units), (n + 4095) / 4096));
  const int chunk = (n + copies - 1) / copies;
  static Tensor copies_scratch;
  Tensor& scratch = scratch_of(copies_scratch, int64_t(copies - 1) * g.numel(), "grid gradient copies");
  launch_with_local("grid", "vm_scatter_private", rank_build_options(g.rank), {size_t(copies)}, {1}, pts, g.params,
                    dsrc, sigma, dgrid, scratch, n, chunk, g.res[0], g.res[1], g.res[2], g.rank[0], g.rank[1],
                    g.rank[2], kind, int(act));
  if (copies > 1) launch("grid", "vm_reduce_copies", {size_t(g.numel())}, scratch, dgrid, int(g.numel()), copies - 1);
}

// Max-|x| partials of x into partials[0, parts): at most kBoundParts chunks, one work-group of
// kBoundLanes each (BOUND_WG in kernels/grid_fixed.cl), each chunk at least 8 floats a lane.
constexpr int kBoundParts = 4096, kBoundLanes = 256;
static int bound_partials(const std::string& opts, const Tensor& x, Tensor& partials) {
  const int64_t n = x.numel();
  const int parts = static_cast<int>(std::clamp<int64_t>(n / (8 * kBoundLanes), 1, kBoundParts));
  const int64_t chunk = (n + parts - 1) / parts;
  launch_with_local("grid+grid_fixed", "vm_fixed_bound_partials", opts, {size_t(parts) * kBoundLanes},
                    {size_t(kBoundLanes)}, x, partials, n, chunk);
  return parts;
}

static void scatter_fixed(const VMGrid& g, const Tensor& pts, const Tensor& dsrc, const Tensor& sigma, Tensor& dgrid,
                          int n, int kind, DensityActivation act) {
  // Every kernel of the program is launched with the grid's rank options: one build per grid.
  const std::string opts = rank_build_options(g.rank);
  const int numel = static_cast<int>(g.numel());
  const auto run = [&](const char* kernel, size_t global, auto&&... args) {
    launch_with_local("grid+grid_fixed", kernel, opts, {global}, host::Range(0), args...);
  };
  static Tensor acc, gpart_store, ppart_store, state_store;
  if (!acc.defined() || acc.numel() < 2 * g.numel()) {
    acc = Tensor({2 * g.numel()}, "grid gradient, fixed point");
    run("vm_fixed_zero", size_t(numel), acc, numel);
  }
  Tensor& gpart = scratch_of(gpart_store, kBoundParts, "scatter bound partials");
  Tensor& ppart = scratch_of(ppart_store, kBoundParts, "scatter bound partials");
  Tensor& state = scratch_of(state_store, 2, "scatter scale");
  const int ng = bound_partials(opts, dsrc, gpart), np = bound_partials(opts, g.params, ppart);
  run("vm_fixed_scale", 1, gpart, ng, ppart, np, n, state);
  const size_t work = size_t(n) * size_t(g.features());
  launch_with_local("grid+grid_fixed", "vm_scatter_fixed", opts, {work}, {kPointGroup}, pts, g.params, dsrc, sigma,
                    acc, state, n, g.res[0], g.res[1], g.res[2], g.rank[0], g.rank[1], g.rank[2], kind, int(act));
  run("vm_fixed_finish", size_t(numel), acc, dgrid, state, numel);
}

void scatter_into_grid(const VMGrid& g, const Tensor& pts, const Tensor& dsrc, const Tensor& sigma, Tensor& dgrid,
                       int kind, DensityActivation act, ScatterMode mode) {
  const int n = static_cast<int>(pts.dim(0));
  if (dgrid.numel() != g.numel())
    throw Error("grid backward: gradient has " + std::to_string(dgrid.numel()) + " values, grid has " +
                std::to_string(g.numel()));
  if (n == 0) return;
  switch (resolved_scatter_mode(mode)) {
    case ScatterMode::Fixed:
      scatter_fixed(g, pts, dsrc, sigma, dgrid, n, kind, act);
      return;
    default:
      scatter_private(g, pts, dsrc, sigma, dgrid, n, kind, act);
  }
}

}  // namespace stylerf::field
