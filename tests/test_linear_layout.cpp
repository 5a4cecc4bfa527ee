// nn::linear and the layout ops [R,C] <-> [1,C,H,W]:
//  - forward against double-precision CPU references;
//  - backward (dx, dW, db; the layout ops' transposes) against central differences of those references;
//  - the module form accumulates (two backward calls give twice one), the ops form overwrites;
//  - hard shapes: tiles cut by the matrix edge, 1x1 images, one row, columns not a multiple of 8, more
//    rows than the bias-gradient block; bad inputs (N = 0, mismatched shapes) give errors naming the op.
#include <doctest/doctest.h>

#include <array>

#include <string>
#include <vector>

#include "host/tensor.hpp"
#include "lib/nn/layout.hpp"
#include "lib/nn/linear.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;
using testing::to_double;

namespace {

// ---- layout references -------------------------------------------------------------------------------
// rows [H*W, C] -> image [C, H*W] (row-major pixels), in double.
std::vector<double> ref_rows_to_image(const std::vector<double>& rows, int hw, int C) {
  std::vector<double> img(rows.size());
  for (int p = 0; p < hw; ++p)
    for (int c = 0; c < C; ++c) img[size_t(c) * hw + p] = rows[size_t(p) * C + c];
  return img;
}

std::vector<double> ref_image_to_rows(const std::vector<double>& img, int hw, int C) {
  std::vector<double> rows(img.size());
  for (int p = 0; p < hw; ++p)
    for (int c = 0; c < C; ++c) rows[size_t(p) * C + c] = img[size_t(c) * hw + p];
  return rows;
}

struct LayoutCase {
  int H, W, C;
};

std::string name(const LayoutCase& c) {
  return std::to_string(c.H) + "x" + std::to_string(c.W) + " C=" + std::to_string(c.C);
}

// Shapes: whole 16x16 tiles only (C = 256 at 16x16, StyleRF's channel count); edges in both directions;
// fewer than one tile; a single pixel; a single channel.
const LayoutCase kLayoutCases[] = {{16, 16, 256}, {17, 9, 33}, {5, 7, 3}, {1, 1, 1}, {1, 1, 40}, {6, 11, 1},
                                   {32, 24, 32}};

// ---- linear reference ----------------------------------------------------------------------------------
// y[N,out] = x[N,in] W[in,out] + b, in double.
std::vector<double> ref_linear(const std::vector<double>& x, const std::vector<double>& w, const std::vector<double>& b,
                               int n, int in, int out) {
  std::vector<double> y(size_t(n) * out);
  for (int r = 0; r < n; ++r)
    for (int j = 0; j < out; ++j) {
      double s = b.empty() ? 0.0 : b[j];
      for (int k = 0; k < in; ++k) s += x[size_t(r) * in + k] * w[size_t(k) * out + j];
      y[size_t(r) * out + j] = s;
    }
  return y;
}

struct LinearCase {
  int n, in, out;
  bool bias;
};

std::string name(const LinearCase& c) {
  return "N=" + std::to_string(c.n) + " in=" + std::to_string(c.in) + " out=" + std::to_string(c.out) +
         (c.bias ? " bias" : "");
}

struct LinearData {
  std::vector<float> x, w, b, dy;
};

LinearData make_data(const LinearCase& c, uint64_t seed) {
  return {testing::random_normal(size_t(c.n) * c.in, seed), testing::random_normal(size_t(c.in) * c.out, seed + 1, 0.3f),
          testing::random_normal(size_t(c.out), seed + 2), testing::random_normal(size_t(c.n) * c.out, seed + 3)};
}

// Up to `count` evenly spread indices of a vector of size n (all when n <= count).
std::vector<size_t> probe(size_t n, size_t count) {
  std::vector<size_t> idx;
  const size_t stride = std::max<size_t>(1, n / count);
  for (size_t i = 0; i < n; i += stride) idx.push_back(i);
  if (idx.back() != n - 1) idx.push_back(n - 1);
  return idx;
}

std::vector<float> pick(const std::vector<float>& v, const std::vector<size_t>& idx) {
  std::vector<float> out;
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

}  // namespace

// ---- layout --------------------------------------------------------------------------------------------
TEST_CASE("layout: rows_to_image and image_to_rows match the reference exactly and invert each other") {
  uint64_t seed = 100;
  for (const LayoutCase& c : kLayoutCases) {
    const int hw = c.H * c.W;
    auto rows = testing::random_normal(size_t(hw) * c.C, seed++);
    Tensor img = nn::rows_to_image(Tensor::from_host(rows, {hw, c.C}), c.H, c.W);
    CHECK(img.shape() == host::Shape{1, c.C, c.H, c.W});
    // A transpose moves values: exact (atol 0 would reject any rounding, rtol 0 any relative change).
    check_close(img.to_host(), ref_rows_to_image(to_double(rows), hw, c.C), 0.0, 1e-30, "rows_to_image " + name(c));

    auto im = testing::random_normal(size_t(hw) * c.C, seed++);
    Tensor r = nn::image_to_rows(Tensor::from_host(im, {1, c.C, c.H, c.W}));
    CHECK(r.shape() == host::Shape{hw, c.C});
    check_close(r.to_host(), ref_image_to_rows(to_double(im), hw, c.C), 0.0, 1e-30, "image_to_rows " + name(c));

    CHECK(nn::image_to_rows(img).to_host() == rows);
  }
}

TEST_CASE("layout: backward of each is the other, against central differences of the reference") {
  uint64_t seed = 200;
  for (const LayoutCase& c : kLayoutCases) {
    const int hw = c.H * c.W;
    const size_t n = size_t(hw) * c.C;
    const auto x = to_double(testing::random_normal(n, seed++));
    const auto g = testing::random_normal(n, seed++);
    const auto gd = to_double(g);
    const auto idx = probe(n, 300);
    // L(rows) = <g, rows_to_image(rows)>: linear, so the differences are exact up to double rounding.
    auto fd = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(gd, ref_rows_to_image(v, hw, c.C)); }, x, idx, 1e-2);
    auto got = nn::rows_to_image_backward(Tensor::from_host(g, {1, c.C, c.H, c.W}));
    CHECK(got.shape() == host::Shape{hw, c.C});
    // Tolerance: the differences are exact up to the rounding of a double dot product of up to 65536
    // terms (~1e-16 * 65536 / h relative); a misplaced element is an O(1) error.
    check_close(pick(got.to_host(), idx), fd, 1e-9, 1e-9, "rows_to_image_backward " + name(c));

