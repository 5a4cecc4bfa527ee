#include "lib/train/style_trainer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "host/error.hpp"
#include "lib/io/json_fields.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/features/target_cache.hpp"
#include "lib/features/target_gather.hpp"
#include "lib/io/image.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"
#include "lib/train/data_parallel.hpp"
#include "lib/train/training_loop.hpp"
#include "lib/train/stage_programs.hpp"
#include "lib/train/trainer_state.hpp"
#include "lib/train/reconstruction_loss.hpp"
#include "lib/style/style_encoder.hpp"

namespace stylerf::train {

using host::Error;
using host::Tensor;
using nlohmann::json;

// ---- config and style sets --------------------------------------------------------------------------------
#define STYLE_TRAIN_FIELDS                                                                                   \
  dst_bias, iters, patch, style_size, style_crop, lr_stylizer, lr_decoder, beta1, beta2, lr_decay_ratio, \
      warm_start, warm_share, decoder_warm, running_init_patches, inference_supersample, decoder_phases, seed, styles_per_step, \
      content_skip

json StyleTrainConfig::to_json() const {
  json j{{"sict", style::sict_mode_name(sict)},
         {"content_weight", weights.content},
         {"style_weight", weights.style},
         {"warm_maps", warm_maps_name(warm_maps)},
         {"style_decoder", model::style_decoder_name(style_decoder)}};
  STYLERF_JSON_PUT_FIELDS(j, *this, STYLE_TRAIN_FIELDS);
  return j;
}

StyleTrainConfig StyleTrainConfig::from_json(const json& j) {
  StyleTrainConfig c;
  // Absent from checkpoints written before these options existed: their value then.
  json defaults = {{"decoder_warm", 0}, {"inference_supersample", 1}, {"decoder_phases", false}, {"warm_share", 1.0},
                  {"styles_per_step", 1}, {"content_skip", false}};
  defaults.update(j);
  c.sict = style::parse_sict_mode(j.at("sict").get<std::string>());
  c.weights.content = j.at("content_weight").get<float>();
  c.weights.style = j.at("style_weight").get<float>();
  c.warm_maps = parse_warm_maps(j.value("warm_maps", std::string("vgg")));
  c.style_decoder = model::parse_style_decoder(j.value("style_decoder", std::string("stage2")));
  STYLERF_JSON_GET_FIELDS(defaults, c, STYLE_TRAIN_FIELDS);
  return c;
}

void StyleTrainConfig::validate() const {
  using host::SettingError;
  auto positive = [](const char* field, float v) {
    if (!(v > 0) || !std::isfinite(v)) throw SettingError(field, "must be a positive number, got " + std::to_string(v));
  };
  if (iters < 1) throw SettingError("iters", "must be >= 1, got " + std::to_string(iters));
  if (patch < 8 || patch % 8) throw SettingError("patch", "must be a positive multiple of 8, got " + std::to_string(patch));
  if (style_crop < 8 || style_crop % 8)
    throw SettingError("style_crop", "must be a positive multiple of 8, got " + std::to_string(style_crop));
  if (style_size < style_crop || style_size > 4096)
    throw SettingError("style_size", "must be in [" + std::to_string(style_crop) + ", 4096] (the crop is " +
                                         std::to_string(style_crop) + "), got " + std::to_string(style_size));
  positive("lr_stylizer", lr_stylizer);
  positive("lr_decoder", lr_decoder);
  positive("content_weight", weights.content);
  positive("style_weight", weights.style);
  if (!(lr_decay_ratio > 0 && lr_decay_ratio <= 1))
    throw SettingError("lr_decay_ratio", "must be in (0, 1], got " + std::to_string(lr_decay_ratio));
  if (warm_start < 0) throw SettingError("warm_start", "must be >= 0, got " + std::to_string(warm_start));
  if (!(warm_share > 0 && warm_share <= 1))
    throw SettingError("warm_share", "must be in (0, 1], got " + std::to_string(warm_share));
  if (styles_per_step < 1 || styles_per_step > 1024)
    throw SettingError("styles_per_step", "must be in [1, 1024], got " + std::to_string(styles_per_step));
  if (decoder_warm < 0) throw SettingError("decoder_warm", "must be >= 0, got " + std::to_string(decoder_warm));
  if (running_init_patches < 0)
    throw SettingError("running_init_patches", "must be >= 0, got " + std::to_string(running_init_patches));
  if (!model::valid_supersample(inference_supersample) && inference_supersample != model::kSupersampleByScene)
    throw SettingError("inference_supersample", "must be in 1.." + std::to_string(model::kMaxSupersample) +
                                                    ", model::kQuincunx or model::kSupersampleByScene, got " +
                                                    std::to_string(inference_supersample));
  if (decoder_phases && !model::map_decoder_for(style_decoder).has_vgg_pool())
    throw SettingError("decoder_phases", std::string("needs a vgg-adain decoder (the phases are those of its VGG "
                                                     "pool), not ") + model::style_decoder_name(style_decoder));
}

StyleSet StyleSet::from_dir(const std::string& dir, int holdout, std::ostream* log) {
  std::vector<std::string> all = style::style_images_in(dir, log);
  if (holdout < 0) throw host::SettingError("holdout_styles", "must be >= 0, got " + std::to_string(holdout));
  if (int(all.size()) < holdout + 1)
    throw Error("style folder " + dir + " has " + std::to_string(all.size()) + " images (.jpg/.png); " +
                std::to_string(holdout) + " held out leaves none to train on");
  StyleSet s;
  std::vector<bool> held(all.size(), false);
  for (int i = 0; i < holdout; ++i) held[size_t((2 * int64_t(i) + 1) * int64_t(all.size()) / (2 * holdout))] = true;
  for (size_t i = 0; i < all.size(); ++i) (held[i] ? s.holdout : s.train).push_back(all[i]);
  return s;
}

json StyleSet::to_json() const { return {{"train", train}, {"holdout", holdout}}; }

StyleSet StyleSet::from_json(const json& j) {
  StyleSet s;
  s.train = j.at("train").get<std::vector<std::string>>();
  s.holdout = j.at("holdout").get<std::vector<std::string>>();
  return s;
}

namespace {
std::string stem(const std::string& p) { return std::filesystem::path(p).stem().string(); }

// rows [R, C] each times its own factor. On the host: the warm start's maps are a few thousand rows.
Tensor scale_rows(const Tensor& rows, const std::vector<float>& factor) {
  const int64_t R = rows.dim(0), C = rows.dim(1);
  auto v = rows.to_host();
  for (int64_t r = 0; r < R; ++r)
    for (int64_t c = 0; c < C; ++c) v[size_t(r * C + c)] *= factor[size_t(r)];
  return Tensor::from_host(v, {R, C}, "scaled rows");
}

// Options retired as neutral or worse (docs/experiments.md) may still be in a checkpoint's config: those
// that only steered training are ignored on resume (the rest of the run trains without them); a run this
// trainer cannot continue as it ran (a weight average, a frozen decoder) is refused, naming the file and field.
void refuse_retired_state(const json& config, const std::string& path) {
  if (config.value("ema_decay", 0.0f) > 0)
    throw Error("checkpoint " + path + ": its config has ema_decay " + config.at("ema_decay").dump() +
                ": its model is a weight average, which train-style no longer keeps (docs/experiments.md), so the "
                "run cannot be resumed; the checkpoint still stylises and evaluates as it is");
  if (config.value("lr_decoder", 1.0f) == 0)
    throw Error("checkpoint " + path + ": its config has lr_decoder 0: a frozen decoder, which train-style no longer "
                "supports (docs/experiments.md), so the run cannot be resumed as it ran; the checkpoint still "
                "stylises and evaluates as it is");
}
}  // namespace

// ---- trainer ----------------------------------------------------------------------------------------------
StyleTrainer::StyleTrainer(const scene::Scene& scene, model::FeatureModel features, StyleSet styles,
                           const StyleTrainConfig& cfg, std::ostream* log)
    : scene_(&scene), cfg_(cfg), styles_(std::move(styles)) {
  cfg_.validate();
  if ((cfg_.warm_start > 0 || cfg_.decoder_warm > 0) && features.profile != model::DecoderProfile::Fast)
    throw host::SettingError(cfg_.warm_start > 0 ? "warm_start" : "decoder_warm",
                             "needs the fast profile (the cached relu3_1 targets are at its map resolution); this "
                             "feature checkpoint is " + std::string(model::decoder_profile_name(features.profile)));
  model_ = model::StyleModel::create(std::move(features), cfg_.sict, cfg_.dst_bias, cfg_.seed, cfg_.style_decoder,
                                     cfg_.content_skip);
  model_.inference_supersample = cfg_.inference_supersample;
  if (model_.inference_supersample == model::kSupersampleByScene) {  // the recipe's: by this scene
    const int s = model_.stride();
    model_.inference_supersample = model::default_inference_supersample(
        (scene.width() + s - 1) / s, (scene.height() + s - 1) / s, model_.features.geo.ndc);
  }
  model_.decoder_phases = cfg_.decoder_phases;
  init(log);
  init_running_stats(log);
}

StyleTrainer::StyleTrainer(const scene::Scene& scene, const io::Checkpoint& ck, std::ostream* log) : scene_(&scene) {
  read_trainer_state(ck, "style-trainer", [&](const json& t) {
    refuse_retired_state(t.at("config"), ck.path);
    cfg_ = StyleTrainConfig::from_json(t.at("config"));
    iteration_ = t.at("iteration").get<int>();
    styles_ = StyleSet::from_json(ck.meta.at("styles"));
  });
  model_ = model::StyleModel::load(ck);
  init(log);
  adam_.load(ck, "", model_.params());
}

void StyleTrainer::init(std::ostream* log) {
  adam_ = nn::Adam({{"stylizer", cfg_.lr_stylizer}, {"decoder", cfg_.lr_decoder}}, cfg_.beta1, cfg_.beta2);
  vgg_ = nn::VggEncoder::load_default();
  if (cfg_.warm_start > 0 && cfg_.decoder_warm + cfg_.warm_start > iteration_) {
    if (cfg_.warm_maps == WarmMaps::Rendered) {
      rendered_maps_ = render_warm_maps(model_.features, *scene_, log);
    } else {
      features::TargetCacheOptions to;
      to.log = log;
      targets_ = features::load_or_compute_targets(*scene_, vgg_, to);
    }
  }
  const uint64_t s = cfg_.seed * 0x9E3779B97F4A7C15ULL + uint64_t(iteration_);
  patches_ = std::make_unique<features::PatchSampler>(*scene_, s + 1, cfg_.patch);
}

void StyleTrainer::init_running_stats(std::ostream* log) {
  if (cfg_.running_init_patches <= 0 || cfg_.sict != style::SictMode::VolumeAdaptive) return;
  // The mean of the patches' batch statistics (each patch's kept samples, as a training step sees them).
  const int C = style::Sict::kChannels;
  std::vector<double> mean(C, 0.0), var(C, 0.0);
  int n = 0;
  for (int i = 0; i < cfg_.running_init_patches; ++i) {
    const features::Patch p = patches_->next(model_.stride());
    const int64_t R = int64_t(p.height / model_.stride()) * (p.width / model_.stride());
    model::StyleModel::Context ctx;
    model_.render_content(Tensor::from_host(p.rays.origins, {R, 3}), Tensor::from_host(p.rays.directions, {R, 3}),
                          true, uint32_t(i), &ctx);
    if (!ctx.rays.head) continue;  // nothing kept
    const auto& sc = dynamic_cast<const model::SictHead::SictContext&>(*ctx.rays.head).sict;
    const auto m = sc.mean.to_host(), v = sc.var.to_host();
    for (int c = 0; c < C; ++c) {
      mean[size_t(c)] += m[size_t(c)];
      var[size_t(c)] += v[size_t(c)] * double(sc.points) / double(std::max<int64_t>(1, sc.points - 1));
    }
    ++n;
  }
  if (n == 0) return;
  std::vector<float> mf(C), vf(C);
  for (int c = 0; c < C; ++c) {
    mf[size_t(c)] = float(mean[size_t(c)] / n);
    vf[size_t(c)] = float(var[size_t(c)] / n);
  }
  model_.sict.running_mean.value.upload(mf);
  model_.sict.running_var.value.upload(vf);
  if (log) *log << "SICT running statistics initialised from the kept samples of " << n << " training patches" << std::endl;
}

StyleStepStats StyleTrainer::rendered_step(int64_t sub, std::mt19937_64& draw, const StyleTargets& style_targets,
                                           const style::StyleCode& code, style::Dst::StyleContext& sctx) {
  StyleStepStats st;
  const int s = model_.stride();
  const features::Patch p = patches_->next(s, draw);
  const int h = p.height / s, w = p.width / s;
  const int64_t R = int64_t(h) * w;
  model::StyleModel::Context ctx;
  const model::StyleModel::Content content =
      model_.render_content(Tensor::from_host(p.rays.origins, {R, 3}, "patch origins"),
                            Tensor::from_host(p.rays.directions, {R, 3}, "patch directions"), true,
                            uint32_t(cfg_.seed * 7919 + uint64_t(sub) + 1), &ctx);
  st.rays = R;
  st.kept = content.kept;
  OpacityMask mask;
  const bool masked = model_.features.geo.has_background;
  if (masked) {
    mask = opacity_mask(content.acc.to_host(), h, w, p.height, p.width);
    if (mask.empty() || !ctx.rays.head) {
      st.skipped = true;
      return st;
    }
  } else if (!ctx.rays.head) {
    st.skipped = true;
    return st;
  }
  const Tensor content41 = content_target(p);
  const Tensor rgb = model_.decode_styled(content, code, h, w, &ctx);
  const nn::VggFeatures out = vgg_.forward(rgb, 4, true);
  nn::VggFeatures grads;
  const StyleLossValues lv = style_losses(out, content41, style_targets, masked ? &mask : nullptr, cfg_.weights, &grads);
  const Tensor drgb = vgg_.backward(grads);
  vgg_.release();
  const style::Dst::ApplyGrads g = model_.backward(ctx, drgb);
  model_.dst.style_code_backward(sctx, g.dT, g.dmean, g.dstd, false);
  model_.sict.update_running(dynamic_cast<const model::SictHead::SictContext&>(*ctx.rays.head).sict);
  st.content = lv.content;
  st.style = lv.style;
  return st;
}

StyleStepStats StyleTrainer::warm_step(std::mt19937_64& draw, const StyleTargets& style_targets,
                                       const style::StyleCode& code, style::Dst::StyleContext& sctx) {
  StyleStepStats st;
  st.warm = true;
  const bool rendered = cfg_.warm_maps == WarmMaps::Rendered;
  const features::Patch p = patches_->next(4, draw);
  const int h = p.height / 4, w = p.width / 4;
  const int64_t R = int64_t(h) * w;
  // The map pixels of the patch's blocks: block centres (4j + 2) sit exactly on the map's pixel centres.
  std::vector<int32_t> view(size_t(R), p.view);
  std::vector<float> xy(size_t(2 * R)), acc(size_t(R), 1.0f);
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      xy[size_t(2 * (i * w + j))] = float(p.x0 + 4 * j + 2);
      xy[size_t(2 * (i * w + j) + 1)] = float(p.y0 + 4 * i + 2);
      if (rendered) acc[size_t(i * w + j)] = rendered_maps_.opacity(p.view, p.y0 / 4 + i, p.x0 / 4 + j);
    }
  const Tensor x = features::gather_targets(rendered ? rendered_maps_.maps.maps : targets_.maps,
                                            Tensor::from_host(view, {R}), Tensor::from_host(xy, {R, 2}));
  const Tensor acc_t = Tensor::from_host(acc, {R}, "warm-start opacity");
  // Rendered maps are normalised with the running statistics, those of 3D samples (what inference uses):
  // the normalisation is affine, so normalising a ray's mean feature equals averaging its samples'
  // normalised features, and only the attention is approximated. The batch statistics of a map of means
  // are not the samples' (averaging along a ray lowers the variance). VGG maps keep their batch statistics.
  style::Sict::Context sc;
  Tensor c = model_.sict.forward(x, !rendered, &sc);
  if (rendered) c = scale_rows(c, acc);  // c = acc * SICT(mean feature), as the kept samples' sum
  // The content skip's features likewise: acc * mean feature on rendered maps, normalised as SICT's input.
  const Tensor z = model_.content_skip && rendered ? scale_rows(x, acc) : x;
  model::StyleModel::Context mctx;  // its DST, skip and decoder parts
  const Tensor y = model_.transform_features(c, z, acc_t, sc.mean, sc.var, code, &mctx);
  OpacityMask mask;
  const bool masked = rendered && model_.features.geo.has_background;
  if (masked) {
    mask = opacity_mask(acc, h, w, p.height, p.width);
    if (mask.empty()) {
      st.skipped = true;
      return st;
    }
  }
  const Tensor content41 = content_target(p);
  const Tensor background =
      rendered ? model_.features.field.shell_term(model_.features.geo, Tensor::from_host(p.rays.origins, {R, 3}),
                                                  Tensor::from_host(p.rays.directions, {R, 3}), acc_t)
               : Tensor();
  const Tensor rgb = rendered ? model_.decode_rows(y, acc_t, h, w, &code, &mctx, background)
                              : model_.decode_map(nn::rows_to_image(y, h, w), &code, &mctx.decoder);
  const nn::VggFeatures out = vgg_.forward(rgb, 4, true);
  nn::VggFeatures grads;
  const StyleLossValues lv = style_losses(out, content41, style_targets, masked ? &mask : nullptr, cfg_.weights, &grads);
  const Tensor drgb = vgg_.backward(grads);
  vgg_.release();
  const Tensor dy = nn::rows_to_image_backward(model_.decode_map_backward(mctx.decoder, drgb, true));
  const style::Dst::ApplyGrads g = model_.transform_backward(mctx, dy);
  model_.dst.style_code_backward(sctx, g.dT, g.dmean, g.dstd, false);
  model_.sict.backward(sc, rendered ? scale_rows(g.dc, acc) : g.dc, false);
  // The running statistics are left alone: they describe 3D samples, which these 2D maps only resemble.
  st.content = lv.content;
  st.style = lv.style;
  st.rays = R;
  return st;
}

