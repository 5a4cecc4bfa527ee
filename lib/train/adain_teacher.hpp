// 2D AdaIN as a teacher for the stylizer: train-style --adain-teacher W (off by default; not the paper's
// loss).
//
// Why: the style loss tells the stylizer how far a few statistics per channel of the decoded image are
// from the style's; from that alone it has to find what each of the map's 64x64 pixels should be, and a
// 45-minute run on this CPU gives it ~2000 such hints where the paper gives 25k. 2D AdaIN of the true
// patch with the step's style is a stylisation that eval-style itself uses as the yardstick, and the
// relu3_1 map of that image is a target for every pixel of DST's output, the map the style decoder draws.
// The teacher term W x MSE(DST output, relu3_1 of AdaIN(true patch, style)) adds that dense target. The
// stylizer stays what it is (SICT per 3D point, DST per ray), so views still agree; only the training
// signal changes.
#pragma once
#include <vector>

#include "host/tensor.hpp"
#include "lib/nn/conv_stack.hpp"
#include "lib/nn/vgg.hpp"

namespace stylerf::train {

using host::Tensor;

class AdainTeacher {
 public:
  // AdaIN's pretrained decoder (nn::load_adain_decoder; errors name the file), frozen: a copy of its own,
  // so a style decoder fine-tuned from the same weights does not move the teacher.
  static AdainTeacher load_default();
  // The target of a patch: relu3_1 of AdaIN's output from the patch's relu4_1 (content41 [1, 512, H/8,
  // W/8]) and the style's (style41), re-encoded by `vgg`, as rows [(H/4)(W/4), 256] (the map's layout).
  // Inference only: vgg keeps nothing for backward (call it before the forward that backward follows).
  Tensor target_rows(nn::VggEncoder& vgg, const Tensor& content41, const Tensor& style41) const;

 private:
  nn::ConvStack decoder_;
};

struct TeacherLoss {
  double value = 0;  // weight x the (row-weighted) mean squared difference
  Tensor dy;         // d value / d y, [R, C]
};
// weight x sum_r a_r sum_c (y_rc - t_rc)^2 / (C sum_r a_r), with a_r = row_weights[r] (null: all 1; on
// scenes with a background, the rays' opacities, so empty space is not taught AdaIN's background).
// Computed on the host in double (a 64x64 map is 1M values, a few ms). An Error when the shapes differ,
// and value 0 with a zero gradient when the row weights sum to 0.
TeacherLoss teacher_loss(const Tensor& y, const Tensor& target, const std::vector<float>* row_weights, float weight);

}  // namespace stylerf::train