    fd = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(gd, ref_image_to_rows(v, hw, c.C)); }, x, idx, 1e-2);
    got = nn::image_to_rows_backward(Tensor::from_host(g, {hw, c.C}), c.H, c.W);
    CHECK(got.shape() == host::Shape{1, c.C, c.H, c.W});
    check_close(pick(got.to_host(), idx), fd, 1e-9, 1e-9, "image_to_rows_backward " + name(c));
  }
}

TEST_CASE("layout: bad shapes give errors naming the op") {
  Tensor rows = Tensor::zeros({12, 4});
  testing::expect_error([&] { nn::rows_to_image(rows, 3, 5); }, "rows_to_image: rows [12, 4] has 12 rows but the image is 3x5");
  testing::expect_error([&] { nn::rows_to_image(rows, 0, 12); }, "rows_to_image: image size must be at least 1x1");
  testing::expect_error([&] { nn::rows_to_image(Tensor::zeros({12}), 3, 4); }, "rows_to_image: rows must be [R, C]");
  testing::expect_error([&] { nn::rows_to_image(Tensor(), 3, 4); }, "rows_to_image: rows is undefined");
  testing::expect_error([&] { nn::image_to_rows(Tensor::zeros({2, 4, 3, 4})); }, "image_to_rows: image must be a non-empty [1, C, H, W]");
  testing::expect_error([&] { nn::image_to_rows_backward(rows, 4, 4); }, "image_to_rows_backward: rows [12, 4] has 12 rows");
  testing::expect_error([&] { nn::rows_to_image_backward(Tensor::zeros({4, 12})); }, "rows_to_image_backward: dimage must be");
}

TEST_CASE("layout: column blocks are concatenated and taken exactly; taking's backward places the gradient, zero elsewhere") {
  // Widths not a multiple of the kernel's 8 columns a work-item, one row, and a renderer call's rows.
  for (const auto& [R, A, B] : std::vector<std::array<int, 3>>{{1, 1, 1}, {7, 32, 13}, {4096, 32, 144}, {33, 9, 20}}) {
    CAPTURE(R);
    CAPTURE(A);
    CAPTURE(B);
    const auto a = testing::random_normal(size_t(R) * A, 300), b = testing::random_normal(size_t(R) * B, 301);
    const Tensor ab = nn::concat_columns(Tensor::from_host(a, {R, A}), Tensor::from_host(b, {R, B}));
    REQUIRE(ab.shape() == host::Shape{R, A + B});
    const auto v = ab.to_host();
    bool exact = true;
    for (int r = 0; r < R; ++r) {
      for (int j = 0; j < A; ++j) exact &= v[size_t(r) * (A + B) + j] == a[size_t(r) * A + j];
      for (int j = 0; j < B; ++j) exact &= v[size_t(r) * (A + B) + A + j] == b[size_t(r) * B + j];
    }
    CHECK(exact);
    CHECK(nn::take_columns(ab, 0, A).to_host() == a);
    CHECK(nn::take_columns(ab, A, B).to_host() == b);
    // take_columns is linear: <g, take(x)> = <place(g), x>, exact for a gradient that is the placed g.
    const Tensor dx = nn::take_columns_backward(Tensor::from_host(b, {R, B}), A, A + B);
    REQUIRE(dx.shape() == host::Shape{R, A + B});
    const auto d = dx.to_host();
    bool placed = true;
    for (int r = 0; r < R; ++r) {
      for (int j = 0; j < A; ++j) placed &= d[size_t(r) * (A + B) + j] == 0.0f;
      for (int j = 0; j < B; ++j) placed &= d[size_t(r) * (A + B) + A + j] == b[size_t(r) * B + j];
    }
    CHECK(placed);
  }
}