StyleStepStats StyleTrainer::decoder_warm_step(const Tensor& style_image, const nn::VggFeatures& style_taps) {
  StyleStepStats st;
  st.decoder_warm = true;
  constexpr float kFeatureWeight = 0.1f;  // stage 2's patch loss
  model::StyleModel::DecoderCtx dctx;
  style::StyleCode own;  // the crop's own relu4_1 statistics, for the vgg-adain-relu4 decoder
  if (model_.map_decoder->renormalises_relu4()) style::set_relu4_stats(own, style_taps[3]);
  const Tensor rgb = model_.decode_map(style_taps[2], &own, &dctx);
  host::expect_shape(rgb, style_image.shape(), "train-style decoder warm-up", "decoded style crop");
  const ReconstructionLoss loss = reconstruction_loss(vgg_, rgb, style_image, style_taps, kFeatureWeight);
  model_.decode_map_backward(dctx, loss.drgb, false);
  st.content = loss.pixel_mse + kFeatureWeight * loss.feature_mse;
  st.rays = rgb.numel() / 3;
  return st;
}

void StyleTrainer::set_group_lr(const std::string& group, float lr) {
  for (nn::AdamGroup& g : adam_.groups())
    if (g.name == group) g.lr = lr;
}

// The decoder trains from the first step, so its rate decays over the whole run. The stylizer starts after
// the decoder warm-up: its rate decays over the rest of the run, from lr_stylizer at its first step (on the
// run's clock, a 1500-step warm-up of a 45-minute run would start it at ~0.5 lr_stylizer).
void StyleTrainer::set_step_lrs(int k, bool decoder_warm) {
  const double progress = schedule_progress_ >= 0 ? std::min(1.0, schedule_progress_)
                                                  : double(k - 1) / double(std::max(1, cfg_.iters));
  if (!decoder_warm && stylizer_start_ < 0) {
    // Where the stylizer's decay starts: at once without a warm-up; here when this run just ended it; a run
    // resumed after it continues by iterations (decoder_warm / iters) or, under a time budget (whose
    // progress restarts at a resume), starts at the resumed run's start.
    if (cfg_.decoder_warm == 0 || schedule_progress_ >= 0)
      stylizer_start_ = iteration_ == cfg_.decoder_warm && cfg_.decoder_warm > 0 ? progress : 0.0;
    else
      stylizer_start_ = double(cfg_.decoder_warm) / double(std::max(1, cfg_.iters));
  }
  const double stylizer_progress =
      stylizer_start_ < 0 ? 0.0 : std::clamp((progress - stylizer_start_) / std::max(1e-9, 1.0 - stylizer_start_), 0.0, 1.0);
  const double decay = double(cfg_.lr_decay_ratio);
  set_group_lr("stylizer", float(double(cfg_.lr_stylizer) * std::pow(decay, stylizer_progress)));
  set_group_lr("decoder", float(double(cfg_.lr_decoder) * std::pow(decay, progress)));
}

