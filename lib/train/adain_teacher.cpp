#include "lib/train/adain_teacher.hpp"

#include "host/error.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/ops.hpp"

namespace stylerf::train {

using host::Error;

AdainTeacher AdainTeacher::load_default() {
  AdainTeacher t;
  t.decoder_ = nn::load_adain_decoder("", "adain_teacher.");
  return t;
}

Tensor AdainTeacher::target_rows(nn::VggEncoder& vgg, const Tensor& content41, const Tensor& style41) const {
  if (content41.ndim() != 4 || content41.dim(1) != 512 || style41.ndim() != 4 || style41.dim(1) != 512)
    throw Error("adain teacher: relu4_1 maps [1, 512, h, w] expected, got content " + host::shape_str(content41.shape()) +
                " and style " + host::shape_str(style41.shape()));
  const Tensor image = decoder_.forward(nn::adain_forward(content41, style41));
  return nn::image_to_rows(vgg.forward(image, 3, false)[2]);
}

TeacherLoss teacher_loss(const Tensor& y, const Tensor& target, const std::vector<float>* row_weights, float weight) {
  if (y.ndim() != 2 || y.shape() != target.shape())
    throw Error("adain teacher: the stylised map " + host::shape_str(y.shape()) + " and its target " +
                host::shape_str(target.shape()) + " must be the same [rays, channels]");
  const int64_t R = y.dim(0), C = y.dim(1);
  if (row_weights && int64_t(row_weights->size()) != R)
    throw Error("adain teacher: " + std::to_string(row_weights->size()) + " row weights for " + std::to_string(R) + " rows");
  const auto yv = y.to_host(), tv = target.to_host();
  double wsum = 0;
  for (int64_t r = 0; r < R; ++r) wsum += row_weights ? double((*row_weights)[size_t(r)]) : 1.0;
  TeacherLoss out;
  std::vector<float> g(yv.size(), 0.0f);
  if (wsum > 0) {
    const double scale = double(weight) / (wsum * double(C));
    double acc = 0;
    for (int64_t r = 0; r < R; ++r) {
      const double a = row_weights ? double((*row_weights)[size_t(r)]) : 1.0;
      for (int64_t c = 0; c < C; ++c) {
        const size_t i = size_t(r * C + c);
        const double d = double(yv[i]) - double(tv[i]);
        acc += a * d * d;
        g[i] = float(2.0 * scale * a * d);
      }
    }
    out.value = scale * acc;
  }
  out.dy = Tensor::from_host(g, {R, C}, "adain teacher gradient");
  return out;
}

}  // namespace stylerf::train
