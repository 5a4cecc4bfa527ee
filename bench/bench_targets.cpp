// `stylerf bench targets`: see bench_targets.hpp. Maps are random [V, 50, 50, 256] (lego at 1/4: 100 views
// of 200x200; --quick: 8 views), rays uniform over every view's pixels. Bytes count what a kernel must
// move at least: the four taps it reads (each C values of the stored dtype), what it writes (floats), and
// its per-ray inputs.
#include "bench/bench_targets.hpp"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "bench/timing.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/features/feature_targets.hpp"
#include "lib/features/target_gather.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::bench {

using host::Tensor;

namespace {

struct Row {
  std::string name;
  double ms, gbs;
};

// Part 1: the read kernels over random maps stored as `dtype`.
void bench_reads(host::DType dtype, int V, int repeats, std::vector<Row>& rows) {
  const int hf = 50, wf = 50, C = features::kTargetChannels, R = 4096;
  const int P = 192;  // the largest multiple of 64 that fits a 200x200 view
  const double esize = double(host::dtype_size(dtype));
  std::mt19937_64 rng(1);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> ux(0.0f, 4.0f * wf), uy(0.0f, 4.0f * hf);
  std::uniform_int_distribution<int> uv(0, V - 1);
  std::vector<float> view_map(size_t(hf) * wf * C), xy(2 * size_t(R)), grad(size_t(R) * C);
  std::vector<int32_t> view(static_cast<size_t>(R));
  features::FeatureTargets t = features::allocate_targets(V, 4 * wf, 4 * hf, dtype);
  for (int v = 0; v < V; ++v) {
    for (float& x : view_map) x = normal(rng);
    features::put_view(t, v, features::encode_view(view_map, dtype));
  }
  for (float& x : grad) x = normal(rng);
  for (int r = 0; r < R; ++r) view[size_t(r)] = uv(rng), xy[2 * size_t(r)] = ux(rng), xy[2 * size_t(r) + 1] = uy(rng);
  const Tensor tv = Tensor::from_host(view, {R}, "bench view index"), txy = Tensor::from_host(xy, {R, 2});
  const std::string tag = std::string(" (") + host::dtype_name(dtype) + ")";
  auto add = [&](const std::string& name, const Timing& tm, double bytes) {
    rows.push_back({name + tag, tm.wall_ms, bytes / (tm.wall_ms * 1e6)});
    std::printf("%-34s %9.3f ms %8.2f GB/s\n", (name + tag).c_str(), tm.wall_ms, bytes / (tm.wall_ms * 1e6));
    std::fflush(stdout);
  };
  const double per_ray_in = 12.0;  // view index + pixel_xy
  add("gather fwd", best_of(repeats, [&] { features::gather_targets(t.maps, tv, txy); }),
      R * (per_ray_in + 4.0 * C * esize + C * 4.0));
  if (dtype == host::DType::F32) {
    const Tensor tg = Tensor::from_host(grad, {R, C});
    Tensor dmaps = Tensor::zeros({V, hf, wf, C}, "bench dmaps");
    // Read-modify-write of four taps per ray, plus the gradient row.
    add("gather bwd (atomic)", best_of(repeats, [&] { features::gather_targets_backward(tv, txy, tg, dmaps); }),
        R * (per_ray_in + 4.0 * C * 8 + C * 4.0));
  }
  for (int scale : {4, 1}) {
    // Each output pixel reads its four taps and writes C floats.
    const double pixels = double(P / scale) * (P / scale);
    add("patch " + std::to_string(P) + " scale " + std::to_string(scale),
        best_of(repeats, [&] { features::target_patch(t, V / 2, 4, 8, P, P, scale); }),
        pixels * (4.0 * C * esize + C * 4.0));
  }
}

// Part 2: what each way of holding lego's targets costs, at 1/4 and at its own 800x800.
nlohmann::json bench_storage(int repeats, bool quick) {
  nlohmann::json out = nlohmann::json::array();
  nn::VggEncoder vgg;
  try {
    vgg = nn::VggEncoder::load_default();
  } catch (const std::exception& e) {
    std::printf("\nstorage choices: not measured, the VGG weights are missing (%s)\n", e.what());
    return out;
  }
  const int V = 100, C = features::kTargetChannels, step_patch = 256;
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  auto image = [&](int side) {
    std::vector<float> rgb(size_t(side) * side * 3);
    for (float& x : rgb) x = u01(rng);
    return rgb;
  };
  // One step's own relu3_1: the patch plus a 16-pixel margin on each side, so its border matches the
  // full image's receptive field (relu3_1 sees 18 pixels around).
  const int per_patch_side = step_patch + 32;
  const std::vector<float> patch_img = image(per_patch_side);
  const Timing per_patch = best_of(repeats, [&] { features::compute_view_targets(vgg, patch_img, per_patch_side, per_patch_side); });
  std::printf("\nstorage choices for lego, %d views (one step reads a %dx%d patch's targets; per patch: VGG of %dx%d)\n",
              V, step_patch, step_patch, per_patch_side, per_patch_side);
  std::printf("%-10s %-14s %12s %14s %18s\n", "images", "storage", "maps GB", "per step ms", "once: s (VGG)");
  for (int side : quick ? std::vector<int>{200} : std::vector<int>{200, 800}) {
    const std::vector<float> img = image(side);
    const Timing one_view = best_of(1, [&] { features::compute_view_targets(vgg, img, side, side); });
    const double once_s = one_view.wall_ms * V / 1000.0;
    const int hf = features::target_map_size(side);
    const int ps = std::min(step_patch, side - side % 64);
    for (host::DType d : {host::DType::F32, host::DType::F16}) {
      features::FeatureTargets t = features::allocate_targets(1, side, side, d);
      features::put_view(t, 0, features::encode_view(std::vector<float>(size_t(hf) * hf * C, 1.0f), d));
      const Timing read = best_of(repeats, [&] { features::target_patch(t, 0, 0, 0, ps, ps, 4); });
      const double gb = double(V) * hf * hf * C * host::dtype_size(d) / 1e9;
      const std::string name = std::string("stored ") + host::dtype_name(d);
      std::printf("%4dx%-5d %-14s %12.2f %14.3f %18.1f\n", side, side, name.c_str(), gb, read.wall_ms, once_s);
      out.push_back({{"image", side}, {"storage", name}, {"maps_gb", gb}, {"step_ms", read.wall_ms}, {"once_s", once_s}});
    }
    std::printf("%4dx%-5d %-14s %12.2f %14.3f %18.1f\n", side, side, "per patch", 0.0, per_patch.wall_ms, 0.0);
    out.push_back({{"image", side}, {"storage", "per patch"}, {"maps_gb", 0.0}, {"step_ms", per_patch.wall_ms}, {"once_s", 0.0}});
  }
  return out;
}

}  // namespace

int bench_targets(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  const int repeats = opt.quick ? 1 : opt.repeats;
  const int V = opt.quick ? 8 : 100;
  std::cout << "device: " << rt.device().describe() << "\n"
            << "target reads: maps [" << V << ", 50, 50, " << features::kTargetChannels
            << "], 4096 rays, 192x192 patches, best of " << repeats << " after a warm-up\n";
  std::vector<Row> rows;
  for (host::DType d : {host::DType::F32, host::DType::F16}) bench_reads(d, V, repeats, rows);
  const nlohmann::json storage = bench_storage(repeats, opt.quick);

  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "targets"}, {"device", rt.device().describe()}, {"views", V},
                        {"map", {50, 50, features::kTargetChannels}}, {"rays", 4096}, {"repeats", repeats},
                        {"storage", storage}};
    for (const Row& r : rows) j["rows"].push_back({{"name", r.name}, {"ms", r.ms}, {"gb_s", r.gbs}});
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