std::shared_ptr<const StyleTrainer::EncodedStyle> StyleTrainer::encoded_style(const std::string& path, bool whole_image,
                                                                              const std::function<Tensor()>& load) {
  if (whole_image) {
    const auto hit = encoded_styles_.find(path);
    if (hit != encoded_styles_.end()) return hit->second;
  }
  const nn::VggFeatures taps = vgg_.forward(load(), 4, false);
  auto e = std::make_shared<EncodedStyle>();
  e->targets = style_targets(taps);
  e->taps[2] = taps[2];
  e->taps[3] = taps[3];
  const size_t bytes = size_t(taps[2].numel() + taps[3].numel()) * sizeof(float);
  if (whole_image && encoded_style_bytes_ + bytes <= kEncodedStyleBytes) {
    encoded_style_bytes_ += bytes;
    encoded_styles_.emplace(path, e);
  }
  return e;
}

Tensor StyleTrainer::content_target(const features::Patch& p) {
  // At most 2 x 2 corners a view (an image up to 7 px larger than the patch, which keeps multiples of 8).
  const bool whole_view = scene_->width() - p.width < 8 && scene_->height() - p.height < 8;
  const int64_t key = (int64_t(p.view) * 8 + p.x0 / 4) * 8 + p.y0 / 4;
  if (whole_view) {
    const auto hit = content_targets_.find(key);
    if (hit != content_targets_.end()) return hit->second;
  }
  Tensor t = vgg_.forward(p.rgb_tensor(), 4, false)[3];
  const size_t bytes = size_t(t.numel()) * sizeof(float);
  if (whole_view && content_target_bytes_ + bytes <= kContentTargetBytes) {
    content_target_bytes_ += bytes;
    content_targets_.emplace(key, t);
  }
  return t;
}

