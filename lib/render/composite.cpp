#include "lib/render/composite.hpp"

#include <algorithm>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/render/int_tensor.hpp"

namespace stylerf::render {

using host::Error;
using host::launch_with_local;

// Work-group size for per-ray and per-row kernels. Left to PoCL, a ray count like 4096 becomes two groups
// of 2048 (one per core: the slower core, or one descheduled by other load, sets the time) and an odd
// count like a sample total becomes groups of a few items (per-group overhead); 64 gives the pthread
// device many groups to balance. Global sizes are rounded up; the kernels guard their index.
constexpr size_t kGroup = 64;

Kept keep_by_weight(const Samples& s, const Tensor& weights, float threshold) {
  host::expect_shape(weights, {s.count}, "keep_by_weight", "weights");
  const int R = static_cast<int>(s.ray_count.numel());
  Kept k;
  k.ray_count = Tensor({R}, "kept counts");
  launch_with_local("render", "keep_count", "", {size_t(R)}, {kGroup}, weights, s.ray_offset, s.ray_count, R, threshold, k.ray_count);
  std::vector<int32_t> offsets;
  k.count = exclusive_scan(int_tensor_to_host(k.ray_count), offsets);
  k.ray_offset = int_tensor_from_host(offsets, "kept offsets");
  k.index = Tensor({k.count}, "kept sample index");
  launch_with_local("render", "keep_write", "", {size_t(R)}, {kGroup}, weights, s.ray_offset, s.ray_count, R, threshold, k.ray_offset,
         k.index);
  return k;
}

Tensor gather_rows(const Tensor& src, const Tensor& index, int64_t count) {
  if (src.ndim() < 1) throw Error("gather_rows: source has no rows");
  const int64_t C = src.ndim() == 1 ? 1 : src.numel() / std::max<int64_t>(src.dim(0), 1);
  host::Shape shape = src.shape();
  shape[0] = count;
  Tensor out(shape, "gathered rows");
  launch_with_local("render", "gather_rows", "", {size_t(count)}, {kGroup}, src, index, out, int(count), int(C));
  return out;
}

Tensor scatter_rows(const Tensor& rows, const Tensor& index, int64_t total) {
  const int64_t K = rows.dim(0);
  const int64_t C = rows.ndim() == 1 ? 1 : rows.numel() / std::max<int64_t>(K, 1);
  host::Shape shape = rows.shape();
  shape[0] = total;
  Tensor out = Tensor::zeros(shape, "scattered rows");
  launch_with_local("render", "scatter_rows", "", {size_t(K)}, {kGroup}, rows, index, out, int(K), int(C));
  return out;
}

Samples compact(const Samples& s, const Kept& k) {
  Samples out;
  out.count = k.count;
  out.positions = gather_rows(s.positions, k.index, k.count);
  out.t = gather_rows(s.t, k.index, k.count);
  out.deltas = gather_rows(s.deltas, k.index, k.count);
  out.ray_index = gather_rows(s.ray_index, k.index, k.count);
  out.ray_offset = k.ray_offset;
  out.ray_count = k.ray_count;
  return out;
}

}  // namespace stylerf::render
