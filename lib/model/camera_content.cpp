// Inference over a whole camera, StyleModel's camera methods (declared in style_model.hpp): the content of
// every feature-map block (its centre ray, then n x n sub-rays or a quincunx where the map has edges), the
// opacity per pixel near silhouettes, and the stylised picture of that content under one style or two by a
// region. Training renders through render_content alone (style_model.cpp).
#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/model/block_refine.hpp"
#include "lib/model/content_of.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/model/opacity_head.hpp"
#include "lib/model/style_model.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::model {

using host::Error;

std::string supersample_name(int n) {
  if (n == kQuincunx) return "quincunx";
  return n == 1 ? "1" : std::to_string(n) + "x" + std::to_string(n);
}

int default_inference_supersample(int map_w, int map_h, bool ndc) {
  return ndc && std::max(map_w, map_h) >= kQuincunxMapSide ? kQuincunx : 3;
}

int parse_supersample(const std::string& text) {
  if (text == "quincunx" || text == "q") return kQuincunx;
  // "n" or supersample_name's "nxn", so that every name written (metrics, tables) reads back.
  const bool square = text.size() == 3 && text[1] == 'x' && text[2] == text[0];
  if ((text.size() == 1 || square) && text[0] >= '1' && text[0] - '0' <= kMaxSupersample) return text[0] - '0';
  throw Error("supersample '" + text + "': expected 1.." + std::to_string(kMaxSupersample) +
              " (n x n rays a block) or quincunx");
}

namespace {
constexpr int kEmbed = style::Sict::kEmbed;  // SICT's columns of a ray's content, the first ones

// A per-block map [h][w] at the image's pixels [cam_h][cam_w], bilinear between the block centres (block
// j's ray passes through pixel coordinate s (j + 0.5)), clamped at the edges.
std::vector<float> upsample_blocks(const std::vector<float>& v, int w, int h, int s, int cam_w, int cam_h) {
  auto at = [&](int x, int y) { return v[size_t(std::clamp(y, 0, h - 1)) * w + size_t(std::clamp(x, 0, w - 1))]; };
  std::vector<float> out(size_t(cam_w) * cam_h);
  for (int y = 0; y < cam_h; ++y)
    for (int x = 0; x < cam_w; ++x) {
      const float fx = (x + 0.5f) / float(s) - 0.5f, fy = (y + 0.5f) / float(s) - 0.5f;
      const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
      const float u = fx - x0, t = fy - y0;
      out[size_t(y) * cam_w + x] = (1 - u) * (1 - t) * at(x0, y0) + u * (1 - t) * at(x0 + 1, y0) +
                                   (1 - u) * t * at(x0, y0 + 1) + u * t * at(x0 + 1, y0 + 1);
    }
  return out;
}

// The rays `pick(r)` (r < R) of a set of rays, as the origins and directions of one renderer call.
template <class Pick>
void gather_rays(const scene::Rays& rays, int64_t R, Pick pick, std::vector<float>& o, std::vector<float>& d) {
  o.resize(size_t(3 * R));
  d.resize(size_t(3 * R));
  for (int64_t r = 0; r < R; ++r)
    for (int j = 0; j < 3; ++j) {
      o[size_t(3 * r + j)] = rays.origins[size_t(3 * pick(r) + j)];
      d[size_t(3 * r + j)] = rays.directions[size_t(3 * pick(r) + j)];
    }
}

// A renderer call's per-ray content on the host.
struct HostContent {
  std::vector<float> c, kept_acc, acc, depth;
  explicit HostContent(const StyleModel::Content& part)
      : c(part.c.to_host()), kept_acc(part.kept_acc.to_host()), acc(part.acc.to_host()), depth(part.depth.to_host()) {}
};

// Per block, sums over the rays that make it up (each weighted), divided by their weight at the end.
struct BlockSums {
  int width;  // columns of a ray's content (StyleModel::content_channels)
  std::vector<double> c, kept_acc, acc, depth;
  std::vector<float> acc_lo, acc_hi;  // over each block's sub-rays
  std::vector<double> inside;         // with a region: its composited indicator
  std::vector<double> rays_in;        // the weight of the rays summed per block

