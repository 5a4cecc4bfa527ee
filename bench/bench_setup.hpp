// The patch a render bench draws: a checkpoint's geometry and first training camera resized to size x size
// (--ckpt: density, features or style kind), or a synthetic positive density where every sample is kept
// (a worst case for the render parts). Shared by bench patch and bench dst.
#pragma once
#include <array>
#include <string>

#include "bench/bench.hpp"
#include "lib/model/geometry.hpp"
#include "lib/nn/conv_stack.hpp"
#include "lib/scene/scene.hpp"

namespace stylerf::bench {

struct Setup {
  model::Geometry geo;
  scene::Scene scene;  // cameras only
  scene::Camera cam;
  std::string source;
  std::array<int, 3> rank{48, 48, 48};
};

Setup setup_from(const BenchOptions& opt);

// FLOPs of a decoder's 3x3 convs on an h x w input (upsampling doubles the size after a conv), forward.
double stack_flops(const nn::ConvStack& s, int h, int w);
// VGG-19 to relu4_1 (conv1_1 .. conv4_1) on an S x S image, forward.
double vgg_flops(int S);

}  // namespace stylerf::bench
