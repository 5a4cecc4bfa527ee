#include "lib/render/composite_values.hpp"

#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"

namespace stylerf::render {

using host::Error;
using host::launch_with_local;

static const Tensor& absent() {
  static Tensor t = Tensor::zeros({1}, "absent input");
  return t;
}

constexpr int kVectorWidths[] = {16, 8, 4, 1};

// The widest float vector dividing C (the kernels' VW build option).
static int vector_width(int C) {
  for (int w : kVectorWidths)
    if (C % w == 0) return w;
  return 1;
}

static std::string vw_option(int vw) { return "-DVW=" + std::to_string(vw); }

std::vector<std::string> composite_value_build_options() {
  std::vector<std::string> out;
  for (int w : kVectorWidths) out.push_back(vw_option(w));
  return out;
}

static int check_values(const KeptLayout& l, const Tensor& w, const Tensor& values, const char* op) {
  host::expect_shape(w, {l.count}, host::DType::F32, op, "weights");
  host::expect_dtype(values, host::DType::F32, op, "values");
  if (values.ndim() != 2 || values.dim(0) != l.count)
    throw Error(std::string(op) + ": values have shape " + host::shape_str(values.shape()) + ", expected [" +
                std::to_string(l.count) + ", C]");
  if (values.dim(1) < 1) throw Error(std::string(op) + ": values have no channels");
  return static_cast<int>(values.dim(1));
}

// Both forms of the weighted sum: values read in order, or through rows (when given).
static CompositedValues values_forward(const KeptLayout& l, const Tensor& w, const Tensor& values, const Tensor* rows,
                                       const char* op) {
  const int C = static_cast<int>(values.dim(1));
  const int R = static_cast<int>(check_ray_lists(l.ray_offset, l.ray_count, op));
  const int vw = vector_width(C);
  CompositedValues out;
  out.value = Tensor({R, C}, "composited values");
  out.acc = Tensor({R}, "accumulated opacity (kept samples)");
  if (R == 0) return out;
  // Rays along dimension 0 in groups of 16 rays x all chunks (16 at C = 256): 256 work-items per group.
  const size_t chunks = size_t(C / vw);
  const size_t rays_per_group = chunks >= 16 ? 4 : 64;
  if (rows)
    launch_with_local("composite", "values_forward_indexed", vw_option(vw), {size_t(R), chunks},
                      {rays_per_group, chunks}, w, values, *rows, l.ray_offset, l.ray_count, R, C, out.value, out.acc);
  else
    launch_with_local("composite", "values_forward", vw_option(vw), {size_t(R), chunks}, {rays_per_group, chunks},
                      w, values, l.ray_offset, l.ray_count, R, C, out.value, out.acc);
  return out;
}

CompositedValues composite_values_forward(const KeptLayout& l, const Tensor& w, const Tensor& values) {
  check_values(l, w, values, "composite_values_forward");
  return values_forward(l, w, values, nullptr, "composite_values_forward");
}

CompositedValues composite_values_forward(const KeptLayout& l, const Tensor& w, const Tensor& values,
                                          const Tensor& rows) {
  const char* op = "composite_values_forward (indexed)";
  host::expect_shape(w, {l.count}, host::DType::F32, op, "weights");
  host::expect_shape(rows, {l.count}, host::DType::I32, op, "rows");
  host::expect_dtype(values, host::DType::F32, op, "values");
  if (values.ndim() != 2 || values.dim(1) < 1)
    throw Error(std::string(op) + ": values have shape " + host::shape_str(values.shape()) + ", expected [N, C]");
  return values_forward(l, w, values, &rows, op);
}

CompositeValuesGrads composite_values_backward(const KeptLayout& l, const Tensor& w, const Tensor& values,
                                               const Tensor& dvalue, const Tensor& dacc) {
  const int C = check_values(l, w, values, "composite_values_backward");
  const int R = static_cast<int>(l.rays()), K = static_cast<int>(l.count), vw = vector_width(C);
  // The backward kernels go from each kept entry to its ray: ray_index, not the per-ray offsets (with no
  // entries there is nothing to read, and callers leave it undefined).
  if (K > 0) host::expect_shape(l.ray_index, {K}, host::DType::I32, "composite_values_backward", "ray_index");
  if (dvalue.defined()) host::expect_shape(dvalue, {R, C}, host::DType::F32, "composite_values_backward", "dvalue");
  if (dacc.defined()) host::expect_shape(dacc, {R}, host::DType::F32, "composite_values_backward", "dacc");
  CompositeValuesGrads g;
  g.dw = Tensor({K}, "d kept weights");
  if (dvalue.defined()) {
    g.dvalues = Tensor({K, C}, "d kept values");
  } else {
    g.dvalues = Tensor::zeros({K, C}, "d kept values");
  }
  if (K == 0) return g;
  const size_t chunks = size_t(C / vw);
  if (dvalue.defined())
    launch_with_local("composite", "values_backward_dvalues", vw_option(vw), {size_t(K), chunks},
                      {size_t(chunks >= 16 ? 4 : 64), chunks}, w, l.ray_index, K, C, dvalue, g.dvalues);
  launch_with_local("composite", "values_backward_dweights", vw_option(vw), {size_t(K)}, {64}, values, l.ray_index,
                    K, C, dvalue.defined() ? dvalue : absent(), int(dvalue.defined()),
                    dacc.defined() ? dacc : absent(), int(dacc.defined()), g.dw);
  return g;
}

void background_forward(Tensor& value, const Tensor& acc, const Tensor& bg) {
  const int R = static_cast<int>(acc.numel());
  if (value.ndim() != 2 || value.dim(0) != R)
    throw Error("background_forward: value has shape " + host::shape_str(value.shape()) + ", expected [" +
                std::to_string(R) + ", C]");
  const int C = static_cast<int>(value.dim(1));
  host::expect_shape(bg, {C}, "background_forward", "background");
  launch_with_local("composite", "background_forward", "", {size_t(R)}, {64}, value, acc, bg, R, C);
}

void background_backward(const Tensor& dvalue, const Tensor& bg, Tensor& dacc, bool accumulate) {
  const int R = static_cast<int>(dvalue.dim(0)), C = static_cast<int>(dvalue.dim(1));
  host::expect_shape(bg, {C}, "background_backward", "background");
  if (!dacc.defined()) {
    dacc = Tensor({R}, "dacc");
    accumulate = false;
  }
  host::expect_shape(dacc, {R}, "background_backward", "dacc");
  launch_with_local("composite", "background_backward", "", {size_t(R)}, {64}, dvalue, bg, R, C, dacc,
                    int(accumulate));
}

}  // namespace stylerf::render
