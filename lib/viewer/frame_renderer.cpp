#include "lib/viewer/frame_renderer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "host/error.hpp"
#include "lib/model/region.hpp"
#include "lib/scene/camera_path.hpp"
#include "lib/scene/poses.hpp"

namespace stylerf::viewer {

namespace {

using Clock = std::chrono::steady_clock;

std::string number_key(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// (1 - t) a + t b of two defined tensors of one shape, on the host (statistics of [1, 512]).
host::Tensor lerp(const host::Tensor& a, const host::Tensor& b, double t) {
  const auto va = a.to_host(), vb = b.to_host();
  std::vector<float> out(va.size());
  for (size_t i = 0; i < va.size(); ++i) out[i] = float((1 - t) * va[i] + t * vb[i]);
  return host::Tensor::from_host(out, a.shape(), "interpolated scene statistics");
}

template <class T>
void remember(std::list<std::pair<std::string, T>>& cache, const std::string& key, const T& value, size_t keep) {
  cache.emplace_front(key, value);
  while (cache.size() > keep) cache.pop_back();
}

}  // namespace

RegionPlacement RegionPlacement::of(const scene::Scene& scene) {
  std::array<double, 3> c{}, half{};
  if (scene::view_kind(scene) == scene::ViewKind::Forward && !scene.train.empty()) {
    // The box of a forward-facing scene is in NDC: place the region in the world, where the views look.
    std::vector<scene::Pose> poses;
    for (const auto& v : scene.train) poses.push_back(scene::pose_of(v.camera));
    const scene::Pose avg = scene::average_pose(poses);
    const double focal = scene::path_focus_depth(scene);
    const scene::Vec3 t = scene::sub(avg.axis(3), scene::scale(avg.axis(2), focal));
    c = {t[0], t[1], t[2]};
    half = {0.3 * focal, 0.3 * focal, 0.3 * focal};
  } else {
    for (int k = 0; k < 3; ++k) {
      c[size_t(k)] = 0.5 * (double(scene.aabb[0][k]) + scene.aabb[1][k]);
      half[size_t(k)] = 0.25 * (double(scene.aabb[1][k]) - scene.aabb[0][k]);
    }
  }
  RegionPlacement p;
  for (int k = 0; k < 3; ++k) {
    p.box[size_t(k)] = c[size_t(k)] - half[size_t(k)];
    p.box[size_t(k) + 3] = c[size_t(k)] + half[size_t(k)];
    p.sphere[size_t(k)] = c[size_t(k)];
  }
  p.sphere[3] = std::min({half[0], half[1], half[2]});
  return p;
}

std::string RegionPlacement::spec(const std::string& shape, double scale) const {
  std::string s;
  auto add = [&](double v) { s += (s.back() == ':' ? "" : ",") + number_key(v); };
  if (shape == "sphere") {
    s = "sphere:";
    for (int k = 0; k < 3; ++k) add(sphere[size_t(k)]);
    add(sphere[3] * scale);
  } else if (shape == "box") {
    s = "box:";
    for (int side = 0; side < 2; ++side)
      for (int k = 0; k < 3; ++k) {
        const double c = 0.5 * (box[size_t(k)] + box[size_t(k) + 3]), h = 0.5 * (box[size_t(k) + 3] - box[size_t(k)]);
        add(c + (side == 0 ? -h : h) * scale);
      }
  } else {
    throw host::Error("region shape must be box or sphere, got '" + shape + "'");
  }
  return s;
}

FrameRenderer::FrameRenderer(const model::StyleModel& m, const scene::Scene& scene, StyleLibrary& styles,
                             style::StyleEncoder& encoder, const model::SceneStyleStats& scene_stats,
                             FrameRendererOptions options)
    : m_(m), scene_(scene), styles_(styles), encoder_(encoder), scene_stats_(scene_stats), opt_(options),
      placement_(RegionPlacement::of(scene)) {
  if (opt_.supersample == 0) opt_.supersample = m.inference_supersample;
  if (scene.train.empty()) throw host::Error("viewer: scene " + scene.name + " has no training views");
}

int FrameRenderer::full_side() const {
  const auto& c = scene_.train.front().camera;
  return std::max(c.width, c.height);
}

const model::StyleModel::CameraContent& FrameRenderer::content(const FrameRequest& r, const scene::Camera& cam,
                                                               bool preview, const std::atomic<bool>* cancel,
                                                               bool& cached) {
  const std::string region = r.region_shape.empty() ? "" : placement_.spec(r.region_shape, r.region_scale);
  const std::string key = std::to_string(r.camera.view) + " " + number_key(r.camera.yaw) + " " +
                          number_key(r.camera.pitch) + " " + number_key(r.camera.zoom) + " " +
                          std::to_string(cam.width) + "x" + std::to_string(cam.height) + " " +
                          (preview ? "preview " : "full ") + region;
  for (auto it = contents_.begin(); it != contents_.end(); ++it)
    if (it->key == key) {
      contents_.splice(contents_.begin(), contents_, it);
      cached = true;
      return contents_.front().content;
    }
  cached = false;
  std::unique_ptr<model::RegionHead> head;
  if (!region.empty())
    head = std::make_unique<model::RegionHead>(model::Region::parse(region, {cam}),
                                               model::RegionSpace::of(m_.features.geo, scene_));
  // Previews take one ray a block: a fraction of the refined content's cost, and gone a moment later.
  const int supersample = preview ? 1 : opt_.supersample;
  auto cc = m_.render_camera_content(scene_, cam, opt_.chunk, head.get(), supersample, opt_.refine_contrast,
                                     model::kMergeKeptPerRay, cancel);
  contents_.push_front({key, std::move(cc)});
  while (contents_.size() > size_t(std::max(1, opt_.cached_contents))) contents_.pop_back();
  return contents_.front().content;
}

style::StyleCode FrameRenderer::code_of(const std::string& id, bool pooled_only) {
  for (const auto& [key, code] : codes_)
    if (key == id) return code;
  style::StyleCode c = styles_.code(id, encoder_);
  if (pooled_only) return c;
  scene_stats_.attach(c);
  remember(codes_, id, c, 16);
  return c;
}

style::StyleCode FrameRenderer::mixed(const FrameRequest& r, bool preview) {
  if (r.style_b.empty() || r.mix <= 0) return code_of(r.style, preview);
  if (r.mix >= 1) return code_of(r.style_b, preview);
  const style::StyleCode a = code_of(r.style, preview), b = code_of(r.style_b, preview);
  style::StyleCode m = style::mix_codes({a, b}, {float(1 - r.mix), float(r.mix)}, "mix");
  if (preview) {
    // Pooling a mix's scene statistics renders the scene's statistic views again (seconds): a preview takes
    // its styles' statistics interpolated instead; the full frame pools them as stylize does.
    if (a.scene_mean.defined() && b.scene_mean.defined()) {
      m.scene_mean = lerp(a.scene_mean, b.scene_mean, r.mix);
      m.scene_std = lerp(a.scene_std, b.scene_std, r.mix);
      if (a.scene_lo.defined() && b.scene_lo.defined()) {
        m.scene_lo = lerp(a.scene_lo, b.scene_lo, r.mix);
        m.scene_hi = lerp(a.scene_hi, b.scene_hi, r.mix);
      }
    }
    return m;
  }
  const std::string key = r.style + "+" + r.style_b + "@" + number_key(r.mix);
  for (const auto& [k, code] : codes_)
    if (k == key) return code;
  scene_stats_.attach(m);
  remember(codes_, key, m, 16);
  return m;
}

Frame FrameRenderer::render(const FrameRequest& r, const std::atomic<bool>* cancel) {
  const auto t0 = Clock::now();
  if (!r.region_shape.empty() && r.style_b.empty())
    throw host::Error("a region needs a second style (style_b) to put inside it");
  const scene::Camera cam = scene::offset_camera(scene_, r.camera, r.side);
  Frame f;
  f.preview = r.side < full_side();
  const auto& cc = content(r, cam, f.preview, cancel, f.content_cached);
  std::vector<float> rgb;
  if (!r.region_shape.empty()) {
    rgb = m_.stylize_camera_regions(cc, code_of(r.style_b, f.preview), code_of(r.style, f.preview), cam.width,
                                    cam.height);
  } else {
    rgb = m_.stylize_camera(cc, mixed(r, f.preview), cam.width, cam.height);
  }
  if (!opt_.decoded_background) m_.over_background(rgb, cc, cam.width, cam.height);
  f.image = io::from_interleaved(rgb, cam.width, cam.height);
  f.render_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return f;
}

}  // namespace stylerf::viewer