StyleStepStats StyleTrainer::sub_step(int64_t g, StepKind kind) {
  // Every draw of sub-batch g (its style, crop and patch) comes from g and the seed alone, so a step's
  // sub-batches are the same whichever rank takes them.
  std::mt19937_64 draw = sub_batch_draws(cfg_.seed, g);
  std::uniform_int_distribution<size_t> pick(0, styles_.train.size() - 1);
  const std::string& path = styles_.train[pick(draw)];
  auto crop = [&] {
    auto source = style_sources_.find(path);
    if (source == style_sources_.end())
      source = style_sources_.emplace(path, style::load_style_source(path, cfg_.style_size)).first;
    // Draws the crop's corner only when the crop is smaller than the image.
    return style::crop_style_image(source->second, cfg_.style_crop, &draw, path);
  };
  StyleStepStats st;
  if (kind == StepKind::DecoderWarm) {
    const Tensor simg = crop();
    st = decoder_warm_step(simg, vgg_.forward(simg, 4, false));  // the style branch is not used
  } else {
    const auto style = encoded_style(path, cfg_.style_size == cfg_.style_crop, crop);
    style::Dst::StyleContext sctx;
    const style::StyleCode code = model_.style_code(style->taps, &sctx);
    st = kind == StepKind::Warm ? warm_step(draw, style->targets, code, sctx)
                                : rendered_step(g, draw, style->targets, code, sctx);
  }
  st.style_name = stem(path);
  return st;
}

