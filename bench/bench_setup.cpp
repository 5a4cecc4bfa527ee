#include "bench/bench_setup.hpp"

#include <algorithm>
#include <cmath>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/model/density_model.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/nn/conv_stack.hpp"

namespace stylerf::bench {

using host::Error;

Setup setup_from(const BenchOptions& opt) {
  Setup s;
  const int S = opt.size;
  if (!opt.ckpt.empty()) {
    const auto ck = io::load_checkpoint(opt.ckpt, "");
    if (ck.kind == "density")
      s.geo = model::load_model(ck).geo;
    else if (ck.kind == "features" || ck.kind == "style")
      s.geo = model::Geometry::load(ck, "geometry.");
    else
      throw Error("bench patch: --ckpt " + opt.ckpt + " holds a '" + ck.kind + "' stage (density, features or style)");
    const auto meta = ck.meta.value("scene", nlohmann::json::object());
    scene::SceneOverrides o;
    o.load_images = false;
    s.scene = scene::open_scene_for(meta, opt.ckpt, o).scene;
    if (s.scene.format != "blender") s.rank = {48, 12, 12};
    s.cam = s.scene.train.at(0).camera.resized(S, S);
    s.source = opt.ckpt + " (" + s.scene.name + ", first training camera at " + std::to_string(S) + "x" +
               std::to_string(S) + ")";
    return s;
  }
  // Synthetic: planes and lines ~ N(1, 0.3), relu, distance scale 1: positive density everywhere.
  model::Geometry& g = s.geo;
  g.box_lo = {-1.5f, -1.5f, -1.5f};
  g.box_hi = {1.5f, 1.5f, 1.5f};
  g.near = 2.0f;
  g.far = 6.0f;
  g.act = field::DensityActivation::Relu;
  g.distance_scale = 1.0f;
  g.weight_threshold = 0.0f;
  g.density = field::VMGrid::create({64, 64, 64}, {4, 4, 4}, 0.3f, 1);
  auto v = g.density.params.to_host();
  for (auto& x : v) x = 0.5f + 0.3f * std::fabs(x);
  g.density.params.upload(v);
  g.update_step();
  g.max_samples = std::min(g.max_samples, 256);
  s.cam.width = s.cam.height = S;
  s.cam.fx = s.cam.fy = 1.1f * S;
  s.cam.cx = s.cam.cy = 0.5f * S;
  s.cam.c2w[2][3] = 4.0f;  // at z = 4 looking down -z at the box
  s.source = "synthetic geometry (64^3 positive density, <= 256 samples/ray, every sample kept)";
  return s;
}


// FLOPs of a stack of 3x3 convs on an h x w input (upsampling doubles the size after a conv).
double stack_flops(const nn::ConvStack& s, int h, int w) {
  double f = 0;
  for (const auto& l : s.layers()) {
    f += 2.0 * double(l.w.value.dim(0)) * double(l.w.value.dim(1)) * 9.0 * h * w;
    if (l.upsample) h *= 2, w *= 2;
  }
  return f;
}

// VGG-19 to relu4_1 (conv1_1 .. conv4_1) on an S x S image, forward.
double vgg_flops(int S) {
  const int layers[][3] = {{3, 64, 1}, {64, 64, 1}, {64, 128, 2}, {128, 128, 2}, {128, 256, 4},
                           {256, 256, 4}, {256, 256, 4}, {256, 256, 4}, {256, 512, 8}};
  double f = 0;
  for (const auto& l : layers) f += 2.0 * l[0] * l[1] * 9.0 * double(S / l[2]) * double(S / l[2]);
  return f;
}

}  // namespace stylerf::bench
