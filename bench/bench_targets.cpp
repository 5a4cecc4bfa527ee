// `stylerf bench targets`: see bench_targets.hpp. Maps are random [V, 50, 50, 256] (lego at 1/4: 100 views
// of 200x200; --quick: 8 views), rays uniform over every view's pixels. Bytes count what a kernel must
// move at least: the four taps it reads (each C floats), what it writes, and its per-ray inputs.
#include "bench/bench_targets.hpp"

#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "bench/timing.hpp"
#include "host/files.hpp"
#include "host/runtime.hpp"
#include "lib/features/target_gather.hpp"

namespace stylerf::bench {

using host::Tensor;

int bench_targets(const BenchOptions& opt) {
  auto& rt = host::Runtime::instance();
  const int repeats = opt.quick ? 1 : opt.repeats;
  const int V = opt.quick ? 8 : 100, hf = 50, wf = 50, C = features::kTargetChannels, R = 4096;
  const int P = 192;  // the largest multiple of 64 that fits a 200x200 view
  std::cout << "device: " << rt.device().describe() << "\n"
            << "target reads: maps [" << V << ", " << hf << ", " << wf << ", " << C << "], " << R << " rays, " << P
            << "x" << P << " patches, best of " << repeats << " after a warm-up\n";

  std::mt19937_64 rng(1);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::uniform_real_distribution<float> ux(0.0f, 4.0f * wf), uy(0.0f, 4.0f * hf);
  std::uniform_int_distribution<int> uv(0, V - 1);
  std::vector<float> maps(size_t(V) * hf * wf * C), xy(2 * size_t(R)), grad(size_t(R) * C);
  std::vector<int32_t> view(static_cast<size_t>(R));
  for (float& x : maps) x = normal(rng);
  for (float& x : grad) x = normal(rng);
  for (int r = 0; r < R; ++r) view[size_t(r)] = uv(rng), xy[2 * size_t(r)] = ux(rng), xy[2 * size_t(r) + 1] = uy(rng);
  features::FeatureTargets t;
  t.maps = Tensor::from_host(maps, {V, hf, wf, C}, "bench target maps");
  t.image_width = 4 * wf;
  t.image_height = 4 * hf;
  const Tensor tv = Tensor::from_host(view, {R}, "bench view index"), txy = Tensor::from_host(xy, {R, 2});
  const Tensor tg = Tensor::from_host(grad, {R, C});
  Tensor dmaps = Tensor::zeros({V, hf, wf, C}, "bench dmaps");

  struct Row {
    std::string name;
    double ms, gbs;
  };
  std::vector<Row> rows;
  auto add = [&](const std::string& name, const Timing& tm, double bytes) {
    rows.push_back({name, tm.wall_ms, bytes / (tm.wall_ms * 1e6)});
    std::printf("%-28s %9.3f ms %8.2f GB/s\n", name.c_str(), tm.wall_ms, bytes / (tm.wall_ms * 1e6));
    std::fflush(stdout);
  };
  const double per_ray_in = 12.0;  // view index + pixel_xy
  add("gather fwd", best_of(repeats, [&] { features::gather_targets(t.maps, tv, txy); }),
      R * (per_ray_in + 4.0 * C * 4 + C * 4.0));
  // Read-modify-write of four taps per ray, plus the gradient row.
  add("gather bwd (atomic)", best_of(repeats, [&] { features::gather_targets_backward(tv, txy, tg, dmaps); }),
      R * (per_ray_in + 4.0 * C * 8 + C * 4.0));
  for (int scale : {4, 1}) {
    // Each output pixel reads its four taps and writes C floats.
    const double pixels = double(P / scale) * (P / scale);
    add("patch " + std::to_string(P) + " scale " + std::to_string(scale),
        best_of(repeats, [&] { features::target_patch(t, V / 2, 4, 8, P, P, scale); }), pixels * (4.0 * C * 4 + C * 4.0));
  }

  if (!opt.json_path.empty()) {
    nlohmann::json j = {{"bench", "targets"}, {"device", rt.device().describe()}, {"views", V}, {"map", {hf, wf, C}},
                        {"rays", R}, {"repeats", repeats}};
    for (const Row& r : rows) j["rows"].push_back({{"name", r.name}, {"ms", r.ms}, {"gb_s", r.gbs}});
    host::write_file_atomic(opt.json_path, j.dump(2) + "\n");
    std::cout << "wrote " << opt.json_path << "\n";
  }
  return 0;
}

}  // namespace stylerf::bench
