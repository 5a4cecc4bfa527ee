// Tensor element types (host/dtype.hpp): F32, I32 and U8 round trips, dtype kept by reshape/clone/copy,
// errors that name the tensor when it is read or written as the wrong type, zero-size tensors, and the ops
// that take index tensors (gather_rows/scatter_rows, keep_by_weight, compositing, gather_targets, march's
// alpha mask) refusing the wrong dtype instead of reading its bits.
#include <doctest/doctest.h>

#include <climits>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "host/tensor.hpp"
#include "lib/features/target_gather.hpp"
#include "lib/field/alpha_mask.hpp"
#include "lib/render/composite.hpp"
#include "lib/render/composite_values.hpp"
#include "lib/render/ray_march.hpp"
#include "lib/render/weights.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::DType;
using host::Tensor;

namespace {

// Checks that f() throws a host::Error whose message contains every one of `parts`.
void expect_error_with(const std::function<void()>& f, const std::vector<std::string>& parts) {
  const std::string msg = testing::error_of(f);
  CAPTURE(msg);
  REQUIRE(!msg.empty());
  for (const auto& p : parts) {
    CAPTURE(p);
    CHECK(msg.find(p) != std::string::npos);
  }
}

// Values a float cannot hold (above 2^24, odd) and the int32 extremes: a float round trip anywhere on the
// way would change them.
std::vector<int32_t> hard_ints() {
  return {0, -1, 1, 16777217, -16777217, 2147483647, INT_MIN, 123456789, -987654321, 33554431};
}

// A sample list of R rays with the given counts, offsets and ray index as I32, t and deltas as F32.
render::Samples samples_of(const std::vector<int32_t>& counts) {
  render::Samples s;
  std::vector<int32_t> off, ray;
  for (size_t r = 0; r < counts.size(); ++r) {
    off.push_back(int32_t(s.count));
    s.count += counts[r];
    ray.insert(ray.end(), size_t(counts[r]), int32_t(r));
  }
  const int64_t R = int64_t(counts.size());
  s.ray_count = Tensor::from_host(counts, {R}, "test ray counts");
  s.ray_offset = Tensor::from_host(off, {R}, "test ray offsets");
  s.ray_index = Tensor::from_host(ray, {s.count}, "test ray index");
  s.t = Tensor::zeros({s.count}, "test t");
  s.deltas = Tensor::full({s.count}, 0.1f, "test deltas");
  s.positions = Tensor::zeros({s.count, 3}, "test positions");
  return s;
}

}  // namespace

TEST_CASE("each dtype round-trips exactly and reports its element size") {
  const std::vector<float> f = testing::random_normal(37, 5);
  const Tensor tf = Tensor::from_host(f, {37}, "floats");
  CHECK(tf.dtype() == DType::F32);
  CHECK(tf.element_size() == 4);
  CHECK(tf.bytes() == 37 * 4);
  CHECK(tf.to_host() == f);

  const std::vector<int32_t> i = hard_ints();
  const Tensor ti = Tensor::from_host(i, {2, 5}, "ints");
  CHECK(ti.dtype() == DType::I32);
  CHECK(ti.element_size() == 4);
  CHECK(ti.bytes() == 40);
  CHECK(ti.name() == "ints");
  CHECK(ti.to_host_i32() == i);

  std::vector<uint8_t> b(300);
  for (size_t k = 0; k < b.size(); ++k) b[k] = uint8_t(k * 7);
  const Tensor tb = Tensor::from_host(b, {3, 100}, "bytes");
  CHECK(tb.dtype() == DType::U8);
  CHECK(tb.element_size() == 1);
  CHECK(tb.bytes() == 300);
  CHECK(tb.to_host_u8() == b);

  // upload overwrites in place, per dtype.
  Tensor tu(host::Shape{4}, DType::I32, "uploaded");
  tu.upload(std::vector<int32_t>{-5, 6, INT_MAX, 16777219});
  CHECK(tu.to_host_i32() == std::vector<int32_t>{-5, 6, INT_MAX, 16777219});

  // A braced list still means floats: the float API is unchanged for existing callers.
  const Tensor braced = Tensor::from_host({1, 2, 3}, {3});
  CHECK(braced.dtype() == DType::F32);
  CHECK(braced.to_host() == std::vector<float>{1, 2, 3});
  CHECK(Tensor(host::Shape{2}).dtype() == DType::F32);
}

