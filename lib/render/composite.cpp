#include "lib/render/composite.hpp"

#include <algorithm>
#include <string>

#include "host/error.hpp"
#include "host/launch.hpp"
#include "lib/render/scan.hpp"

namespace stylerf::render {

using host::Error;
using host::launch_with_local;

// Work-group size for per-ray and per-row kernels. Left to PoCL, a ray count like 4096 becomes two groups
// of 2048 (one per core: the slower core, or one descheduled by other load, sets the time) and an odd
// count like a sample total becomes groups of a few items (per-group overhead); 64 gives the pthread
// device many groups to balance. Global sizes are rounded up; the kernels guard their index.
constexpr size_t kGroup = 64;

Kept keep_by_weight(const Samples& s, const Tensor& weights, float threshold) {
  const int R = static_cast<int>(check_ray_lists(s.ray_offset, s.ray_count, "keep_by_weight"));
  host::expect_shape(weights, {s.count}, host::DType::F32, "keep_by_weight", "weights");
  Kept k;
  k.ray_count = Tensor({R}, host::DType::I32, "kept counts");
  launch_with_local("render", "keep_count", "", {size_t(R)}, {kGroup}, weights, s.ray_offset, s.ray_count, R, threshold, k.ray_count);
  std::vector<int32_t> offsets;
  k.count = exclusive_scan(k.ray_count.to_host_i32(), offsets);
  k.ray_offset = Tensor::from_host(offsets, {R}, "kept offsets");
  k.index = Tensor({k.count}, host::DType::I32, "kept sample index");
  launch_with_local("render", "keep_write", "", {size_t(R)}, {kGroup}, weights, s.ray_offset, s.ray_count, R, threshold, k.ray_offset,
         k.index);
  return k;
}

// Rows of C 32-bit words: the kernels copy bits, so F32 and I32 payloads move unchanged.
static int64_t row_words(const Tensor& t, const char* op, const char* name) {
  host::expect_dtype(t, {host::DType::F32, host::DType::I32}, op, name);
  if (t.ndim() < 1) throw Error(std::string(op) + ": " + name + " has no rows");
  return t.ndim() == 1 ? 1 : t.numel() / std::max<int64_t>(t.dim(0), 1);
}

static void check_index(const Tensor& index, int64_t count, const char* op) {
  host::expect_dtype(index, host::DType::I32, op, "index");
  if (index.ndim() != 1 || index.numel() < count)
    throw Error(std::string(op) + ": index has shape " + host::shape_str(index.shape()) + ", expected at least " +
                std::to_string(count) + " entries");
}

Tensor gather_rows(const Tensor& src, const Tensor& index, int64_t count) {
  const int64_t C = row_words(src, "gather_rows", "source");
  check_index(index, count, "gather_rows");
  host::Shape shape = src.shape();
  shape[0] = count;
  Tensor out(shape, src.dtype(), "gathered rows");
  if (count == 0) return out;
  launch_with_local("render", "gather_rows", "", {size_t(count)}, {kGroup}, src, index, out, int(count), int(C));
  return out;
}

Tensor scatter_rows(const Tensor& rows, const Tensor& index, int64_t total) {
  const int64_t C = row_words(rows, "scatter_rows", "rows");
  const int64_t K = rows.dim(0);
  check_index(index, K, "scatter_rows");
  host::Shape shape = rows.shape();
  shape[0] = total;
  Tensor out = Tensor::zeros(shape, rows.dtype(), "scattered rows");
  if (K == 0) return out;
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
