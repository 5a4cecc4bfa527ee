#include "lib/render/background_shell.hpp"

#include <cstdint>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::render {

using host::DType;
using host::Error;
using host::launch_with_local;

ShellTaps background_shell_taps(const Tensor& origins, const Tensor& dirs, float radius, int height, int width) {
  const char* op = "background_shell_taps";
  if (!(radius > 0)) throw Error(std::string(op) + ": the shell's radius must be positive, got " + std::to_string(radius));
  if (height < 1 || width < 1)
    throw Error(std::string(op) + ": the map must have at least one texel, got " + std::to_string(width) + "x" +
                std::to_string(height));
  if (origins.ndim() != 2 || origins.dim(1) != 3)
    throw Error(std::string(op) + ": origins have shape " + host::shape_str(origins.shape()) + ", expected [R, 3]");
  const int64_t R = origins.dim(0);
  host::expect_shape(dirs, {R, 3}, DType::F32, op, "dirs");
  ShellTaps t;
  t.idx = Tensor::zeros({R, 4}, DType::I32, "shell taps");
  t.w = Tensor::zeros({R, 4}, "shell tap weights");
  if (R > 0)
    launch_with_local("background_shell", "background_shell_taps", "", {size_t(R)}, {64}, origins, dirs, int(R),
                      radius, height, width, t.idx, t.w);
  return t;
}

static int check_map(const Tensor& map, const ShellTaps& taps, int64_t R, const char* op) {
  if (taps.rays() != R)
    throw Error(std::string(op) + ": " + std::to_string(taps.rays()) + " taps for " + std::to_string(R) + " rays");
  if (map.ndim() != 2)
    throw Error(std::string(op) + ": the map has shape " + host::shape_str(map.shape()) + ", expected [texels, C]");
  return static_cast<int>(map.dim(1));
}

void background_shell_forward(Tensor& value, const Tensor& acc, const Tensor& map, const ShellTaps& taps) {
  const char* op = "background_shell_forward";
  const int64_t R = acc.numel();
  const int C = check_map(map, taps, R, op);
  host::expect_shape(value, {R, C}, DType::F32, op, "value");
  if (R > 0)
    launch_with_local("background_shell", "background_shell_forward", "", {size_t(C), size_t(R)}, host::Range(0),
                      value, acc, map, taps.idx, taps.w, int(R), C);
}

// The taps grouped by texel: the texels that any tap with a non-zero weight lands on, each with its list of
// (ray, weight), as device tensors for background_shell_dmap.
struct TexelLists {
  Tensor texel, offset, entry_ray, entry_w;
  int count = 0;
};
static TexelLists group_by_texel(const ShellTaps& taps, int64_t texels) {
  const std::vector<int32_t> idx = taps.idx.to_host_i32();
  const std::vector<float> w = taps.w.to_host();
  std::vector<int32_t> per_texel(size_t(texels) + 1, 0);
  for (size_t e = 0; e < idx.size(); ++e)
    if (w[e] != 0.0f) {
      if (idx[e] < 0 || idx[e] >= texels) throw Error("background_shell_backward: a tap on texel " + std::to_string(idx[e]) + " of " + std::to_string(texels));
      ++per_texel[size_t(idx[e])];
    }
  std::vector<int32_t> texel, offset{0};
  std::vector<int32_t> start(size_t(texels), 0);
  for (int64_t t = 0; t < texels; ++t)
    if (per_texel[size_t(t)] > 0) {
      start[size_t(t)] = offset.back();
      texel.push_back(int32_t(t));
      offset.push_back(offset.back() + per_texel[size_t(t)]);
    }
  std::vector<int32_t> entry_ray(size_t(offset.back()));
  std::vector<float> entry_w(size_t(offset.back()));
  for (size_t e = 0; e < idx.size(); ++e)
    if (w[e] != 0.0f) {
      const int32_t at = start[size_t(idx[e])]++;
      entry_ray[size_t(at)] = int32_t(e / 4);
      entry_w[size_t(at)] = w[e];
    }
  TexelLists l;
  l.count = int(texel.size());
  if (l.count == 0) return l;
  l.texel = Tensor::from_host(texel, {int64_t(texel.size())}, "shell texels");
  l.offset = Tensor::from_host(offset, {int64_t(offset.size())}, "shell texel offsets");
  l.entry_ray = Tensor::from_host(entry_ray, {int64_t(entry_ray.size())}, "shell tap rays");
  l.entry_w = Tensor::from_host(entry_w, {int64_t(entry_w.size())}, "shell tap weights");
  return l;
}

void background_shell_backward(const Tensor& dvalue, const Tensor& acc, const Tensor& map, const ShellTaps& taps,
                               Tensor* dacc, bool accumulate, Tensor* dmap) {
  const char* op = "background_shell_backward";
  const int64_t R = acc.numel();
  const int C = check_map(map, taps, R, op);
  host::expect_shape(dvalue, {R, C}, DType::F32, op, "dvalue");
  if (dacc) {
    if (!dacc->defined()) {
      *dacc = Tensor({R}, "dacc");
      accumulate = false;
    }
    host::expect_shape(*dacc, {R}, DType::F32, op, "dacc");
    if (R > 0)
      launch_with_local("background_shell", "background_shell_dacc", "", {size_t(R)}, {64}, dvalue, map, taps.idx,
                        taps.w, int(R), C, *dacc, int(accumulate));
  }
  if (dmap && R > 0) {
    host::expect_shape(*dmap, map.shape(), DType::F32, op, "dmap");
    const TexelLists l = group_by_texel(taps, map.dim(0));
    if (l.count > 0)
      launch_with_local("background_shell", "background_shell_dmap", "", {size_t(C), size_t(l.count)},
                        host::Range(0), dvalue, acc, l.texel, l.offset, l.entry_ray, l.entry_w, l.count, C, *dmap);
  }
}

}  // namespace stylerf::render
