#include "lib/eval/path_consistency.hpp"

#include <chrono>

#include "lib/eval/path_frames.hpp"

namespace stylerf::eval {

PathSetup path_setup(const model::Geometry& g, const scene::Scene& scene, const PathOptions& p) {
  const auto t0 = std::chrono::steady_clock::now();
  PathSetup out;
  out.cams = path_cameras(scene, p.frames, p.path_frames, p.size);
  ConsistencyOptions opt;
  opt.warp.depth_tolerance = p.depth_tolerance;
  // The geometry records whether the scene has a background: the scene here is loaded without its images,
  // so its own effects cannot tell (they come from the images' alpha).
  opt.warp.mask_background = g.has_background;
  out.warps = path_warps(render_path_geometry(g, scene, out.cams, p.chunk), RaySpace::of(scene), opt);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::unique_ptr<MaskedDistance> lpips_distance(const Lpips* lpips) {
  if (!lpips) return nullptr;
  return std::make_unique<MaskedDistance>(
      [lpips](const io::Image& a, const io::Image& b, const std::vector<float>& mask) { return lpips->distance(a, b, mask); });
}

}  // namespace stylerf::eval
