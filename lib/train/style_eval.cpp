#include "lib/train/style_eval.hpp"

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <ostream>

#include "host/dist.hpp"
#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/model/scene_style_stats.hpp"
#include "lib/nn/layout.hpp"
#include "lib/train/style_trainer.hpp"

namespace stylerf::train {

using host::Error;
using host::Tensor;

Tensor planar_crop(const std::vector<float>& rgb, int W, int He, int We) {
  std::vector<float> v(size_t(3) * He * We);
  for (int c = 0; c < 3; ++c)
    for (int y = 0; y < He; ++y)
      for (int x = 0; x < We; ++x) v[(size_t(c) * He + y) * We + x] = rgb[(size_t(y) * W + x) * 3 + c];
  return Tensor::from_host(v, {1, 3, He, We}, "evaluation image");
}

std::vector<float> content_opacity_pixels(const model::StyleModel::CameraContent& cc, int stride, int He, int We) {
  const auto acc = cc.content.acc.to_host();
  std::vector<float> full(size_t(He) * We);
  for (int y = 0; y < He; ++y)
    for (int x = 0; x < We; ++x) full[size_t(y) * We + x] = acc[size_t(y / stride) * cc.width + x / stride];
  return full;
}

OpacityMask content_opacity_mask(const model::StyleModel::CameraContent& cc, int stride, int He, int We) {
  return opacity_mask(content_opacity_pixels(cc, stride, He, We), He, We, He, We);
}

namespace {

// A planar [1, 3, H, W] tensor as an image, clamped to [0, 1] (what a PNG of it would hold).
io::Image clamped_image(const Tensor& t) {
  io::Image im;
  im.height = int(t.shape()[2]);
  im.width = int(t.shape()[3]);
  im.data = t.to_host();
  for (float& x : im.data) x = std::clamp(x, 0.0f, 1.0f);
  return im;
}

}  // namespace

namespace {

// The picture with its values clamped to [0, 1], in place (as it would be shown).
Tensor clamped(Tensor t) {
  auto v = t.to_host();
  for (float& x : v) x = std::clamp(x, 0.0f, 1.0f);
  t.upload(v);
  return t;
}

// Pictures of one size [1, 3, H, W] side by side in one PNG (truth | ours | AdaIN), clamped to [0, 1].
void save_sheet(const std::string& path, const std::vector<Tensor>& parts) {
  const int He = int(parts.front().shape()[2]), We = int(parts.front().shape()[3]), n = int(parts.size());
  io::Image sheet;
  sheet.width = n * We;
  sheet.height = He;
  sheet.data.assign(size_t(3) * sheet.width * He, 0.0f);
  for (int k = 0; k < n; ++k) {
    const auto p = parts[size_t(k)].to_host();
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < He; ++y)
        for (int x = 0; x < We; ++x)
          sheet.at(c, y, k * We + x) = std::clamp(p[(size_t(c) * He + y) * We + x], 0.0f, 1.0f);
  }
  io::save_png(path, sheet);
}

// The style module on a true view's relu3_1 map [1, 256, h, w], as the 2D warm start trains it (SICT with the
// map's own statistics, full opacity): RGB [1, 3, 4h, 4w], clamped to [0, 1].
Tensor stylise_vgg_map(const model::StyleModel& m, const Tensor& relu31, const style::StyleCode& code) {
  const int h = int(relu31.shape()[2]), w = int(relu31.shape()[3]);
  style::Sict::Context sc;
  const Tensor x = nn::image_to_rows(relu31);
  const Tensor c = m.sict.forward(x, true, &sc);
  const Tensor acc = Tensor::full({int64_t(h) * w}, 1.0f, "full opacity");
  Tensor y = m.transform_features(c, x, acc, sc.mean, sc.var, code, nullptr);
  m.blend_at_strength(y, x);  // as stylize shows a frame
  return clamped(m.decode_map(nn::rows_to_image(y, h, w), &code, nullptr));
}

}  // namespace