TEST_CASE("zeros and zero() clear every dtype") {
  for (DType d : {DType::F32, DType::I32, DType::U8}) {
    CAPTURE(host::dtype_name(d));
    const Tensor z = Tensor::zeros({5, 3}, d, "zeros");
    CHECK(z.dtype() == d);
    CHECK(z.bytes() == 15 * host::dtype_size(d));
    if (d == DType::F32) CHECK(z.to_host() == std::vector<float>(15, 0.0f));
    if (d == DType::I32) CHECK(z.to_host_i32() == std::vector<int32_t>(15, 0));
    if (d == DType::U8) CHECK(z.to_host_u8() == std::vector<uint8_t>(15, 0));
  }
  Tensor ti = Tensor::from_host(std::vector<int32_t>{-1, -1, 7}, {3}, "to clear");
  ti.zero();
  CHECK(ti.to_host_i32() == std::vector<int32_t>{0, 0, 0});
  Tensor tb = Tensor::from_host(std::vector<uint8_t>{255, 1, 9}, {3}, "bytes to clear");
  tb.zero();
  CHECK(tb.to_host_u8() == std::vector<uint8_t>{0, 0, 0});
}

TEST_CASE("reading or writing as the wrong dtype is an error naming the tensor") {
  Tensor ti = Tensor::from_host(std::vector<int32_t>{1, 2, 3}, {3}, "ray offsets");
  Tensor tf = Tensor::from_host(std::vector<float>{1, 2, 3}, {3}, "sample t");
  Tensor tb = Tensor::from_host(std::vector<uint8_t>{1, 2, 3}, {3}, "mask bytes");
  expect_error_with([&] { ti.to_host(); }, {"to_host", "'ray offsets'", "i32", "f32"});
  expect_error_with([&] { tf.to_host_i32(); }, {"to_host_i32", "'sample t'", "f32", "i32"});
  expect_error_with([&] { ti.to_host_u8(); }, {"to_host_u8", "'ray offsets'", "i32", "u8"});
  expect_error_with([&] { tb.to_host_i32(); }, {"to_host_i32", "'mask bytes'", "u8"});
  expect_error_with([&] { ti.upload(std::vector<float>{1, 2, 3}); }, {"upload", "'ray offsets'", "i32"});
  expect_error_with([&] { tb.upload(std::vector<int32_t>{1, 2, 3}); }, {"upload", "'mask bytes'", "u8"});
  expect_error_with([&] { tf.upload(std::vector<uint8_t>{1, 2, 3}); }, {"upload", "'sample t'", "f32"});
  expect_error_with([&] { ti.fill(1.0f); }, {"fill", "'ray offsets'", "i32"});
  // Same dtype, wrong count: still an error that names it.
  expect_error_with([&] { ti.upload(std::vector<int32_t>{1, 2}); }, {"upload of 2 values", "'ray offsets'"});
  // copy_from between dtypes would reinterpret bits (or copy the wrong number of bytes).
  Tensor same_size_float(host::Shape{3}, "destination");
  expect_error_with([&] { same_size_float.copy_from(ti); }, {"copy_from", "'ray offsets'", "'destination'"});
  Tensor other_int(host::Shape{3}, DType::I32, "int destination");
  other_int.copy_from(ti);
  CHECK(other_int.to_host_i32() == std::vector<int32_t>{1, 2, 3});
  // expect_dtype names the op, the argument and the tensor.
  expect_error_with([&] { host::expect_dtype(tf, DType::I32, "some_op", "index"); },
                    {"some_op", "index", "'sample t'", "has dtype f32, expected i32"});
  expect_error_with([&] { host::expect_dtype(tb, {DType::F32, DType::I32}, "some_op", "src"); },
                    {"expected f32 or i32"});
  expect_error_with([&] { host::expect_dtype(Tensor(), DType::I32, "some_op", "index"); }, {"some_op: index is undefined"});
  host::expect_dtype(ti, {DType::F32, DType::I32}, "some_op", "src");  // allowed: no throw
}

TEST_CASE("zero-size tensors of every dtype") {
  for (DType d : {DType::F32, DType::I32, DType::U8}) {
    CAPTURE(host::dtype_name(d));
    for (const host::Shape& shape : {host::Shape{0}, host::Shape{0, 3}}) {
      const Tensor z = Tensor::zeros(shape, d, "empty");
      CHECK(z.defined());
      CHECK(z.numel() == 0);
      CHECK(z.bytes() == 0);
      const Tensor c = z.clone();
      CHECK(c.dtype() == d);
      CHECK(c.shape() == shape);
      CHECK(z.reshape({0, 5}).dtype() == d);
    }
  }
  CHECK(Tensor::from_host(std::vector<int32_t>{}, {0}, "no ints").to_host_i32().empty());
  CHECK(Tensor::from_host(std::vector<uint8_t>{}, {0}, "no bytes").to_host_u8().empty());
  CHECK(Tensor::from_host(std::vector<float>{}, {0}, "no floats").to_host().empty());
}