  BlockSums(int64_t n, int width, bool region)
      : width(width), c(size_t(n) * width, 0.0), kept_acc(size_t(n), 0.0), acc(size_t(n), 0.0), depth(size_t(n), 0.0),
        acc_lo(size_t(n), 1.0f), acc_hi(size_t(n), 0.0f), inside(region ? size_t(n) : 0, 0.0),
        rays_in(size_t(n), 1.0) {}
  // Content c_row [width] and kept opacity that stand for `weight` rays of block i.
  void add_content(size_t i, const float* c_row, double weight, float kept) {
    for (int e = 0; e < width; ++e) c[i * width + size_t(e)] += weight * c_row[e];
    kept_acc[i] += weight * kept;
  }
  // One ray's opacity, depth and (with a region) region indicator.
  void add_ray(size_t i, float a, float d, const std::vector<float>& in, size_t ray) {
    acc[i] += a;
    acc_lo[i] = std::min(acc_lo[i], a);
    acc_hi[i] = std::max(acc_hi[i], a);
    depth[i] += d;
    if (!inside.empty()) inside[i] += in[ray];
  }
  // Block i's sums so far weighted by f (the quincunx's centre ray counts 4).
  void scale(size_t i, double f) {
    for (int e = 0; e < width; ++e) c[i * width + size_t(e)] *= f;
    kept_acc[i] *= f;
    acc[i] *= f;
    depth[i] *= f;
    if (!inside.empty()) inside[i] *= f;
  }
  // Forgets block i's centre ray (even n: the centre is not one of the sub-rays).
  void clear(size_t i) {
    std::fill(c.begin() + int64_t(i) * width, c.begin() + int64_t(i + 1) * width, 0.0);
    kept_acc[i] = acc[i] = depth[i] = 0.0;
    acc_lo[i] = 1.0f;
    acc_hi[i] = 0.0f;
    if (!inside.empty()) inside[i] = 0.0;
  }
  std::vector<float> mean(const std::vector<double>& sum, int per_block) const {
    std::vector<float> m(sum.size());
    for (size_t i = 0; i < sum.size(); ++i) m[i] = float(sum[i] / rays_in[i / size_t(per_block)]);
    return m;
  }
};

// One render_camera_content: the centre rays of every block, then the refinement of the blocks at edges.
class CameraContentRender {
 public:
  CameraContentRender(const StyleModel& model, const scene::Scene& scene, const scene::Camera& cam, int chunk,
                      const RegionHead* region, int supersample, float merge_kept_per_ray,
                      const std::atomic<bool>* cancel)
      : model_(model), scene_(scene), cam_(cam), chunk_(chunk), region_(region), supersample_(supersample),
        merge_kept_per_ray_(merge_kept_per_ray), cancel_(cancel), geo_(model.inference_geometry()),
        centre_head_(model.features.field, const_cast<style::Sict&>(model.sict), false, model.content_skip),
        width_(model.content_channels()), w_(strided_camera(cam, model.stride()).width),
        h_(strided_camera(cam, model.stride()).height), n_(int64_t(w_) * h_), sums_(n_, width_, region != nullptr) {
    out_.width = w_;
    out_.height = h_;
  }

  // Every block's centre first. Then the blocks whose centre differs from a neighbour's (blocks_to_refine)
  // get the other sub-rays: elsewhere the n x n average equals the centre up to the map's curvature.
  StyleModel::CameraContent run(float refine_contrast) {
    add_rays(0.5f, 0.5f, {});
    if (supersample_ != 1) refine(refine_contrast);
    return finish();
  }

 private:
  struct Shaded {
    StyleModel::Content part;
    std::vector<float> inside;
  };

  bool quincunx() const { return supersample_ == kQuincunx; }

  // Between renderer calls: a viewer whose camera moved on stops the render here (RenderCancelled).
  void check_cancelled() const {
    if (cancel_ && cancel_->load(std::memory_order_relaxed)) throw RenderCancelled();
  }

  Tensor shade(const Tensor& comps) const {
    const Tensor c = model_.sict.forward_factored(comps, model_.features.field.basis.value, false, nullptr);
    return model_.content_skip ? nn::concat_columns(c, comps) : c;
  }

