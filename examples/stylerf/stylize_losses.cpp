#include "host/dist.hpp"
#include "examples/stylerf/stylize_losses.hpp"

#include <algorithm>
#include <iomanip>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/image.hpp"
#include "lib/style/style_encoder.hpp"
#include "lib/style/style_image.hpp"
#include "lib/train/style_eval.hpp"

namespace stylerf::cli {

using host::Tensor;

namespace {
std::vector<float> interleave(const io::Image& img) {
  std::vector<float> v(size_t(3) * img.width * img.height);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c) v[(size_t(y) * img.width + x) * 3 + c] = img.at(c, y, x);
  return v;
}
}  // namespace

ViewLosses::ViewLosses(const model::StyleModel& m, nn::VggEncoder& vgg, bool adain_baseline) : m_(m), vgg_(vgg) {
  if (adain_baseline) adain_ = std::make_unique<style::AdainModel>(style::AdainModel::load_default());
}

void ViewLosses::add_style(const std::string& path) {
  Style s;
  s.path = path;
  if (!path.empty()) {
    s.image = style::load_style_image(path, style::kStyleImageSize, style::kStyleImageSize, nullptr);
    s.targets = train::style_targets(vgg_.forward(s.image, 4, false));
  }
  styles_.push_back(std::move(s));
  sums_.emplace_back();
}

void ViewLosses::begin_view(const scene::Scene& scene, const scene::View* truth, const scene::Camera& cam,
                            const model::StyleModel::CameraContent& cc) {
  const int W = cam.width, H = cam.height;
  We_ = W / 8 * 8;
  He_ = H / 8 * 8;
  skip_ = We_ < 8 || He_ < 8;
  if (skip_) return;
  std::vector<float> ref;
  if (truth) {
    if (truth->rgb.empty()) throw host::Error("stylize: test view " + truth->image_path + " has no image loaded");
    io::Image img;
    img.width = truth->camera.width;
    img.height = truth->camera.height;
    img.data.resize(size_t(3) * img.width * img.height);
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        for (int c = 0; c < 3; ++c) img.at(c, y, x) = truth->rgb[(size_t(y) * img.width + x) * 3 + c];
    ref = interleave(io::resize(img, W, H));
  } else {
    ref = m_.features.render_decoded(scene, cam).rgb;
  }
  truth_ = train::planar_crop(ref, W, He_, We_);
  content41_ = vgg_.forward(truth_, 4, false)[3];
  masked_ = m_.features.geo.has_background;
  if (masked_) {
    mask_ = train::content_opacity_mask(cc, m_.stride(), He_, We_);
    skip_ = mask_.empty();
  }
}

nlohmann::json ViewLosses::measure(const std::vector<float>& rgb, int cam_w, size_t set) {
  if (skip_) return {{"skipped", "nothing visible to compare"}};
  const Style& s = styles_.at(set);
  Sums& sum = sums_[set];
  const train::StyleLossWeights w;
  const train::OpacityMask* mask = masked_ ? &mask_ : nullptr;
  const Tensor ours = train::planar_crop(rgb, cam_w, He_, We_);
  nlohmann::json j;
  const auto ours_taps = vgg_.forward(ours, 4, false);
  if (s.path.empty()) {
    // No single style: the content loss alone (style_losses needs style taps: compare with the content's).
    const auto lo = train::style_losses(ours_taps, content41_, ours_taps, mask, w, nullptr);
    j["content"] = lo.content;
    sum.ours_content += lo.content;
    ++sum.views;
    return j;
  }
  const auto lo = train::style_losses(ours_taps, content41_, s.targets, mask, w, nullptr);
  j["content"] = lo.content;
  j["style"] = lo.style;
  sum.ours_content += lo.content;
  sum.ours_style += lo.style;
  ++sum.views;
  if (adain_) {
    Tensor ad = style::adain_stylize(*adain_, truth_, s.image, 1.0f);
    auto a = ad.to_host();
    for (float& x : a) x = std::clamp(x, 0.0f, 1.0f);
    ad.upload(a);
    const auto la = train::style_losses(vgg_.forward(ad, 4, false), content41_, s.targets, mask, w, nullptr);
    j["adain_content"] = la.content;
    j["adain_style"] = la.style;
    sum.adain_content += la.content;
    sum.adain_style += la.style;
    ++sum.adain_views;
  }
  return j;
}

void ViewLosses::merge_ranks() {
  std::vector<double> v;
  for (const Sums& s : sums_) v.insert(v.end(), {s.ours_content, s.ours_style, s.adain_content, s.adain_style,
                                                 double(s.views), double(s.adain_views)});
  host::Dist::world().allreduce_sum(v);
  for (size_t i = 0; i < sums_.size(); ++i) {
    const double* p = &v[6 * i];
    sums_[i] = {p[0], p[1], p[2], p[3], int(p[4]), int(p[5])};
  }
}

nlohmann::json ViewLosses::means() const {
  nlohmann::json out = nlohmann::json::object();
  for (size_t i = 0; i < styles_.size(); ++i) {
    const Sums& s = sums_[i];
    if (s.views == 0) continue;
    nlohmann::json j = {{"views", s.views}, {"content", s.ours_content / s.views}};
    if (!styles_[i].path.empty()) j["style"] = s.ours_style / s.views;
    if (s.adain_views > 0) {
      j["adain_content"] = s.adain_content / s.adain_views;
      j["adain_style"] = s.adain_style / s.adain_views;
      j["style_ratio_ours_over_adain"] = (s.ours_style / s.views) / std::max(1e-12, s.adain_style / s.adain_views);
    }
    out[styles_[i].path.empty() ? "set_" + std::to_string(i) : styles_[i].path] = j;
  }
  return out;
}

std::string ViewLosses::summary() const {
  std::ostringstream o;
  o << std::fixed << std::setprecision(3);
  const nlohmann::json all = means();
  for (const auto& [name, j] : all.items()) {
    o << "  " << name << ": content " << j["content"].get<double>();
    if (j.contains("style")) o << ", style " << j["style"].get<double>();
    if (j.contains("adain_style"))
      o << "; AdaIN content " << j["adain_content"].get<double>() << ", style " << j["adain_style"].get<double>();
    o << "\n";
  }
  return o.str();
}

}  // namespace stylerf::cli
