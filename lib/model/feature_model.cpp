#include "lib/model/feature_model.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/weights.hpp"
#include "lib/scene/rays.hpp"

namespace stylerf::model {

using host::Error;
using nlohmann::json;

DecoderProfile parse_decoder_profile(const std::string& s) {
  if (s == "fast") return DecoderProfile::Fast;
  if (s == "paper") return DecoderProfile::Paper;
  throw Error("unknown decoder profile '" + s + "' (fast, paper)");
}

const char* decoder_profile_name(DecoderProfile p) { return p == DecoderProfile::Fast ? "fast" : "paper"; }

int render_stride(DecoderProfile p) { return p == DecoderProfile::Fast ? 4 : 1; }

scene::Camera strided_camera(const scene::Camera& cam, int stride) {
  scene::Camera c = cam;
  c.width = (cam.width + stride - 1) / stride;
  c.height = (cam.height + stride - 1) / stride;
  c.fx /= stride;
  c.fy /= stride;
  c.cx /= stride;
  c.cy /= stride;
  return c;
}

FeatureModel FeatureModel::create(const Geometry& geo, const FeatureFieldConfig& cfg, DecoderProfile profile,
                                  uint64_t seed) {
  FeatureModel m;
  m.geo = geo;
  m.field = FeatureField::create(geo, cfg, seed);
  m.profile = profile;
  if (profile == DecoderProfile::Fast) {
    m.decoder = nn::fast_decoder_from_adain(nn::load_adain_decoder(), "decoder.", kGroupDecoder);
  } else {
    m.decoder = nn::ConvStack(nn::plain_decoder_spec("decoder.", kGroupDecoder), seed * 2 + 7);
  }
  if (m.decoder.in_channels() != cfg.channels)
    throw Error("feature model: the " + std::string(decoder_profile_name(profile)) + " decoder takes " +
                std::to_string(m.decoder.in_channels()) + " channels, the field renders " +
                std::to_string(cfg.channels));
  return m;
}

// Rays through the centres of the stride x stride blocks of the full camera (NDC from the full camera, so
// the ray space is exactly the one training used, whatever the rounding of the map's size).
scene::Rays block_rays(const scene::Scene& scene, const scene::Camera& cam, int stride, int& w, int& h, float fx,
                       float fy) {
  w = (cam.width + stride - 1) / stride;
  h = (cam.height + stride - 1) / stride;
  scene::Rays r;
  r.origins.resize(size_t(3) * w * h);
  r.directions.resize(size_t(3) * w * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t i = size_t(y) * w + x;
      float* o = &r.origins[3 * i];
      float* d = &r.directions[3 * i];
      scene::pixel_ray(cam, stride * (x + fx), stride * (y + fy), o, d);
      if (scene.effects.ndc) scene::to_ndc(cam, scene.ndc_near, o, d);
    }
  return r;
}

FeatureModel::FeatureMap FeatureModel::render_feature_map(const scene::Scene& scene, const scene::Camera& cam,
                                                          int chunk) const {
  if (chunk < 1) throw Error("render_feature_map: chunk must be >= 1");
  int w = 0, h = 0;
  const scene::Rays rays = block_rays(scene, cam, stride(), w, h);
  const int64_t n = int64_t(w) * h, C = field.channels();
  Tensor rows({n, C}, "rendered feature rows");
  std::vector<float> all(size_t(n * C));
  FeatureMap fm;
  fm.width = w;
  fm.height = h;
  fm.acc.resize(size_t(n));
  fm.depth.resize(size_t(n));
  for (int64_t b = 0; b < n; b += chunk) {
    const int64_t R = std::min<int64_t>(chunk, n - b);
    std::vector<float> o(rays.origins.begin() + 3 * b, rays.origins.begin() + 3 * (b + R));
    std::vector<float> d(rays.directions.begin() + 3 * b, rays.directions.begin() + 3 * (b + R));
    RayResult r = field.render(geo, Tensor::from_host(o, {R, 3}, "render origins"),
                               Tensor::from_host(d, {R, 3}, "render directions"), RayOptions{}, nullptr);
    const auto v = r.value.to_host(), acc = r.acc.to_host(), depth = r.depth.to_host();
    std::copy(v.begin(), v.end(), all.begin() + b * C);
    for (int64_t i = 0; i < R; ++i) {
      fm.acc[size_t(b + i)] = acc[size_t(i)];
      fm.depth[size_t(b + i)] = acc[size_t(i)] > 1e-6f ? depth[size_t(i)] / acc[size_t(i)] : 0.0f;
    }
  }
  rows.upload(all);
  fm.features = nn::rows_to_image(rows, h, w);
  return fm;
}

FeatureModel::DecodedView FeatureModel::render_decoded(const scene::Scene& scene, const scene::Camera& cam,
                                                       int chunk) const {
  DecodedView out;
  out.map = render_feature_map(scene, cam, chunk);
  const Tensor img = decoder.forward(out.map.features, nullptr);  // [1, 3, h * 2^u, w * 2^u]
  const int H = int(img.dim(2)), W = int(img.dim(3));
  if (H < cam.height || W < cam.width)
    throw Error("feature model: the decoder gave " + std::to_string(W) + "x" + std::to_string(H) +
                " pixels for a " + std::to_string(cam.width) + "x" + std::to_string(cam.height) + " view");
  // The decoded image covers whole blocks: crop it to the camera (the blocks' padding is at the bottom/right).
  const auto v = img.to_host();
  out.width = cam.width;
  out.height = cam.height;
  out.rgb.resize(size_t(3) * cam.width * cam.height);
  const size_t plane = size_t(H) * W;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      for (int c = 0; c < 3; ++c)
        out.rgb[(size_t(y) * cam.width + x) * 3 + c] = std::clamp(v[c * plane + size_t(y) * W + x], 0.0f, 1.0f);
  return out;
}

void FeatureModel::collect_params(std::vector<nn::Param*>& out) {
  field.collect_params(out);
  decoder.collect_params(out);
}

void FeatureModel::save(io::Checkpoint& ck) {
  geo.save(ck, "geometry.");
  const auto g = field.head.grid();
  ck.meta["feature_model"] = {{"profile", decoder_profile_name(profile)},
                              {"rank", field.cfg.rank},
                              {"channels", field.cfg.channels},
                              {"res", g.res},
                              {"decoder", decoder.spec().describe()}};
  nn::Module::save(ck, "model.");
}

FeatureModel FeatureModel::load(const io::Checkpoint& ck) {
  if (!ck.meta.contains("feature_model")) throw Error("checkpoint " + ck.path + " has no feature model");
  FeatureModel m;
  m.geo = Geometry::load(ck, "geometry.");
  try {
    const json& j = ck.meta.at("feature_model");
    m.profile = parse_decoder_profile(j.at("profile").get<std::string>());
    m.field.cfg.rank = j.at("rank").get<std::array<int, 3>>();
    m.field.cfg.channels = j.at("channels").get<int>();
    const auto res = j.at("res").get<std::array<int, 3>>();
    // Shapes from a fresh field and decoder of the stored architecture; values then loaded by name.
    m.field.head = FeatureGridHead(field::VMGrid::create(res, m.field.cfg.rank, 0.0f, 0));
    m.field.basis.value = Tensor::zeros({m.field.head.channels(), m.field.cfg.channels}, "feature basis");
    if (m.geo.has_background) m.field.background.value = Tensor::zeros({m.field.cfg.channels}, "feature background");
    if (m.geo.shell.on()) m.field.shell.value = Tensor::zeros({m.geo.shell.texels(), m.field.cfg.channels}, "feature shell");
    const nn::ConvStackSpec spec = m.profile == DecoderProfile::Fast ? nn::fast_decoder_spec("decoder.", kGroupDecoder)
                                                                     : nn::plain_decoder_spec("decoder.", kGroupDecoder);
    if (j.at("decoder").get<std::string>() != spec.describe())
      throw Error("checkpoint " + ck.path + ": its decoder is '" + j.at("decoder").get<std::string>() +
                  "', this build's " + decoder_profile_name(m.profile) + " decoder is '" + spec.describe() + "'");
    m.decoder = nn::ConvStack(spec, 0);
  } catch (const json::exception& e) {
    throw Error("checkpoint " + ck.path + ": bad feature-model metadata (" + e.what() + ")");
  }
  m.nn::Module::load(ck, "model.");
  m.decoder.freeze();
  return m;
}

}  // namespace stylerf::model