  // One renderer call on the R rays o, d ([R, 3] on the host), each ray its own: their content and, with a
  // region, their region indicator composited with the same weights (the same kept samples, no jitter).
  // Whether it shades per depth slab (render_ray_groups of one ray) is decided by the first call, whose
  // rays are shaded per sample; the later calls merge when that call kept >= merge_kept_per_ray samples a
  // ray. On soft geometry SICT on every kept sample is most of a centre ray's cost.
  Shaded shade_rays(const std::vector<float>& o, const std::vector<float>& d, int64_t R) {
    check_cancelled();
    const Tensor origins = Tensor::from_host(o, {R, 3}, "render origins");
    const Tensor dirs = Tensor::from_host(d, {R, 3}, "render directions");
    const ShadeFn shade_fn = [this](const Tensor& comps) { return shade(comps); };
    Shaded s;
    s.part = slab_rays_ ? content_of(render_ray_groups(geo_, model_.features.field.head, shade_fn, width_, origins,
                                                       dirs, 1, kMergeSteps))
                        : content_of(render_rays(geo_, centre_head_, origins, dirs, RayOptions{}, nullptr));
    if (first_call_) {
      first_call_ = false;
      slab_rays_ = double(s.part.kept) >= double(merge_kept_per_ray_) * double(R);
      out_.slab_shaded = slab_rays_;
    }
    out_.content.samples += s.part.samples;
    out_.content.kept += s.part.kept;
    if (region_) s.inside = render_rays(geo_, *region_, origins, dirs, RayOptions{}, nullptr).value.to_host();
    return s;
  }

  // Renders the blocks `which` (all when empty) at sub-position (fx, fy) of each block and adds into the sums.
  void add_rays(float fx, float fy, const std::vector<int64_t>& which) {
    int w = w_, h = h_;
    const scene::Rays rays = block_rays(scene_, cam_, model_.stride(), w, h, fx, fy);
    const int64_t count = which.empty() ? n_ : int64_t(which.size());
    for (int64_t b = 0; b < count; b += chunk_) {
      const int64_t R = std::min<int64_t>(chunk_, count - b);
      auto block = [&](int64_t r) { return which.empty() ? b + r : which[size_t(b + r)]; };
      std::vector<float> o, d;
      gather_rays(rays, R, block, o, d);
      const Shaded s = shade_rays(o, d, R);
      const HostContent p(s.part);
      for (int64_t r = 0; r < R; ++r) {
        const size_t i = size_t(block(r));
        sums_.add_content(i, &p.c[size_t(r * width_)], 1.0, p.kept_acc[size_t(r)]);
        sums_.add_ray(i, p.acc[size_t(r)], p.depth[size_t(r)], s.inside, size_t(r));
      }
    }
  }

  // The blocks to refine (blocks_to_refine on the centre rays' content), whether their sub-rays are shaded
  // merged, and the sub-rays themselves: n x n a block, one group a block, or the quincunx.
  void refine(float refine_contrast) {
    // Judged on SICT's columns alone (the components, where carried, would change which blocks pass).
    std::vector<float> c0(size_t(n_) * kEmbed);
    for (int64_t b = 0; b < n_; ++b)
      for (int e = 0; e < kEmbed; ++e) c0[size_t(b * kEmbed + e)] = float(sums_.c[size_t(b * width_ + e)]);
    const std::vector<float> a0(sums_.acc.begin(), sums_.acc.end());
    const std::vector<uint8_t> refine = blocks_to_refine(c0, kEmbed, a0, w_, h_, refine_contrast);
    std::vector<int64_t> which;
    for (int64_t b = 0; b < n_; ++b)
      if (refine[size_t(b)]) which.push_back(b);
    out_.refined = int64_t(which.size());
    // Shading merged per depth slab where SICT on every sub-ray sample is what costs (many kept samples a
    // ray: soft forward-facing geometry); on crisp surfaces the merge saves nothing (docs/results.md).
    const double kept_per_ray = double(out_.content.kept) / double(std::max<int64_t>(1, n_));
    out_.merged = !quincunx() && !which.empty() && kept_per_ray >= double(merge_kept_per_ray_);  // groups, not corners
    // For odd n the centre is the middle sub-ray and is kept (a merged block: the others form its group);
    // for even n it is not one of them and is replaced.
    const bool keep_centre = quincunx() || supersample_ % 2 == 1;
    if (!keep_centre)
      for (int64_t b : which) sums_.clear(size_t(b));
    if (quincunx()) {
      add_corners(which);
    } else if (out_.merged) {
      add_groups(which, keep_centre);
    } else if (!which.empty()) {
      for (int sy = 0; sy < supersample_; ++sy)
        for (int sx = 0; sx < supersample_; ++sx) {
          if (keep_centre && sx == supersample_ / 2 && sy == supersample_ / 2) continue;  // rendered above
          add_rays((sx + 0.5f) / float(supersample_), (sy + 0.5f) / float(supersample_), which);
        }
    }
    if (!quincunx())
      for (int64_t b : which) sums_.rays_in[size_t(b)] = double(supersample_) * supersample_;
  }