StyleStepStats StyleTrainer::step() {
  const auto t0 = std::chrono::steady_clock::now();
  const int k = iteration_ + 1;
  if (styles_.train.empty()) throw Error("train-style: no training styles");
  StepKind kind = k <= cfg_.decoder_warm ? StepKind::DecoderWarm
                  : k <= cfg_.decoder_warm + cfg_.warm_start ? StepKind::Warm
                                                            : StepKind::Rendered;
  if (kind == StepKind::Warm && schedule_progress_ >= cfg_.warm_share) {
    // The warm start's share of the minutes is spent: it ends here, and the config (hence the checkpoint)
    // records the steps it took, so a resumed run goes on with rendered steps.
    cfg_.warm_start = k - 1 - cfg_.decoder_warm;
    kind = StepKind::Rendered;
  }
  if (kind == StepKind::Rendered && (rendered_maps_.maps.maps.defined() || targets_.maps.defined())) {
    rendered_maps_ = RenderedWarmMaps{};  // the warm start is over: its maps (2 GB at 800x800) go
    targets_ = features::FeatureTargets{};
  }
  model_.zero_grad();
  // One style a step in one process: the step is that style's. Otherwise this rank's share of the step's
  // styles, their gradients and SICT's running statistics then averaged over every rank's.
  host::Dist& dist = host::Dist::world();
  const int B = cfg_.styles_per_step;
  const bool batched = B > 1 || dist.size() > 1;
  std::unique_ptr<BufferMoves> moves;
  if (batched) moves = std::make_unique<BufferMoves>(model_.sict.buffers());
  const std::vector<nn::Param*> stepped = kind == StepKind::DecoderWarm ? model_.decoder_params() : model_.params();
  GradientSum grads;
  StyleStepStats st;
  std::vector<double> sums(5, 0.0);  // content, style, contributing styles, rays, kept
  for (int j = 0; j < B; ++j) {
    if (!my_share(j, dist)) continue;
    if (moves) moves->restart();
    const StyleStepStats one = sub_step(int64_t(k - 1) * B + j, kind);
    if (moves && kind == StepKind::Rendered && !one.skipped) moves->add();
    if (batched && !one.skipped) grads.add(stepped);
    if (st.style_name.empty()) st = one;
    if (!one.skipped) sums[0] += one.content, sums[1] += one.style, sums[2] += 1;
    sums[3] += double(one.rays), sums[4] += double(one.kept);
  }
  if (batched) {
    dist.allreduce_sum(sums);
    moves->finish(dist);
    st.skipped = sums[2] == 0;
    st.content = st.skipped ? 0 : sums[0] / sums[2];
    st.style = st.skipped ? 0 : sums[1] / sums[2];
    st.rays = int64_t(sums[3]);
    st.kept = int64_t(sums[4]);
    if (B > 1) st.style_name += " +" + std::to_string(B - 1);
  }
  st.decoder_warm = kind == StepKind::DecoderWarm;
  st.warm = kind == StepKind::Warm;
  if (!st.skipped) {
    if (!std::isfinite(st.content + st.style))
      throw Error("train-style: the loss is not finite at iteration " + std::to_string(k) + " (style " + st.style_name +
                  "); try lower learning rates or another --seed");
    if (batched) sync_.add(grads.average(stepped, sums[2], dist));
    set_step_lrs(k, st.decoder_warm);
    // The decoder warm-up steps the decoder only: the stylizer's zeroed gradients would advance its Adam
    // clocks, and a stylizer that starts after 1500 such steps would begin without bias correction (its
    // first ~100 updates up to ~3x their intended size).
    adam_.step(stepped);
  }
  iteration_ = k;
  if (cfg_.finite_check_every > 0 && k % cfg_.finite_check_every == 0) {
    const std::string bad = model_.first_nonfinite();
    if (!bad.empty())
      throw Error("train-style: '" + bad + "' holds NaN or infinite values after iteration " + std::to_string(k));
  }
  st.iteration = k;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return st;
}

