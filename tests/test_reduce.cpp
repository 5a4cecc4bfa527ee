// Whole-tensor sum (two-stage, kernels/reduce.cl), the non-finite check and axpby (kernels/elementwise.cl),
// against double references. These ops have no backward: sum's gradient is a fill and axpby is linear.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

#include "host/error.hpp"
#include "host/tensor.hpp"
#include "lib/nn/checks.hpp"
#include "lib/nn/ops.hpp"
#include "lib/nn/reduce_path.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;
using testing::check_close;

namespace {
double ref_sum(const std::vector<float>& x, double* abs_sum = nullptr) {
  double s = 0, a = 0;
  for (float v : x) {
    s += v;
    a += std::fabs(v);
  }
  if (abs_sum) *abs_sum = a;
  return s;
}
}  // namespace

TEST_CASE("sum: sizes around the vector width and the partition, against a double sum") {
  // Tolerance: 1e-6 of sum |x| (the condition of the sum; blocked float accumulation stays well inside).
  for (int n : {1, 7, 8, 9, 63, 1000, 8192, 8193, 100003, 1 << 20}) {
    auto x = testing::random_normal(size_t(n), uint64_t(n), 1.0f, 0.1f);
    double abs_sum = 0;
    const double want = ref_sum(x, &abs_sum);
    Tensor t = Tensor::from_host(x, {n});
    Tensor s = nn::sum(t);
    CHECK(s.shape() == host::Shape{1});
    check_close(s.to_host(), {want}, 0.0, 1e-6 * abs_sum, "sum n=" + std::to_string(n));
    CHECK(nn::sum_value(t) == s.to_host()[0]);
  }
}

TEST_CASE("sum of 10^7 elements: 1e-6 relative, and deterministic") {
  const int n = 10000000;
  auto x = testing::random_uniform(size_t(n), 42, 0.0f, 1.0f);
  const double want = ref_sum(x);
  Tensor t = Tensor::from_host(x, {n});
  const float got = nn::sum_value(t);
  MESSAGE("sum of 1e7 uniform(0,1): got " << got << ", double reference " << want << ", relative error "
                                          << std::fabs(got - want) / want);
  CHECK(std::fabs(got - want) <= 1e-6 * want);
  CHECK(nn::sum_value(t) == got);  // bitwise the same: the split depends on n only
  // A naive float running sum is off by ~1e-3 relative here; show the test would see that.
  float naive = 0;
  for (float v : x) naive += v;
  CHECK(std::fabs(naive - want) > 1e-6 * want);
}

TEST_CASE("sum: large and tiny magnitudes") {
  for (float scale : {1e15f, 1e-20f}) {
    auto x = testing::random_normal(100003, 7, scale, scale);
    double abs_sum = 0;
    const double want = ref_sum(x, &abs_sum);
    check_close(nn::sum(Tensor::from_host(x, {100003})).to_host(), {want}, 0.0, 1e-6 * abs_sum,
                "sum scale " + std::to_string(scale));
  }
}

TEST_CASE("has_nonfinite finds one NaN or Inf anywhere") {
  const int n = 100003;
  auto x = testing::random_normal(size_t(n), 3, 1e30f);
  CHECK_FALSE(nn::has_nonfinite(Tensor::from_host(x, {n})));
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                       -std::numeric_limits<float>::infinity()};
  for (float b : bad)
    for (int i : {0, 5000, n - 1}) {
      auto y = x;
      y[size_t(i)] = b;
      CHECK_MESSAGE(nn::has_nonfinite(Tensor::from_host(y, {n})), "value " << b << " at " << i);
    }
  CHECK_FALSE(nn::has_nonfinite(Tensor::full({5}, std::numeric_limits<float>::max())));
}

TEST_CASE("axpby: y = a x + b y against a double reference; b = 0 ignores y; x may alias y") {
  for (int n : {1, 8, 13, 1001}) {
    auto x = testing::random_normal(size_t(n), 1), y = testing::random_normal(size_t(n), 2);
    Tensor tx = Tensor::from_host(x, {n}), ty = Tensor::from_host(y, {n});
    nn::axpby(1.5f, tx, -0.25f, ty);
    std::vector<double> want(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) want[size_t(i)] = 1.5 * double(x[size_t(i)]) - 0.25 * double(y[size_t(i)]);
    check_close(ty.to_host(), want, 1e-6, 1e-7, "axpby n=" + std::to_string(n));

    Tensor tn = Tensor::full({n}, std::numeric_limits<float>::quiet_NaN());
    nn::axpby(2.0f, tx, 0.0f, tn);
    for (int i = 0; i < n; ++i) want[size_t(i)] = 2.0 * double(x[size_t(i)]);
    check_close(tn.to_host(), want, 1e-7, 0.0, "axpby b=0 over NaN n=" + std::to_string(n));

    nn::axpby(1.0f, tx, 1.0f, tx);  // x = 2x in place
    check_close(tx.to_host(), want, 1e-7, 0.0, "axpby aliased n=" + std::to_string(n));
  }
}

TEST_CASE("bad arguments give errors naming the op") {
  Tensor x = Tensor::zeros({4, 5}), y = Tensor::zeros({5, 4});
  CHECK_THROWS_WITH_AS(nn::axpby(1.0f, x, 1.0f, y), doctest::Contains("axpby"), host::Error);
  CHECK_THROWS_WITH_AS(nn::sum(Tensor()), doctest::Contains("sum: x is undefined"), host::Error);
  CHECK_THROWS_WITH_AS(nn::has_nonfinite(Tensor()), doctest::Contains("has_nonfinite"), host::Error);
}

TEST_CASE("reduction paths: STYLERF_REDUCTION is honoured, and both paths agree with the double sum") {
  const char* env = std::getenv("STYLERF_REDUCTION");
  if (env && std::string(env) == "work-group") CHECK(nn::detail::use_group_reductions());
  if (env && std::string(env) == "per-item") CHECK(!nn::detail::use_group_reductions());
  // Sizes below one group, around it, and with a ragged last chunk; both paths within 1e-6 of the sum of
  // |x|, and each bit-identical on a rerun.
  for (int n : {1, 255, 256, 257, 8191, 100003}) {
    CAPTURE(n);
    const auto x = testing::random_normal(size_t(n), 90 + n, 1.0f, 0.5f);
    double abs_sum = 0;
    const double want = ref_sum(x, &abs_sum);
    Tensor t = Tensor::from_host(x, {n});
    for (auto path : {nn::ReductionPath::PerItem, nn::ReductionPath::WorkGroup}) {
      const auto old = nn::set_reduction_path(path);
      const float got = nn::sum_value(t);
      CHECK(nn::sum_value(t) == got);
      CHECK(std::fabs(double(got) - want) <= 1e-6 * abs_sum + 1e-30);
      nn::set_reduction_path(old);
    }
  }
  CHECK_THROWS_WITH_AS(nn::parse_reduction_path("warp"), doctest::Contains("per-item, work-group"), host::Error);
}