  // The blocks `which` as groups of their n x n sub-rays (render_ray_groups): the geometry per sub-ray, SICT
  // once per depth slab of the block on the weight-averaged field components of the sub-rays' samples there.
  // skip_centre: odd n, whose centre sub-ray the first pass rendered already (kept as it is).
  void add_groups(const std::vector<int64_t>& which, bool skip_centre) {
    std::vector<scene::Rays> sub;  // per sub-position, the rays of every block
    int w = w_, h = h_;
    for (int sy = 0; sy < supersample_; ++sy)
      for (int sx = 0; sx < supersample_; ++sx)
        if (!(skip_centre && sx == supersample_ / 2 && sy == supersample_ / 2))
          sub.push_back(block_rays(scene_, cam_, model_.stride(), w, h, (sx + 0.5f) / float(supersample_),
                                   (sy + 0.5f) / float(supersample_)));
    const int G = int(sub.size());
    const int64_t per_call = std::max<int64_t>(1, chunk_ / G);  // blocks a call
    const int64_t count = int64_t(which.size());
    for (int64_t b = 0; b < count; b += per_call) {
      const int64_t B = std::min<int64_t>(per_call, count - b);
      std::vector<float> o(size_t(3 * B * G)), d(size_t(3 * B * G));
      for (int64_t r = 0; r < B; ++r)
        for (int q = 0; q < G; ++q)
          for (int j = 0; j < 3; ++j) {
            const size_t from = size_t(3 * which[size_t(b + r)] + j), to = size_t(3 * (r * G + q) + j);
            o[to] = sub[size_t(q)].origins[from];
            d[to] = sub[size_t(q)].directions[from];
          }
      add_group_call(which, b, B, G, o, d);
    }
  }

  // One renderer call of B blocks (which[b..b+B)) of G sub-rays each, added into the sums.
  void add_group_call(const std::vector<int64_t>& which, int64_t b, int64_t B, int G, const std::vector<float>& o,
                      const std::vector<float>& d) {
    check_cancelled();
    const Tensor origins = Tensor::from_host(o, {B * G, 3}, "render origins");
    const Tensor dirs = Tensor::from_host(d, {B * G, 3}, "render directions");
    const ShadeFn shade_fn = [this](const Tensor& comps) { return shade(comps); };
    const GroupResult part =
        render_ray_groups(geo_, model_.features.field.head, shade_fn, width_, origins, dirs, G, kMergeSteps);
    const HostContent p(content_of(part));
    std::vector<float> in;
    if (region_) in = render_rays(geo_, *region_, origins, dirs, RayOptions{}, nullptr).value.to_host();
    for (int64_t r = 0; r < B; ++r) {
      const size_t i = size_t(which[size_t(b + r)]);
      // The group's value is already its G sub-rays' mean; the sums here are divided by n^2 at the end.
      sums_.add_content(i, &p.c[size_t(r * width_)], double(G), p.kept_acc[size_t(r)]);
      for (int q = 0; q < G; ++q) {
        const size_t ray = size_t(r * G + q);
        sums_.add_ray(i, p.acc[ray], p.depth[ray], in, ray);
      }
    }
    out_.content.samples += part.samples;
    out_.content.kept += part.kept;
  }