HoldoutLoss StyleTrainer::evaluate_holdout(int max_styles) {
  HoldoutLoss h;
  if (styles_.holdout.empty()) return h;
  const int s = model_.stride();
  const int W = scene_->width(), H = scene_->height();
  const features::Patch p = patches_->at(0, ((W - patches_->width()) / 2) / 4 * 4, ((H - patches_->height()) / 2) / 4 * 4, s);
  const int ph = p.height / s, pw = p.width / s;
  const int64_t R = int64_t(ph) * pw;
  const model::StyleModel::Content content =
      model_.render_content(Tensor::from_host(p.rays.origins, {R, 3}), Tensor::from_host(p.rays.directions, {R, 3}),
                            false, 0, nullptr);
  const bool masked = model_.features.geo.has_background;
  OpacityMask mask;
  if (masked) {
    mask = opacity_mask(content.acc.to_host(), ph, pw, p.height, p.width);
    if (mask.empty()) return h;
  }
  const nn::VggFeatures truth = vgg_.forward(p.rgb_tensor(), 4, false);
  const int n = (max_styles > 0) ? std::min<int>(max_styles, int(styles_.holdout.size())) : int(styles_.holdout.size());
  for (int i = 0; i < n; ++i) {
    const std::string& path = styles_.holdout[size_t(i)];
    const auto style = encoded_style(path, true, [&] { return load_style_image(path, cfg_.style_crop, cfg_.style_crop, nullptr); });
    const style::StyleCode code = model_.style_code(style->taps, nullptr);
    const Tensor rgb = model_.decode_styled(content, code, ph, pw, nullptr);
    const nn::VggFeatures out = vgg_.forward(rgb, 4, false);
    const StyleLossValues lv = style_losses(out, truth[3], style->targets, masked ? &mask : nullptr, cfg_.weights, nullptr);
    h.content += lv.content;
    h.style += lv.style;
    ++h.styles;
  }
  h.content /= n;
  h.style /= n;
  return h;
}

