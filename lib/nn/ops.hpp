// Neural-network ops on device tensors (NCHW, float32). Each op has a forward and a backward, side by
// side; backward functions return fresh gradient tensors (they overwrite, never accumulate).
//
// Kernels: kernels/nn.cl (im2col/col2im, padding, bias, relu, pooling, upsampling),
//          kernels/strided.cl (strided im2col/col2im, k x k max pooling),
//          kernels/norm.cl (channel statistics, instance norm, AdaIN), kernels/loss.cl, kernels/optim.cl,
//          kernels/reduce.cl, kernels/elementwise.cl.
#pragma once
#include "host/tensor.hpp"
#include "lib/nn/conv_algo.hpp"

namespace stylerf::nn {

using host::Shape;
using host::Tensor;

// ---- conv2d (stride 1, "same" size; kernel 1 or 3) ---------------------------------------------
enum class Padding { Zero, Reflect };

// A Winograd conv transforms its weights on every call (kernels/winograd.cl wino_filter_transform: 36 x Cout x
// Cin floats at F(4x4), a third of the device time of a 128 px stylised frame). A ConvFilterCache handed
// to conv2d_forward / conv2d_backward keeps the transform of the weight tensor it last saw and reuses it
// while the same tensor comes back. It holds a handle on that tensor, so a replaced tensor (a load) makes
// it transform again; it cannot see writes into the same buffer. Share one only where the weights cannot
// change between the calls: a frozen network (VGG, LPIPS, a decoder at inference) or one training step's
// forward and backward. Whoever writes the weights in place (an optimiser step, init) calls clear().
class ConvFilterCache {
 public:
  void clear();
  // The transform for Winograd F(m x m, 3 x 3) of w: kept when w is the tensor of the last call with this
  // m, else made by `make` and kept (lib/nn/conv_winograd.cpp).
  template <class Make>
  const Tensor& get(int m, const Tensor& w, Make&& make) {
    Entry& e = entries_[m == 4 ? 1 : 0];
    if (!e.u.defined() || e.w.mem() != w.mem()) e = {w, make()};
    return e.u;
  }