  // Quincunx: a refined block is its centre ray (weight 4) plus the rays through its four corners (weight 1
  // each), the corners shared with the neighbouring blocks: one ray more a block instead of n^2 - 1.
  void add_corners(const std::vector<int64_t>& which) {
    const int cw = w_ + 1;
    std::vector<int64_t> corner_id(size_t(cw) * (h_ + 1), -1), corners;  // corners: grid index k = y cw + x
    for (int64_t b : which)
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const size_t k = size_t(b / w_ + dy) * cw + size_t(b % w_ + dx);
          if (corner_id[k] < 0) {
            corner_id[k] = int64_t(corners.size());
            corners.push_back(int64_t(k));
          }
        }
    const CornerRays cr = render_corners(corners, cw);
    for (int64_t b : which) {
      const size_t i = size_t(b);
      sums_.scale(i, 4.0);
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const size_t q = size_t(corner_id[size_t(b / w_ + dy) * cw + size_t(b % w_ + dx)]);
          sums_.add_content(i, &cr.c[q * size_t(width_)], 1.0, cr.kept_acc[q]);
          sums_.add_ray(i, cr.acc[q], cr.depth[q], cr.inside, q);
        }
      sums_.rays_in[i] = 8.0;
    }
  }

  // The content of the rays through the corner points `corners` of the block grid (cw corners a row).
  struct CornerRays {
    std::vector<float> c, kept_acc, acc, depth, inside;
  };
  CornerRays render_corners(const std::vector<int64_t>& corners, int cw) {
    const int64_t K = int64_t(corners.size());
    const int s = model_.stride();
    CornerRays cr;
    for (int64_t b = 0; b < K; b += chunk_) {
      const int64_t R = std::min<int64_t>(chunk_, K - b);
      std::vector<float> o(size_t(3 * R)), d(size_t(3 * R));
      for (int64_t r = 0; r < R; ++r) {
        const int64_t k = corners[size_t(b + r)];
        scene::pixel_ray(cam_, float(s * (k % cw)), float(s * (k / cw)), &o[size_t(3 * r)], &d[size_t(3 * r)]);
        if (scene_.effects.ndc) scene::to_ndc(cam_, scene_.ndc_near, &o[size_t(3 * r)], &d[size_t(3 * r)]);
      }
      const Shaded sh = shade_rays(o, d, R);
      const HostContent p(sh.part);
      cr.c.insert(cr.c.end(), p.c.begin(), p.c.end());
      cr.kept_acc.insert(cr.kept_acc.end(), p.kept_acc.begin(), p.kept_acc.end());
      cr.acc.insert(cr.acc.end(), p.acc.begin(), p.acc.end());
      cr.depth.insert(cr.depth.end(), p.depth.begin(), p.depth.end());
      cr.inside.insert(cr.inside.end(), sh.inside.begin(), sh.inside.end());
    }
    return cr;
  }

  // The sums as means per block, the region mask, and the opacity per pixel near silhouettes.
  StyleModel::CameraContent finish() {
    if (region_) {
      out_.region_mask.assign(static_cast<size_t>(n_), 0.0f);
      for (int64_t r = 0; r < n_; ++r) {
        const double k = sums_.kept_acc[size_t(r)] / sums_.rays_in[size_t(r)];  // mean kept weight; 1e-6 as for one ray
        out_.region_mask[size_t(r)] =
            k > 1e-6 ? float(std::clamp(sums_.inside[size_t(r)] / sums_.kept_acc[size_t(r)], 0.0, 1.0)) : 0.0f;
      }
    }
    out_.content.c = Tensor::from_host(sums_.mean(sums_.c, width_), {n_, width_}, "camera content");
    out_.content.kept_acc = Tensor::from_host(sums_.mean(sums_.kept_acc, 1), {n_}, "camera kept opacity");
    out_.content.acc = Tensor::from_host(sums_.mean(sums_.acc, 1), {n_}, "camera opacity");
    out_.content.depth = Tensor::from_host(sums_.mean(sums_.depth, 1), {n_}, "camera depth");
    if (geo_.shell.on()) {
      // The shell is smooth over a block (a texel spans many), so each block reads it at its centre ray.
      int w = w_, h = h_;
      const scene::Rays rays = block_rays(scene_, cam_, model_.stride(), w, h);
      out_.content.background = model_.features.field.shell_term(
          geo_, Tensor::from_host(rays.origins, {n_, 3}, "block origins"),
          Tensor::from_host(rays.directions, {n_, 3}, "block directions"), out_.content.acc);
    }
    if (geo_.has_background && model_.stride() > 1)
      out_.pixel_acc = model_.pixel_opacity(scene_, cam_, w_, h_, sums_.acc_lo, sums_.acc_hi, std::max(chunk_, 8192));
    return std::move(out_);
  }

  const StyleModel& model_;
  const scene::Scene& scene_;
  const scene::Camera& cam_;
  const int chunk_;
  const RegionHead* region_;
  const int supersample_;
  const float merge_kept_per_ray_;
  const std::atomic<bool>* cancel_;
  const Geometry geo_;
  const SictHead centre_head_;
  const int width_;  // columns of a ray's content
  const int w_, h_;  // the map's size
  const int64_t n_;
  BlockSums sums_;
  StyleModel::CameraContent out_;
  bool first_call_ = true, slab_rays_ = false;
};
}  // namespace