TEST_CASE("layout: column blocks out of range or of mismatched rows give errors naming the op") {
  const Tensor x = Tensor::zeros({4, 10});
  testing::expect_error([&] { nn::take_columns(x, 6, 5); }, "take_columns: columns [6, 11) of [4, 10]");
  testing::expect_error([&] { nn::take_columns(x, -1, 2); }, "take_columns: columns [-1, 1)");
  testing::expect_error([&] { nn::concat_columns(x, Tensor::zeros({3, 2})); }, "concat_columns: a [4, 10] and b [3, 2] differ in rows");
  testing::expect_error([&] { nn::concat_columns(Tensor::zeros({4}), x); }, "concat_columns: a must be [R, C]");
  testing::expect_error([&] { nn::take_columns_backward(x, 2, 11); }, "take_columns_backward: [4, 10] at column 2 does not fit 11 columns");
}

// ---- linear ----------------------------------------------------------------------------------------------
// Shapes: tiny; one row (the DST's covariance -> T map is 1 x 1024 -> 1024); the feature basis matrix
// (rank 144 -> 256 channels) on a batch of rays; columns not a multiple of 8 with more rows than the
// bias-gradient block of 64; enough rows for the bias gradient's two stages (three parts of ~1667 rows,
// lib/nn/columns.cpp).
const LinearCase kLinearCases[] = {{5, 7, 3, true},    {1, 1024, 1024, true}, {100, 144, 256, false},
                                   {200, 9, 13, true}, {3, 2, 1, true},       {5000, 9, 13, true}};

TEST_CASE("linear: forward matches the double reference") {
  uint64_t seed = 300;
  for (const LinearCase& c : kLinearCases) {
    LinearData d = make_data(c, seed += 10);
    Tensor b = c.bias ? Tensor::from_host(d.b, {c.out}) : Tensor();
    Tensor y = nn::linear_forward(Tensor::from_host(d.x, {c.n, c.in}), Tensor::from_host(d.w, {c.in, c.out}), b);
    CHECK(y.shape() == host::Shape{c.n, c.out});
    auto want = ref_linear(to_double(d.x), to_double(d.w), c.bias ? to_double(d.b) : std::vector<double>{}, c.n, c.in,
                           c.out);
    // Float sums of `in` products of size ~0.3 (std of a term): errors ~ sqrt(in) * 1e-7 * |terms|; 1e-4
    // absolute and relative leaves margin at in = 1024 while a wrong index (an O(1) error) fails.
    check_close(y.to_host(), want, 1e-4, 1e-4, "linear_forward " + name(c));
  }
}

TEST_CASE("linear: dx, dW, db against central differences of the reference") {
  uint64_t seed = 400;
  for (const LinearCase& c : kLinearCases) {
    LinearData d = make_data(c, seed += 10);
    const auto xd = to_double(d.x), wd = to_double(d.w), bd = to_double(d.b), gd = to_double(d.dy);
    const std::vector<double> no_bias;
    Tensor x = Tensor::from_host(d.x, {c.n, c.in}), w = Tensor::from_host(d.w, {c.in, c.out});
    nn::LinearGrads g = nn::linear_backward(x, w, Tensor::from_host(d.dy, {c.n, c.out}), true, true, true);
    REQUIRE(g.dx.defined());
    REQUIRE(g.dw.defined());
    REQUIRE(g.db.defined());
    // L = <dy, x W + b> is linear in each argument: central differences are exact up to double rounding.
    // Tolerance 1e-4: the float GEMM sums up to 1024 (dx) or 200 (dW, db) terms of O(1). 60 probes per
    // tensor: each difference re-runs the whole reference (3.7M products for the largest case).
    auto ix = probe(xd.size(), 60), iw = probe(wd.size(), 60), ib = probe(bd.size(), 60);
    auto fx = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(gd, ref_linear(v, wd, no_bias, c.n, c.in, c.out)); },
        xd, ix, 1e-2);
    auto fw = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(gd, ref_linear(xd, v, no_bias, c.n, c.in, c.out)); },
        wd, iw, 1e-2);
    auto fb = testing::finite_difference_at(
        [&](const std::vector<double>& v) { return testing::dot(gd, ref_linear(xd, wd, v, c.n, c.in, c.out)); }, bd,
        ib, 1e-2);
    check_close(pick(g.dx.to_host(), ix), fx, 1e-4, 1e-4, "linear dx " + name(c));
    check_close(pick(g.dw.to_host(), iw), fw, 1e-4, 1e-4, "linear dW " + name(c));
    check_close(pick(g.db.to_host(), ib), fb, 1e-4, 1e-4, "linear db " + name(c));

    // Only what is asked for is computed.
    nn::LinearGrads only_dx = nn::linear_backward(x, w, Tensor::from_host(d.dy, {c.n, c.out}), true, false, false);
    CHECK(only_dx.dx.defined());
    CHECK(!only_dx.dw.defined());
    CHECK(!only_dx.db.defined());
    CHECK(only_dx.dx.to_host() == g.dx.to_host());
  }
}