std::vector<StyleEvalRow> evaluate_styles(const model::StyleModel& m, nn::VggEncoder& vgg, style::AdainModel& adain,
                                          const scene::Scene& scene, const std::vector<std::string>& styles,
                                          const StyleEvalOptions& opt) {
  const int n = int(scene.test.size());
  if (n == 0) throw Error("evaluate styles: the scene has no test views");
  const int count = (opt.views <= 0 || opt.views >= n) ? n : opt.views;
  const bool masked = m.features.geo.has_background;
  const StyleLossWeights w;
  std::vector<StyleEvalRow> rows(styles.size());
  std::vector<StyleTargets> style_targets_of;  // each style's loss targets, measured once for all views
  std::vector<style::StyleCode> codes;
  std::vector<Tensor> style_imgs;
  const model::SceneStyleStats scene_stats(m, scene, model::SceneStyleStats::kDefaultViews, opt.supersample,
                                          opt.refine_contrast);
  for (const auto& s : styles) {
    style_imgs.push_back(load_style_image(s, 256, 256, nullptr));
    const nn::VggFeatures taps = vgg.forward(style_imgs.back(), 4, false);
    style_targets_of.push_back(style_targets(taps));
    codes.push_back(m.style_code(taps, nullptr));
    scene_stats.attach(codes.back());
  }
  for (int vi = 0; vi < count; ++vi) {
    const scene::View& v = scene.test[size_t(int64_t(vi) * n / count)];
    if (v.rgb.empty()) throw Error("evaluate styles: test view " + v.image_path + " has no image loaded");
    const int W = v.camera.width, H = v.camera.height, We = W / 8 * 8, He = H / 8 * 8;
    const auto cc = m.render_camera_content(scene, v.camera, 4096, nullptr, opt.supersample, opt.refine_contrast);
    const Tensor truth = planar_crop(v.rgb, W, He, We);
    const nn::VggFeatures ft = vgg.forward(truth, 4, false);
    OpacityMask mask;
    if (masked) {
      mask = content_opacity_mask(cc, m.stride(), He, We);  // each pixel's block, cut like the images
      if (mask.empty()) continue;
    }
    // The structure score compares what a person sees: the true view and each stylised picture as shown.
    const bool score_structure = opt.lpips && std::min(He, We) >= opt.lpips->min_side();
    const std::vector<float> pixel_mask =
        score_structure && masked ? content_opacity_pixels(cc, m.stride(), He, We) : std::vector<float>{};
    const io::Image truth_image = score_structure ? clamped_image(truth) : io::Image{};
    auto structure = [&](const Tensor& stylised) {
      const io::Image s = clamped_image(stylised);
      return masked ? opt.lpips->distance(truth_image, s, pixel_mask) : opt.lpips->distance(truth_image, s);
    };
    for (size_t si = 0; si < styles.size(); ++si) {
      host::Dist::world().alive();  // under MPI the other ranks may be waiting for this share of styles
      const auto ours_rgb = m.stylize_camera(cc, codes[si], W, H);
      const Tensor ours = planar_crop(ours_rgb, W, He, We);
      const Tensor ad = clamped(style::adain_stylize(adain, truth, style_imgs[si], 1.0f));
      const StyleLossValues lo = style_losses(vgg.forward(ours, 4, false), ft[3], style_targets_of[si], masked ? &mask : nullptr, w, nullptr);
      const StyleLossValues la = style_losses(vgg.forward(ad, 4, false), ft[3], style_targets_of[si], masked ? &mask : nullptr, w, nullptr);
      StyleEvalRow& r = rows[si];
      r.style = std::filesystem::path(styles[si]).stem().string();
      r.ours_content += lo.content / count;
      r.ours_style += lo.style / count;
      r.adain_content += la.content / count;
      r.adain_style += la.style / count;
      for (size_t t = 0; t < r.ours_style_tap.size(); ++t) {
        r.ours_style_tap[t] += lo.style_tap[t] / count;
        r.adain_style_tap[t] += la.style_tap[t] / count;
      }
      if (opt.vgg_map_row) {
        const Tensor on_map = stylise_vgg_map(m, ft[2], codes[si]);
        const StyleLossValues lm =
            style_losses(vgg.forward(on_map, 4, false), ft[3], style_targets_of[si], masked ? &mask : nullptr, w, nullptr);
        r.vgg_map_content += lm.content / count;
        r.vgg_map_style += lm.style / count;
        if (score_structure) r.vgg_map_lpips += structure(on_map);
      }
      // The pictures show ours as stylize does, over the scene's background (the losses above are masked
      // by opacity instead, so what the decoder draws in empty space never counts).
      std::vector<float> shown_rgb = ours_rgb;
      m.over_background(shown_rgb, cc, W, H);
      const Tensor shown = planar_crop(shown_rgb, W, He, We);
      if (score_structure) {
        r.ours_lpips += structure(shown);
        r.adain_lpips += structure(ad);
        ++r.structure_views;
      }
      if (!opt.image_dir.empty() && vi == 0) save_sheet(opt.image_dir + "/" + r.style + ".png", {truth, shown, ad});
    }
    if (opt.log)
      *opt.log << "  view " << vi + 1 << "/" << count << " done (" << styles.size() << " styles)" << std::endl;
  }
  for (StyleEvalRow& r : rows)
    if (r.structure_views > 0)
      r.ours_lpips /= r.structure_views, r.adain_lpips /= r.structure_views, r.vgg_map_lpips /= r.structure_views;
  return rows;
}

}  // namespace stylerf::train