StyleModel::CameraContent StyleModel::render_camera_content(const scene::Scene& scene, const scene::Camera& cam,
                                                            int chunk, const RegionHead* region, int supersample,
                                                            float refine_contrast, float merge_kept_per_ray,
                                                            const std::atomic<bool>* cancel) const {
  if (chunk < 1) throw Error("style model: chunk must be >= 1");
  if (!valid_supersample(supersample))
    throw Error("style model: supersample must be in 1.." + std::to_string(kMaxSupersample) + " or quincunx, got " +
                std::to_string(supersample));
  return CameraContentRender(*this, scene, cam, chunk, region, supersample, merge_kept_per_ray, cancel)
      .run(refine_contrast);
}

std::vector<float> StyleModel::pixel_opacity(const scene::Scene& scene, const scene::Camera& cam, int w, int h,
                                             const std::vector<float>& acc_lo, const std::vector<float>& acc_hi,
                                             int chunk) const {
  // A block whose sub-rays, and its 8 neighbours' sub-rays, all saw (almost) nothing or (almost) full
  // opacity lies away from any silhouette: its pixels take that value. Only the other blocks' pixels are
  // rendered, one ray each, in calls bounded as render_camera's (rays_per_call).
  constexpr float kSettled = 1e-3f;
  const int s = stride(), W = cam.width, H = cam.height;
  auto block = [&](int bx, int by) { return size_t(std::clamp(by, 0, h - 1)) * w + size_t(std::clamp(bx, 0, w - 1)); };
  std::vector<float> out(size_t(W) * H, 0.0f);
  std::vector<int64_t> todo;  // pixel indices to render
  for (int by = 0; by < h; ++by)
    for (int bx = 0; bx < w; ++bx) {
      bool empty = true, full = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const size_t k = block(bx + dx, by + dy);
          empty = empty && acc_hi[k] < kSettled;
          full = full && acc_lo[k] > 1.0f - kSettled;
        }
      for (int y = by * s; y < std::min(H, (by + 1) * s); ++y)
        for (int x = bx * s; x < std::min(W, (bx + 1) * s); ++x) {
          if (empty || full)
            out[size_t(y) * W + x] = full ? 1.0f : 0.0f;
          else
            todo.push_back(int64_t(y) * W + x);
        }
    }
  if (todo.empty()) return out;
  const scene::Rays rays = scene::camera_rays(scene, cam);
  const OpacityHead head;
  const Geometry geo = inference_geometry();  // as render_camera_content's
  const size_t step = size_t(rays_per_call(geo, chunk));
  for (size_t b = 0; b < todo.size(); b += step) {
    const size_t R = std::min(todo.size() - b, step);
    std::vector<float> o, d;
    gather_rays(rays, int64_t(R), [&](int64_t i) { return todo[b + size_t(i)]; }, o, d);
    const Tensor origins = Tensor::from_host(o, {int64_t(R), 3}, "pixel origins");
    const Tensor dirs = Tensor::from_host(d, {int64_t(R), 3}, "pixel directions");
    const auto a = render_rays(geo, head, origins, dirs, RayOptions{}, nullptr).acc.to_host();
    for (size_t i = 0; i < R; ++i) out[size_t(todo[b + i])] = a[i];
  }
  return out;
}

std::vector<float> StyleModel::crop_rgb(const Tensor& img, int cam_w, int cam_h) {
  const int H = int(img.dim(2)), W = int(img.dim(3));
  if (H < cam_h || W < cam_w)
    throw Error("style model: the decoder gave " + std::to_string(W) + "x" + std::to_string(H) + " pixels for a " +
                std::to_string(cam_w) + "x" + std::to_string(cam_h) + " view");
  const auto v = img.to_host();
  std::vector<float> rgb(size_t(3) * cam_w * cam_h);
  const size_t plane = size_t(H) * W;
  for (int y = 0; y < cam_h; ++y)
    for (int x = 0; x < cam_w; ++x)
      for (int ch = 0; ch < 3; ++ch) {
        const float p = v[ch * plane + size_t(y) * W + x];
        if (std::isnan(p)) throw Error("style model: the decoded image has NaN pixels");
        rgb[(size_t(y) * cam_w + x) * 3 + ch] = std::clamp(p, 0.0f, 1.0f);
      }
  return rgb;
}