TEST_CASE("linear: the module form accumulates into Param grads; two backward calls give twice one") {
  // 5000 rows: the bias gradient's two stages accumulate too.
  for (const LinearCase c : {LinearCase{70, 12, 10, true}, LinearCase{5000, 12, 10, true}}) {
    CAPTURE(c.n);
    LinearData d = make_data(c, 500);
    Tensor x = Tensor::from_host(d.x, {c.n, c.in}), dy = Tensor::from_host(d.dy, {c.n, c.out});
    nn::Param w("lin.w", 1, Tensor::from_host(d.w, {c.in, c.out}));
    nn::Param b("lin.b", 1, Tensor::from_host(d.b, {c.out}));
    nn::LinearGrads once = nn::linear_backward(x, w.value, dy, false, true, true);

    Tensor dx = nn::linear_backward(x, w, &b, dy, /*need_dx=*/false);
    CHECK(!dx.defined());
    REQUIRE(w.grad.defined());
    REQUIRE(b.grad.defined());
    // One call into fresh (zero) grads equals the ops form: same GEMM, beta = 1 on zeros.
    check_close(w.grad.to_host(), to_double(once.dw.to_host()), 1e-6, 1e-7, "accumulated dW after one call");
    check_close(b.grad.to_host(), to_double(once.db.to_host()), 1e-6, 1e-7, "accumulated db after one call");
    dx = nn::linear_backward(x, w, &b, dy, /*need_dx=*/true);
    CHECK(dx.defined());
    auto twice = [](const Tensor& t) {
      auto v = to_double(t.to_host());
      for (double& e : v) e *= 2;
      return v;
    };
    // The second call adds onto the grads inside the GEMM (beta = 1), which may fold its K panels into C one
    // at a time: the same sum in another order, a few ulps of a 5000-term sum from twice one call (3e-6 seen
    // on a loaded machine). A missed or doubled accumulation is off by 50% or more.
    check_close(w.grad.to_host(), twice(once.dw), 1e-5, 1e-7, "dW after two calls");
    check_close(b.grad.to_host(), twice(once.db), 1e-5, 1e-7, "db after two calls");

    w.zero_grad();
    nn::linear_backward(x, w, nullptr, dy, false);  // no bias
    check_close(w.grad.to_host(), to_double(once.dw.to_host()), 1e-6, 1e-7, "dW after zero_grad and one call");
  }
}

TEST_CASE("linear: bad inputs give errors naming the op and the shapes") {
  Tensor w = Tensor::zeros({4, 3});
  // N = 0: device tensors cannot be empty, so the op refuses and says what to do.
  testing::expect_error([&] { nn::linear_forward(Tensor(host::Shape{0, 4}), w, Tensor()); },
                        "linear_forward: x [0, 4] has no rows; skip an empty batch");
  testing::expect_error([&] { nn::linear_forward(Tensor::zeros({2, 5}), w, Tensor()); },
                        "linear_forward: x [2, 5] has 5 columns but W [4, 3] has 4 rows");
  testing::expect_error([&] { nn::linear_forward(Tensor::zeros({2, 4}), w, Tensor::zeros({4})); },
                        "linear_forward: bias has shape [4], expected [3]");
  testing::expect_error([&] { nn::linear_forward(Tensor::zeros({2, 4}), Tensor(), Tensor()); },
                        "linear_forward: W is undefined");
  testing::expect_error([&] { nn::linear_backward(Tensor::zeros({2, 4}), w, Tensor::zeros({2, 4}), true, true, true); },
                        "linear_backward: dy has shape [2, 4], expected [2, 3]");
  nn::Param pw("w", 0, w), pb("b", 0, Tensor::zeros({2}));
  testing::expect_error([&] { nn::linear_backward(Tensor::zeros({2, 4}), pw, &pb, Tensor::zeros({2, 3}), true); },
                        "linear_backward: bias has shape [2], expected [3]");
  CHECK(!pw.grad.defined());  // refused before a gradient was allocated
}