TEST_CASE("reshape and clone keep the dtype; reshape shares the buffer, clone copies it") {
  const std::vector<int32_t> v = {1, -2, 3, -4, 16777217, INT_MIN};
  Tensor t = Tensor::from_host(v, {2, 3}, "index pairs");
  const Tensor r = t.reshape({6});
  CHECK(r.dtype() == DType::I32);
  CHECK(r.same_buffer(t));
  CHECK(r.name() == "index pairs");
  CHECK(r.to_host_i32() == v);
  const Tensor c = t.clone();
  CHECK(c.dtype() == DType::I32);
  CHECK(!c.same_buffer(t));
  CHECK(c.name() == "index pairs");
  t.zero();
  CHECK(c.to_host_i32() == v);
  const Tensor b = Tensor::from_host(std::vector<uint8_t>{0, 1, 1, 0}, {2, 2}, "bits").clone().reshape({4});
  CHECK(b.dtype() == DType::U8);
  CHECK(b.to_host_u8() == std::vector<uint8_t>{0, 1, 1, 0});
}

TEST_CASE("gather_rows and scatter_rows move I32 rows bit-exactly, negatives and values above 2^24 included") {
  const std::vector<int32_t> hard = hard_ints();
  // The test means something: a float round trip changes some of these values.
  int float_breaks = 0;
  for (int32_t x : hard) float_breaks += double(float(x)) != double(x);
  REQUIRE(float_breaks >= 4);
  const int S = int(hard.size()) / 2;  // [S, 2] rows
  const Tensor src = Tensor::from_host(hard, {S, 2}, "int rows");
  const std::vector<int32_t> idx = {4, 0, 2, 2, 1};
  const Tensor index = Tensor::from_host(idx, {int64_t(idx.size())}, "row index");
  const Tensor g = render::gather_rows(src, index, int64_t(idx.size()));
  CHECK(g.dtype() == DType::I32);
  CHECK(g.shape() == host::Shape{int64_t(idx.size()), 2});
  const std::vector<int32_t> got = g.to_host_i32();
  for (size_t k = 0; k < idx.size(); ++k)
    for (int c = 0; c < 2; ++c) CHECK(got[2 * k + c] == hard[2 * size_t(idx[k]) + c]);
  // 1-D I32 source (a ray index), as compact() gathers it.
  const Tensor flat = Tensor::from_host(hard, {int64_t(hard.size())}, "int list");
  const Tensor g1 = render::gather_rows(flat, Tensor::from_host(std::vector<int32_t>{9, 6, 3}, {3}, "i"), 3);
  CHECK(g1.to_host_i32() == std::vector<int32_t>{hard[9], hard[6], hard[3]});
  // scatter_rows: the rows back at their indices, zero elsewhere, still I32.
  const std::vector<int32_t> sidx = {3, 0, 4};
  const Tensor rows = Tensor::from_host(std::vector<int32_t>{INT_MIN, 16777217, -7, 8, INT_MAX, -16777217}, {3, 2}, "r");
  const Tensor sc = render::scatter_rows(rows, Tensor::from_host(sidx, {3}, "scatter index"), 6);
  CHECK(sc.dtype() == DType::I32);
  CHECK(sc.to_host_i32() ==
        std::vector<int32_t>{-7, 8, 0, 0, 0, 0, INT_MIN, 16777217, INT_MAX, -16777217, 0, 0});
  // F32 rows come back as F32.
  const Tensor fr = render::gather_rows(Tensor::from_host({1.5f, -2.5f, 3.5f}, {3}),
                                        Tensor::from_host(std::vector<int32_t>{1, 0}, {2}, "float row index"), 2);
  CHECK(fr.dtype() == DType::F32);
  CHECK(fr.to_host() == std::vector<float>{-2.5f, 1.5f});
}