std::vector<float> StyleModel::stylize_camera(const CameraContent& cc, const style::StyleCode& code, int cam_w,
                                              int cam_h) const {
  return crop_rgb(decode_styled(cc.content, code, cc.height, cc.width, nullptr), cam_w, cam_h);
}

std::vector<float> StyleModel::stylize_camera_regions(const CameraContent& cc, const style::StyleCode& inside,
                                                      const style::StyleCode& outside, int cam_w, int cam_h) const {
  const int64_t n = int64_t(cc.width) * cc.height;
  if (int64_t(cc.region_mask.size()) != n) throw Error("style model: this content was rendered without a region");
  if (map_decoder->renormalises_relu4()) {
    // This decoder re-normalises a whole map to one style's relu4_1 statistics, so two styles cannot share
    // a map: each is drawn over the whole view and the pictures are blended by the region mask, upsampled
    // from the blocks (a blend of pictures, not the paper's of DST outputs; the edge is a block soft).
    std::vector<float> rgb = stylize_camera(cc, inside, cam_w, cam_h);
    const std::vector<float> out = stylize_camera(cc, outside, cam_w, cam_h);
    const auto m = upsample_blocks(cc.region_mask, cc.width, cc.height, stride(), cam_w, cam_h);
    for (size_t i = 0; i < m.size(); ++i)
      for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = m[i] * rgb[i * 3 + c] + (1 - m[i]) * out[i * 3 + c];
    return rgb;
  }
  const auto c = cc.content.c.to_host(), k = cc.content.kept_acc.to_host();
  const int E = content_channels();
  std::vector<float> c_in(c.size()), c_out(c.size()), k_in(k.size()), k_out(k.size());
  for (int64_t r = 0; r < n; ++r) {
    const float m = cc.region_mask[size_t(r)];
    for (int e = 0; e < E; ++e) {
      c_in[size_t(r * E + e)] = m * c[size_t(r * E + e)];
      c_out[size_t(r * E + e)] = (1.0f - m) * c[size_t(r * E + e)];
    }
    k_in[size_t(r)] = m * k[size_t(r)];
    k_out[size_t(r)] = (1.0f - m) * k[size_t(r)];
  }
  Tensor y = stylised_rows(Tensor::from_host(c_in, {n, E}, "content inside"),
                           Tensor::from_host(k_in, {n}, "opacity inside"), inside);
  const Tensor y_out = stylised_rows(Tensor::from_host(c_out, {n, E}, "content outside"),
                                     Tensor::from_host(k_out, {n}, "opacity outside"), outside);
  nn::axpby(1.0f, y_out, 1.0f, y);
  return crop_rgb(decode_rows(std::move(y), cc.content.acc, cc.height, cc.width, nullptr, nullptr, cc.content.background),
                  cam_w, cam_h);
}

void StyleModel::over_background(std::vector<float>& rgb, const CameraContent& cc, int cam_w, int cam_h) const {
  if (!features.geo.has_background) return;
  if (rgb.size() != size_t(3) * cam_w * cam_h) throw Error("over_background: the image is not " + std::to_string(cam_w) + "x" + std::to_string(cam_h));
  const bool per_pixel = cc.pixel_acc.size() == size_t(cam_w) * cam_h;
  const std::vector<float> alpha =
      per_pixel ? cc.pixel_acc : upsample_blocks(cc.content.acc.to_host(), cc.width, cc.height, stride(), cam_w, cam_h);
  const auto& bg = features.geo.background;
  for (size_t i = 0; i < alpha.size(); ++i) {
    const float a = std::clamp(alpha[i], 0.0f, 1.0f);
    for (int c = 0; c < 3; ++c) rgb[i * 3 + c] = rgb[i * 3 + c] * a + bg[size_t(c)] * (1 - a);
  }
}

}  // namespace stylerf::model
