// Double-precision CPU references shared by the conv-chain tests (VGG encoder, ConvStack decoders):
// one image [C,H,W], 3x3 / 1x1 stride-1 "same" convs with reflect or zero padding, ReLU, x2 nearest
// upsampling, 2x2 max pooling (odd sizes floor). Written from the definitions (PyTorch's Conv2d,
// ReflectionPad2d, Upsample(nearest), MaxPool2d).
#pragma once
#include <algorithm>
#include <vector>

namespace stylerf::testing {

struct RefTensor {  // [C,H,W]
  int C = 0, H = 0, W = 0;
  std::vector<double> v;
  double& at(int c, int y, int x) { return v[(size_t(c) * H + y) * W + x]; }
  double at(int c, int y, int x) const { return v[(size_t(c) * H + y) * W + x]; }
};

// ReflectionPad2d(1): -1 -> 1, n -> n-2 (n >= 2).
inline int reflect(int i, int n) { return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i); }

// k x k conv (k = 1 or 3), stride 1, same size; reflect or zero padding; w [Cout,Cin,k,k]. T: float for
// weights as stored, double for finite differences in the weights (no rounding of the perturbed value).
template <class T>
RefTensor ref_conv(const RefTensor& x, const std::vector<T>& w, const std::vector<T>& b, int cout, int k,
                   bool reflect_pad) {
  RefTensor y{cout, x.H, x.W, std::vector<double>(size_t(cout) * x.H * x.W)};
  const int r = k / 2;
  for (int o = 0; o < cout; ++o)
    for (int yy = 0; yy < x.H; ++yy)
      for (int xx = 0; xx < x.W; ++xx) {
        double s = b[o];
        for (int i = 0; i < x.C; ++i)
          for (int dy = -r; dy <= r; ++dy)
            for (int dx = -r; dx <= r; ++dx) {
              int sy = yy + dy, sx = xx + dx;
              if (reflect_pad) {
                sy = reflect(sy, x.H);
                sx = reflect(sx, x.W);
              } else if (sy < 0 || sy >= x.H || sx < 0 || sx >= x.W) {
                continue;
              }
              s += double(w[((size_t(o) * x.C + i) * k + dy + r) * k + dx + r]) * x.at(i, sy, sx);
            }
        y.at(o, yy, xx) = s;
      }
  return y;
}

inline void ref_relu(RefTensor& x) {
  for (double& v : x.v) v = std::max(v, 0.0);
}

inline RefTensor ref_upsample(const RefTensor& x) {
  RefTensor y{x.C, x.H * 2, x.W * 2, std::vector<double>(x.v.size() * 4)};
  for (int c = 0; c < x.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx) y.at(c, yy, xx) = x.at(c, yy / 2, xx / 2);
  return y;
}

// 2x2 max pooling, stride 2; odd sizes floor (the last row / column is in no window), as torch's MaxPool2d(2).
inline RefTensor ref_pool(const RefTensor& x) {
  RefTensor y{x.C, x.H / 2, x.W / 2, std::vector<double>(size_t(x.C) * (x.H / 2) * (x.W / 2))};
  for (int c = 0; c < x.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx)
        y.at(c, yy, xx) = std::max(std::max(x.at(c, 2 * yy, 2 * xx), x.at(c, 2 * yy, 2 * xx + 1)),
                                   std::max(x.at(c, 2 * yy + 1, 2 * xx), x.at(c, 2 * yy + 1, 2 * xx + 1)));
  return y;
}

// The stride-2 pool of x moved by (a, b) (a, b in {0,1}), windows past the last row / column repeating
// it: phase 2a + b of nn::maxpool2x2_phases_forward. H and W even.
inline RefTensor ref_pool_phase(const RefTensor& x, int a, int b) {
  RefTensor y{x.C, x.H / 2, x.W / 2, std::vector<double>(size_t(x.C) * (x.H / 2) * (x.W / 2))};
  for (int c = 0; c < x.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx) {
        const int y0 = 2 * yy + a, x0 = 2 * xx + b, y1 = std::min(y0 + 1, x.H - 1), x1 = std::min(x0 + 1, x.W - 1);
        y.at(c, yy, xx) = std::max(std::max(x.at(c, y0, x0), x.at(c, y0, x1)), std::max(x.at(c, y1, x0), x.at(c, y1, x1)));
      }
  return y;
}

// Four phase images (index 2a + b) side by side: y(c, 2i + a, 2j + b) = phase[2a + b](c, i, j).
inline RefTensor ref_interleave(const std::vector<RefTensor>& ph) {
  const RefTensor& p0 = ph[0];
  RefTensor y{p0.C, 2 * p0.H, 2 * p0.W, std::vector<double>(p0.v.size() * 4)};
  for (int c = 0; c < y.C; ++c)
    for (int yy = 0; yy < y.H; ++yy)
      for (int xx = 0; xx < y.W; ++xx) y.at(c, yy, xx) = ph[size_t((yy % 2) * 2 + xx % 2)].at(c, yy / 2, xx / 2);
  return y;
}

}  // namespace stylerf::testing
