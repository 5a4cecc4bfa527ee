// Sampling-invariant content transformation (StyleRF Sec. 3.2), applied to each kept 3D sample's 256
// VGG channels before compositing (kernels/sict.cl):
//   1. volume-adaptive instance norm over the points: training normalises with the batch statistics and
//      (separately, update_running) moves running statistics towards them with momentum 1e-4; inference
//      uses the running statistics only, so a point's output never depends on which other points were
//      sampled (the whole point of SICT: views render consistently);
//   2. q, k, v = 1x1 convs 256 -> 32 (one GEMM to [K, 96] here);
//   3. channel self-attention per point: out_i = sum_j softmax_j(q_i k_j) v_j over its 32 channels.
// The authors' numerics (docs/design.md): eps 1e-5, no affine, running variance updated with the unbiased
// batch variance. Checked against values from the authors' module (tests/data, tests/test_sict_dst.cpp).
//
// forward_factored: stage 3 feeds SICT x = comps B, the feature field's F grid components per point times
// its basis [F, 256] (no bias, frozen). Normalisation and q/k/v are then linear in comps, so they fold into
// the basis and the [K, 256] features are never formed (lib/style/sict_factored.cpp; design.md, "SICT on
// the field's components"). Same maths; F = 72..144 columns instead of 256 and one GEMM fewer per pass.
//
// The paper's ablations (Fig. 7) are modes: VanillaIn normalises with the batch statistics in training and
// inference alike (what makes blocks of rays disagree); None skips the normalisation.
//
// Parameters (group kGroupStylizer of the style model): "<prefix>qkv.weight" [256, 96] (q | k | v columns,
// nn::linear's [in, out] layout), "<prefix>qkv.bias" [96]; buffers "<prefix>running_mean" [256] (zeros) and
// "<prefix>running_var" [256] (ones).
#pragma once
#include <cstdint>
#include <string>

#include "host/tensor.hpp"
#include "lib/nn/module.hpp"

namespace stylerf::style {

using host::Tensor;

enum class SictMode { VolumeAdaptive, VanillaIn, None };
// The build options of kernels/sict.cl: -DSICT_EMBED=Sict::kEmbed (the kernel refuses to build without).
std::string sict_build_options();
SictMode parse_sict_mode(const std::string& s);  // "volume-adaptive" | "vanilla-in" | "none"
const char* sict_mode_name(SictMode m);

class Sict : public nn::Module {
 public:
  static constexpr int kChannels = 256, kEmbed = 32;
  static constexpr float kEps = 1e-5f, kMomentum = 1e-4f;

  SictMode mode = SictMode::VolumeAdaptive;
  nn::Param qkv_w, qkv_b;
  nn::StateBuffer running_mean, running_var;

  // PyTorch Conv1d's default init (U(+-1/sqrt(256)) for weights and biases), seeded.
  static Sict create(SictMode mode, int group, uint64_t seed, const std::string& prefix = "stylizer.sict.");

  struct Context {
    Tensor x;           // [K, 256] input (kept only when dx is needed)
    Tensor normed;      // [K, 256] what the q/k/v convs saw
    Tensor mean, var;   // [256] the statistics used (batch or running); undefined in mode None
    bool batch_stats = false;
    Tensor qkv;         // [K, 96]
    int64_t points = 0;
    // forward_factored only, what the weight gradient needs instead of `normed`:
    //   normed = rows * scaled_basis - shift (shift undefined: 0).
    Tensor rows;          // [K, F] the components, centred by their batch mean when batch statistics are used
    Tensor scaled_basis;  // [F, 256] the basis with column c times rsqrt(var_c + eps) (the basis in mode None)
    Tensor shift;         // [256] running mean * rsqrt(running var + eps): running statistics only
    bool factored() const { return scaled_basis.defined(); }
  };
  // x [K, 256] -> [K, 32]. training selects batch statistics in VolumeAdaptive mode. The running
  // statistics do not move here (forward is const): call update_running(ctx) once per training step.
  Tensor forward(const Tensor& x, bool training, Context* ctx) const;
  // The same output for x = comps basis (comps [K, F], basis [F, 256]) without forming x. The batch
  // statistics come from the components' centred covariance: mean = mean(comps) B, var_c = B_c^T Cov B_c.
  // ctx->mean / var are x's statistics, as forward's, for update_running. Its backward gives no dx.
  Tensor forward_factored(const Tensor& comps, const Tensor& basis, bool training, Context* ctx) const;
  // Accumulates into qkv_w / qkv_b; returns dx when need_dx (through the batch statistics when they were
  // used; requires the context of a forward that kept x).
  Tensor backward(const Context& ctx, const Tensor& dy, bool need_dx);
  // A momentum step of the running statistics towards the batch statistics of ctx (VolumeAdaptive with
  // batch statistics only; otherwise nothing).
  void update_running(const Context& ctx);

  void collect_params(std::vector<nn::Param*>& out) override;
  void collect_buffers(std::vector<nn::StateBuffer*>& out) override;
};

// The op pieces, for tests and benches.
// y = (x - mean) / sqrt(var + eps), per column of x [K, C].
Tensor point_norm_forward(const Tensor& x, const Tensor& mean, const Tensor& var, float eps);
// Batch statistics (fixed false): through mean and var of the same rows; fixed true: constants.
Tensor point_norm_backward(const Tensor& y, const Tensor& var, const Tensor& dy, float eps, bool fixed);
// qkv [K, 96] -> [K, 32]; and its backward, dqkv [K, 96].
Tensor channel_attention_forward(const Tensor& qkv);
Tensor channel_attention_backward(const Tensor& qkv, const Tensor& dout);

}  // namespace stylerf::style