void StyleTrainer::save(const std::string& path, const json& scene_meta) {
  const std::string bad = model_.first_nonfinite();
  if (!bad.empty())
    throw Error("train-style: '" + bad + "' holds NaN or infinite values at iteration " + std::to_string(iteration_) +
                "; checkpoint " + path + " not written");
  io::Checkpoint ck;
  ck.kind = "style";
  model_.save(ck);
  ck.meta["scene"] = scene_meta;
  ck.meta["styles"] = styles_.to_json();
  ck.meta["trainer"] = {{"config", cfg_.to_json()}, {"iteration", iteration_}};
  adam_.save(ck, "");
  io::save_checkpoint(path, ck);
}

// ---- run loop ----------------------------------------------------------------------------------------------
namespace {

// The style stage in the training loop: the window's content and style losses, the held-out losses every
// eval_every steps (untimed), the lr decay following the budget's fraction.
class StyleLoopStage : public TrainerLoopStage<StyleTrainer, StyleRunOptions, StyleStepStats> {
 public:
  StyleLoopStage(StyleTrainer& t, const StyleRunOptions& o, HoldoutLoss& holdout) : TrainerLoopStage(t, o), holdout_(holdout) {}
  int total() const override { return t_.config().iters; }
  void before_step(const TrainingBudget& budget) override {
    if (budget.limited()) t_.set_schedule_progress(budget.fraction());
  }
  void step(bool) override {
    last_ = t_.step();
    if (last_.skipped)
      ++skipped_;
    else
      content_ += last_.content, style_ += last_.style, ++losses_;
  }
  std::string window_line(double) override {
    std::ostringstream l;
    l << std::fixed << std::setprecision(4) << (last_.warm ? " (2D warm start)" : "")
      << (last_.decoder_warm ? " (decoder warm-up: inversion loss in 'content')" : "");
    if (losses_) l << "  content " << content_ / losses_ << "  style " << style_ / losses_;
    if (skipped_) l << "  (" << skipped_ << " empty patches skipped)";
    content_ = style_ = 0;
    losses_ = skipped_ = 0;
    return l.str();
  }
  void after_report() override {
    if (o_.eval_every > 0 && t_.iteration() % o_.eval_every == 0) evaluate();
  }
  // The lr decay follows the budget's fraction; the refitted length only says when the run is done.
  void refit(const Refit& r) override { t_.set_total_iters(r.total_iters); }
  void save() override {
    if (!o_.checkpoint.empty()) t_.save(o_.checkpoint, o_.scene_meta);
  }
  // The held-out losses, logged with the time they took.
  void evaluate() {
    if (!o_.log || t_.styles().holdout.empty()) return;
    const auto t0 = std::chrono::steady_clock::now();
    holdout_ = t_.evaluate_holdout(o_.eval_styles);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    *o_.log << std::fixed << std::setprecision(4) << "  held-out (" << holdout_.styles
            << " styles never trained on) at it " << t_.iteration() << ": content " << holdout_.content << "  style "
            << holdout_.style << std::setprecision(1) << "  (" << s << " s)" << std::endl;
  }

 private:
  HoldoutLoss& holdout_;
  double content_ = 0, style_ = 0;
  int losses_ = 0, skipped_ = 0;
};

}  // namespace

StyleRunSummary run_style_training(StyleTrainer& trainer, const StyleRunOptions& opt) {
  StyleRunSummary sum;
  StyleLoopStage stage(trainer, opt, sum.last_holdout);
  if (trainer.iteration() == 0 && opt.eval_every > 0) stage.evaluate();
  const LoopResult r = run_training_loop(stage, loop_control(opt, style_stage_programs(trainer.model())));
  if (opt.eval_every > 0 && trainer.iteration() % opt.eval_every != 0) stage.evaluate();
  sum.iterations = r.iterations;
  sum.seconds = r.seconds;
  return sum;
}

}  // namespace stylerf::train