TEST_CASE("ops that take index tensors refuse the wrong dtype with a clear error") {
  const std::vector<int32_t> counts = {2, 0, 3};
  render::Samples s = samples_of(counts);
  const Tensor w = Tensor::full({s.count}, 0.5f, "weights");

  // gather_rows / scatter_rows: index must be I32; the payload 32-bit (F32 or I32).
  const Tensor float_index = Tensor::from_host({0, 1}, {2}, "float index");
  expect_error_with([&] { render::gather_rows(s.positions, float_index, 2); },
                    {"gather_rows", "index", "'float index'", "expected i32"});
  const Tensor bytes = Tensor::zeros({5}, DType::U8, "byte rows");
  expect_error_with([&] { render::gather_rows(bytes, s.ray_index, 2); },
                    {"gather_rows", "'byte rows'", "expected f32 or i32"});
  expect_error_with([&] { render::scatter_rows(w, float_index, 5); }, {"scatter_rows", "'float index'"});

  // keep_by_weight: the per-ray lists are I32, the weights F32.
  render::Samples bad = s;
  bad.ray_count = Tensor::from_host({2, 0, 3}, {3}, "float counts");
  expect_error_with([&] { render::keep_by_weight(bad, w); },
                    {"keep_by_weight", "ray_count", "'float counts'", "has dtype f32, expected i32"});
  bad = s;
  bad.ray_offset = Tensor::zeros({3}, "float offsets");
  expect_error_with([&] { render::keep_by_weight(bad, w); }, {"keep_by_weight", "ray_offset", "'float offsets'"});
  const Tensor int_weights = Tensor::zeros({s.count}, DType::I32, "int weights");
  expect_error_with([&] { render::keep_by_weight(s, int_weights); }, {"keep_by_weight", "weights", "'int weights'"});
  // The same lists with the right dtypes work.
  const render::Kept k = render::keep_by_weight(s, w);
  CHECK(k.count == 5);
  CHECK(k.index.dtype() == DType::I32);
  CHECK(k.ray_offset.to_host_i32() == std::vector<int32_t>{0, 2, 2});

  // Compositing: weights_forward and composite_values read the per-ray lists; its backward the ray index.
  expect_error_with([&] { render::weights_forward(bad, w); }, {"weights_forward", "ray_offset"});
  render::KeptLayout l;
  l.count = s.count;
  l.ray_offset = s.ray_offset;
  l.ray_count = s.ray_count;
  l.ray_index = Tensor::zeros({s.count}, "float ray index");
  const Tensor values = Tensor::zeros({s.count, 4}, "values");
  const Tensor dvalue = Tensor::zeros({3, 4}, "dvalue");
  expect_error_with([&] { render::composite_values_backward(l, w, values, dvalue, Tensor()); },
                    {"composite_values_backward", "ray_index", "'float ray index'"});
  l.ray_count = Tensor::zeros({3}, "float counts");
  expect_error_with([&] { render::composite_values_forward(l, w, values); },
                    {"composite_values_forward", "ray_count", "'float counts'"});

  // gather_targets: view_index I32.
  const Tensor maps = Tensor::zeros({2, 3, 3, 8}, "maps");
  const Tensor xy = Tensor::full({2, 2}, 1.0f, "xy");
  expect_error_with([&] { features::gather_targets(maps, Tensor::from_host({0, 1}, {2}, "float views"), xy); },
                    {"gather_targets", "view_index", "'float views'", "expected i32"});
  expect_error_with(
      [&] { features::gather_targets(maps, Tensor::from_host(std::vector<int32_t>{0, 1}, {2}, "views"),
                                     Tensor::from_host(std::vector<int32_t>{1, 1, 2, 2}, {2, 2}, "int xy")); },
      {"gather_targets", "pixel_xy", "'int xy'"});

  // march: the alpha mask is U8 [mz, my, mx].
  render::MarchConfig cfg;
  cfg.step = 0.1f;
  const Tensor o = Tensor::from_host({0, 0, -3}, {1, 3}), d = Tensor::from_host({0, 0, 1}, {1, 3});
  field::AlphaMask mask;
  mask.res = {2, 3, 4};
  mask.voxels = Tensor::full({4, 3, 2}, 1.0f, "float mask");
  expect_error_with([&] { render::march(o, d, cfg, &mask); }, {"march", "alpha mask", "'float mask'", "expected u8"});
  mask.voxels = Tensor::zeros({2, 3, 4}, DType::U8, "transposed mask");
  expect_error_with([&] { render::march(o, d, cfg, &mask); }, {"march", "[2, 3, 4]", "expected [4, 3, 2]"});
  mask.voxels = Tensor::zeros({4, 3, 2}, DType::U8, "empty mask");
  CHECK(render::march(o, d, cfg, &mask).count == 0);  // every voxel empty: nothing kept
  CHECK(render::march(o, d, cfg, nullptr).count > 0);
}
