#include "lib/eval/path_consistency.hpp"

#include <chrono>

#include "host/error.hpp"
#include "lib/eval/path_frames.hpp"

namespace stylerf::eval {

PathSetup path_setup(const model::Geometry& g, const scene::Scene& scene, const PathOptions& p) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto cams = path_cameras(scene, p.frames, p.path_frames, p.size);
  PathSetup out = path_setup(render_path_geometry(g, scene, cams, p.chunk), g, scene, p);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

PathSetup path_setup(std::vector<FrameGeometry> frames, const model::Geometry& g, const scene::Scene& scene,
                     const PathOptions& p) {
  const auto t0 = std::chrono::steady_clock::now();
  PathSetup out;
  out.cams = path_cameras(scene, p.frames, p.path_frames, p.size);
  if (frames.size() != out.cams.size())
    throw host::Error("path_setup: " + std::to_string(frames.size()) + " rendered frames for a path of " +
                      std::to_string(out.cams.size()));
  ConsistencyOptions opt;
  opt.warp.depth_tolerance = p.depth_tolerance;
  // The geometry records whether the scene has a background: the scene here is loaded without its images,
  // so its own effects cannot tell (they come from the images' alpha).
  opt.warp.mask_background = g.has_background;
  const RaySpace space = RaySpace::of(scene);
  if (g.shell.on() && !space.ndc)
    for (auto& f : frames) add_shell_surface(f, g.shell.radius);
  out.warps = path_warps(frames, space, opt);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

std::unique_ptr<MaskedDistance> lpips_distance(const Lpips* lpips) {
  if (!lpips) return nullptr;
  return std::make_unique<MaskedDistance>(
      [lpips](const io::Image& a, const io::Image& b, const std::vector<float>& mask) { return lpips->distance(a, b, mask); });
}

}  // namespace stylerf::eval