 private:
  struct Entry {
    Tensor w, u;  // the weights (a handle: their buffer cannot be reused while kept) and their transform
  };
  Entry entries_[2];  // F(2x2), F(4x4)
};

// x [N,Cin,H,W], w [Cout,Cin,k,k] (k = 1 or 3), b [Cout] or undefined -> y [N,Cout,H,W]. `algo` picks how a
// 3x3 conv runs (lib/nn/conv_algo.hpp; Auto: the measured default). `filters` (may be null) keeps a
// Winograd transform of w across calls (above).
Tensor conv2d_forward(const Tensor& x, const Tensor& w, const Tensor& b, Padding pad, ConvAlgo algo = ConvAlgo::Auto,
                      ConvFilterCache* filters = nullptr);
struct Conv2dGrads {
  Tensor dx;  // undefined unless asked for
  Tensor dw;  // undefined unless asked for
  Tensor db;  // undefined unless asked for
};
// need_dx false skips the col2im work (frozen early layers); need_params false skips dW/db (frozen VGG).
Conv2dGrads conv2d_backward(const Tensor& x, const Tensor& w, const Tensor& dy, Padding pad, bool need_dx,
                            bool need_params, ConvAlgo algo = ConvAlgo::Auto, ConvFilterCache* filters = nullptr);

// ---- general conv2d: k x k, stride s, zero padding p (AlexNet's trunk) -----------------------------
// x [N,Cin,H,W], w [Cout,Cin,k,k] (any k >= 1), b [Cout] or undefined -> y [N,Cout,Ho,Wo] with
// Ho = floor((H + 2p - k) / s) + 1 (Wo likewise), as torch's Conv2d(stride=s, padding=p). s >= 1, p >= 0;
// a kernel larger than the padded input (k > H + 2p or k > W + 2p) is refused naming the sizes.
// im2col + GEMM like conv2d_forward (kernels/strided.cl), sharing its scratch and row chunking;
// conv2d_forward stays the faster choice for its stride-1 "same" cases.
// floor((in + 2 pad - k) / stride) + 1; 0 when the kernel is larger than the padded input.
int conv2d_output_size(int in, int k, int stride, int pad);
Tensor conv2d_strided_forward(const Tensor& x, const Tensor& w, const Tensor& b, int stride, int pad);
// dx (zero where no output reads the input: rows / columns the flooring leaves out), dw, db.
Conv2dGrads conv2d_strided_backward(const Tensor& x, const Tensor& w, const Tensor& dy, int stride, int pad,
                                    bool need_dx, bool need_params);

// ---- pointwise / spatial ---------------------------------------------------------------------
Tensor relu_forward(const Tensor& x);
Tensor relu_backward(const Tensor& y, const Tensor& dy);  // uses the output: dx = dy * (y > 0)

// 2x2 max pooling, stride 2, H and W >= 2; odd sizes floor (H/2 x W/2 output, the last row / column is
// dropped, as torch's MaxPool2d(2)). Backward routes dy to the first maximum of each window (0 elsewhere).
Tensor maxpool2x2_forward(const Tensor& x);
Tensor maxpool2x2_backward(const Tensor& x, const Tensor& dy);

// k x k max pooling, stride s, no padding: Ho = floor((H - k) / s) + 1 (torch's MaxPool2d(k, s)); H, W >= k,
// k, s >= 1 (kernels/strided.cl). Backward routes each window's dy to its first maximum in row-major
// order (as maxpool2x2); windows overlap when s < k, and an element that is the maximum of several
// windows gets the sum of their dy.
Tensor maxpool_forward(const Tensor& x, int k, int stride);
Tensor maxpool_backward(const Tensor& x, const Tensor& dy, int k, int stride);

// Polyphase ("a trous") 2x2 max pooling: the stride-2 pool at each of its four grid offsets, which
// together are a stride-1 pool. x [N,C,H,W], H and W even -> [4N, C, H/2, W/2], batch block 2a + b the
// pool moved by (a, b) (windows past the last row / column repeat it). Convs run on the phases as on any
// batch; phase_interleave_forward then puts them side by side: [4N, C, h, w] -> [N, C, 2h, 2w], y[n, c,
// 2i+a, 2j+b] = x[(2a+b)N + n, c, i, j], where a nearest upsampling of one phase would repeat it. A pool,
// convs and an upsampling become a net that moves with its input by one pixel, not two: what keeps the
// vgg-adain decoder from painting on a grid fixed to the image (lib/model/map_decoder.cpp).
// Backward routes each window's dy to its first maximum (as maxpool2x2_backward), summed over windows.
Tensor maxpool2x2_phases_forward(const Tensor& x);
Tensor maxpool2x2_phases_backward(const Tensor& x, const Tensor& dy);
Tensor phase_interleave_forward(const Tensor& x);
Tensor phase_interleave_backward(const Tensor& dy);  // the transpose: [N, C, 2h, 2w] -> [4N, C, h, w]

// Nearest-neighbour x2 upsampling; backward sums each 2x2 block.
Tensor upsample2x_forward(const Tensor& x);
Tensor upsample2x_backward(const Tensor& dy);

// ---- channel statistics, instance norm, AdaIN --------------------------------------------------
// Per (n, c) over H*W: mean and std = sqrt(var + eps), var the biased (population) variance.
// eps keeps std > 0 so constant channels (var = 0) give finite values and gradients.
struct ChannelStats {
  Tensor mean;  // [N,C]
  Tensor std;   // [N,C]
};
constexpr float kStatsEps = 1e-5f;
ChannelStats channel_stats_forward(const Tensor& x, float eps = kStatsEps);
Tensor channel_stats_backward(const Tensor& x, const ChannelStats& stats, const Tensor& dmean, const Tensor& dstd);

// y = (x - mean) / std per (n, c).
Tensor instance_norm_forward(const Tensor& x, ChannelStats* stats_out = nullptr, float eps = kStatsEps);
Tensor instance_norm_backward(const Tensor& x, const ChannelStats& stats, const Tensor& dy);

// AdaIN(c, s) = (c - mean_c) / std_c * std_s + mean_s, per (n, c); style may have another H, W.
Tensor adain_forward(const Tensor& content, const Tensor& style, float eps = kStatsEps);
struct AdainGrads {
  Tensor dcontent, dstyle;
};
AdainGrads adain_backward(const Tensor& content, const Tensor& style, const Tensor& dy, float eps = kStatsEps);
// AdaIN towards given statistics: y = (c - mean_c) / std_c * target.std + target.mean per (n, c), target
// [N, C] each. The target is a constant here (no gradient): the vgg-adain-relu4 style decoder's relu4_1
// re-normalisation, whose target is a style image's own VGG statistics (lib/model/style_model.hpp).
Tensor adain_to_stats_forward(const Tensor& content, const ChannelStats& target, float eps = kStatsEps);
Tensor adain_to_stats_backward(const Tensor& content, const ChannelStats& target, const Tensor& dy,
                               float eps = kStatsEps);  // d content
// Between given statistics: y = (c - source.mean) / source.std * target.std + target.mean per (n, c), both
// [N, C] constants: a fixed per-channel affine map. The vgg-adain-relu4 decoder at inference, with the
// source statistics measured once over the scene's views (a frame's own would make frames flicker as a
// whole). Inference only: its gradient is the affine's slope, which no training step asks for.
Tensor adain_between_stats_forward(const Tensor& content, const ChannelStats& source, const ChannelStats& target);

// ---- losses (return a [1] tensor; backward takes the upstream scalar gradient) ---------------
Tensor mse_forward(const Tensor& a, const Tensor& b);             // mean((a-b)^2)
Tensor mse_backward(const Tensor& a, const Tensor& b, float dloss);  // d/da
// AdaIN style loss: MSE(mean_a, mean_b) + MSE(std_a, std_b) over [N,C].
Tensor style_loss_forward(const Tensor& a, const Tensor& b, float eps = kStatsEps);
Tensor style_loss_backward(const Tensor& a, const Tensor& b, float dloss, float eps = kStatsEps);  // d/da
// The same loss against b's statistics measured once (style_target(b)): a style image seen at many steps
// is reduced once. style_loss_forward(a, style_target(b)) equals style_loss_forward(a, b) bit for bit.
struct StyleTarget {
  ChannelStats stats;  // [N,C]
  Tensor mean_lo;      // [N,C]: the mean's low-order residual (the loss compares means in double-float)
};
StyleTarget style_target(const Tensor& b, float eps = kStatsEps);
Tensor style_loss_forward(const Tensor& a, const StyleTarget& b, float eps = kStatsEps);
Tensor style_loss_backward(const Tensor& a, const StyleTarget& b, float dloss, float eps = kStatsEps);  // d/da

// ---- reductions & elementwise ------------------------------------------------------------------
Tensor sum(const Tensor& x);                       // [1]
float sum_value(const Tensor& x);                  // sum, read back to host
void axpby(float a, const Tensor& x, float b, Tensor& y);  // y = a*x + b*y
// Whether the device's kernels flush denormal floats to zero: 1e-20 * 1e-20 through axpby (every program is
// built with -cl-denorms-are-zero, host/runtime.cpp says why; `stylerf devices` and stylerf.device() report it).
bool device_flushes_denormals();

// ---- Adam ------------------------------------------------------------------------------------
struct AdamConfig {
  float lr = 1e-3f, beta1 = 0.9f, beta2 = 0.999f, eps = 1e-8f;
};
// One step on param in place; m and v are the moment buffers (same shape, start at zero); step >= 1.
void adam_step(Tensor& param, const Tensor& grad, Tensor& m, Tensor& v, int step, const AdamConfig& cfg);

}  // namespace stylerf::nn
