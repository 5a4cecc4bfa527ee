// GEMM: every engine against a double-precision CPU reference, all transpose cases, odd sizes, offsets,
// leading dimensions, alpha/beta, K = 0, extreme magnitudes; the tuning database format.
//
// Tolerance: float32 accumulation of K products has error at most about K * eps * sum_k |a_ik b_kj|, so
// each element must satisfy |got - ref| <= 4 * (K + 2) * 2^-24 * (|alpha| sum_k |a_ik b_kj| + |beta c_ij|)
// + 1e-30. This bound is tight enough to catch any wrong index (errors of O(|a b|)) and loose enough
// for any summation order.
#include <doctest/doctest.h>

#include <cmath>
#include <algorithm>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "host/error.hpp"
#include "host/gemm.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "host/tuning_db.hpp"
#include "tests/testing.hpp"

using namespace stylerf::host;
using stylerf::testing::random_normal;

namespace {

struct Case {
  Trans ta, tb;
  int M, N, K;
  int pad_a = 0, pad_b = 0, pad_c = 0;  // extra columns beyond the stored row (leading dimension slack)
  size_t off_a = 0, off_b = 0, off_c = 0;
  float alpha = 1.0f, beta = 0.0f;
  int batch = 0;  // 0: one GEMM through gemm(); n >= 1: gemm_strided_batched() on n operand sets
};

std::string describe(const Case& c) {
  return std::string(c.ta == Trans::Yes ? "T" : "N") + (c.tb == Trans::Yes ? "T" : "N") + " M=" + std::to_string(c.M) +
         " N=" + std::to_string(c.N) + " K=" + std::to_string(c.K) + " lda+" + std::to_string(c.pad_a) + " ldb+" +
         std::to_string(c.pad_b) + " ldc+" + std::to_string(c.pad_c) + " off " + std::to_string(c.off_a) + "/" +
         std::to_string(c.off_b) + "/" + std::to_string(c.off_c) + " alpha=" + std::to_string(c.alpha) +
         " beta=" + std::to_string(c.beta) + (c.batch ? " batch=" + std::to_string(c.batch) : "");
}

// One operand: `count` matrices of rows x cols with leading dimension ld, the first at off, each next
// one stride elements on (rows * ld plus a gap of 3, so a batch stride is not just the matrix size).
struct Stored {
  int rows, cols, ld;
  size_t off;
  int count = 1;
  size_t stride() const { return static_cast<size_t>(rows) * ld + 3; }
  size_t size() const { return off + count * stride(); }
};

// Runs one case with one engine (or explicit own parameters) and compares with the double reference.
// scale multiplies the random inputs (extreme-magnitude tests); c_fill, when set, fills C instead of
// random values (NaN with beta = 0 must not leak).
void run_case(const Case& c, GemmEngine engine, const OwnGemmParams* own = nullptr, float scale_a = 1.0f,
              float scale_b = 1.0f, std::optional<float> c_fill = std::nullopt) {
  const Stored sa{c.ta == Trans::No ? c.M : c.K, c.ta == Trans::No ? c.K : c.M, 0, c.off_a};
  const Stored sb{c.tb == Trans::No ? c.K : c.N, c.tb == Trans::No ? c.N : c.K, 0, c.off_b};
  const int count = std::max(1, c.batch);
  Stored A = sa, B = sb, C{c.M, c.N, c.N + c.pad_c, c.off_c, count};
  A.ld = std::max(1, A.cols + c.pad_a);
  B.ld = std::max(1, B.cols + c.pad_b);
  A.count = B.count = count;
  auto ha = random_normal(A.size(), 11 + c.M, scale_a);
  auto hb = random_normal(B.size(), 23 + c.N, scale_b);
  auto hc = random_normal(C.size(), 37 + c.K);
  if (c_fill)
    for (auto& v : hc) v = *c_fill;
  auto at = [&](const std::vector<float>& v, const Stored& s, int n, bool trans, int i, int k) {
    const size_t base = s.off + n * s.stride();
    return static_cast<double>(trans ? v[base + static_cast<size_t>(k) * s.ld + i] : v[base + static_cast<size_t>(i) * s.ld + k]);
  };
  std::vector<double> want(hc.begin(), hc.end()), bound(hc.size(), 0.0);
  for (int n = 0; n < count; ++n)
  for (int i = 0; i < c.M; ++i)
    for (int j = 0; j < c.N; ++j) {
      double s = 0.0, sabs = 0.0;
      for (int k = 0; k < c.K; ++k) {
        const double p = at(ha, A, n, c.ta == Trans::Yes, i, k) * at(hb, B, n, c.tb == Trans::Yes, k, j);
        s += p;
        sabs += std::fabs(p);
      }
      const size_t ci = c.off_c + n * C.stride() + static_cast<size_t>(i) * C.ld + j;
      const double old = c.beta == 0.0f ? 0.0 : c.beta * static_cast<double>(hc[ci]);
      want[ci] = c.alpha * s + old;
      bound[ci] = 4.0 * (c.K + 2) * std::ldexp(1.0, -24) * (std::fabs(c.alpha) * sabs + std::fabs(old)) + 1e-30;
    }
  Tensor ta = Tensor::from_host(ha, {static_cast<int64_t>(ha.size())});
  Tensor tb = Tensor::from_host(hb, {static_cast<int64_t>(hb.size())});
  Tensor tc = Tensor::from_host(hc, {static_cast<int64_t>(hc.size())});
  if (own)
    gemm_own_with(*own, c.ta, c.tb, c.M, c.N, c.K, c.alpha, ta.mem(), c.off_a, A.ld, tb.mem(), c.off_b, B.ld, c.beta,
                  tc.mem(), c.off_c, C.ld);
  else if (c.batch)
    gemm_strided_batched(c.ta, c.tb, c.M, c.N, c.K, c.alpha, ta.mem(), c.off_a, A.ld, A.stride(), tb.mem(), c.off_b,
                         B.ld, B.stride(), c.beta, tc.mem(), c.off_c, C.ld, C.stride(), c.batch, engine);
  else
    gemm(c.ta, c.tb, c.M, c.N, c.K, c.alpha, ta.mem(), c.off_a, A.ld, tb.mem(), c.off_b, B.ld, c.beta, tc.mem(),
         c.off_c, C.ld, engine);
  auto got = tc.to_host();
  double worst = 0.0;
  size_t worst_i = 0;
  bool finite = true;
  for (size_t i = 0; i < got.size(); ++i) {
    if (std::isnan(want[i]) && std::isnan(got[i])) continue;  // NaN fill outside the C window, untouched
    if (!std::isfinite(got[i]) && std::isfinite(want[i])) finite = false;
    // Elements outside the C window (offset, padding) must be untouched: bound 0 there means equality.
    const double r = std::fabs(got[i] - want[i]) / std::max(bound[i], 1e-300);
    if (!(r <= worst)) {
      worst = r;
      worst_i = i;
    }
  }
  const std::string name = own ? "own(" + own->describe() + ")" : gemm_engine_name(engine);
  CHECK_MESSAGE(finite, name << " " << describe(c) << ": non-finite output");
  CHECK_MESSAGE(worst <= 1.0, name << " " << describe(c) << ": worst element " << worst_i << " got " << got[worst_i]
                                   << " want " << want[worst_i] << " (error / bound = " << worst << ")");
}

const Trans kTrans[2] = {Trans::No, Trans::Yes};

// Every engine this build and device can run: host-blas needs a CBLAS in the build and a CPU device.
std::vector<GemmEngine> engines() {
  std::vector<GemmEngine> e{GemmEngine::Own, GemmEngine::ClblastTuned, GemmEngine::ClblastDefault};
  if (host_blas_usable()) e.push_back(GemmEngine::HostBlas);
  return e;
}

}  // namespace

TEST_CASE("every engine matches the reference for all transpose cases and odd sizes") {
  const int sizes[][3] = {{1, 1, 1}, {7, 33, 65}, {65, 7, 33}, {33, 129, 7}, {129, 65, 17}, {3, 70, 40}};
  for (GemmEngine e : engines())
    for (Trans ta : kTrans)
      for (Trans tb : kTrans)
        for (const auto& s : sizes) {
          Case c{ta, tb, s[0], s[1], s[2]};
          c.alpha = 1.0f;
          c.beta = 0.0f;
          run_case(c, e);
        }
}

TEST_CASE("offsets, leading dimensions, alpha and beta") {
  for (GemmEngine e : engines())
    for (Trans ta : kTrans)
      for (Trans tb : kTrans) {
        Case c{ta, tb, 19, 37, 23, 3, 5, 2, 7, 13, 5, -1.5f, 0.75f};
        run_case(c, e);
      }
}

TEST_CASE("strided batches: every engine, batches below and above the thread count, tall and wide C") {
  // host-blas splits a batch smaller than its thread count into blocks of C rows (tall C) or columns
  // (wide C), and a larger batch into whole GEMMs per thread: all three shapes of work are covered.
  const int shapes[][3] = {{70, 9, 13}, {9, 70, 13}, {33, 35, 1}};
  for (GemmEngine e : engines())
    for (int batch : {1, 2, 3, 36})
      for (const auto& s : shapes)
        for (Trans ta : kTrans)
          for (Trans tb : kTrans) {
            Case c{ta, tb, s[0], s[1], s[2], 1, 2, 3, 4, 5, 6, 0.5f, batch % 2 ? -1.0f : 0.0f};
            c.batch = batch;
            run_case(c, e);
          }
}

TEST_CASE("gemm_strided_batched: batch 0 leaves C alone, a negative batch is an error") {
  Tensor a = Tensor::full({4}, 1.0f), c = Tensor::full({4}, 7.0f);
  gemm_strided_batched(Trans::No, Trans::No, 2, 2, 1, 1.0f, a.mem(), 0, 1, 2, a.mem(), 0, 2, 2, 0.0f, c.mem(), 0, 2, 4,
                       0);
  for (float v : c.to_host()) CHECK(v == 7.0f);
  CHECK_THROWS_AS(gemm_strided_batched(Trans::No, Trans::No, 2, 2, 1, 1.0f, a.mem(), 0, 1, 2, a.mem(), 0, 2, 2, 0.0f,
                                       c.mem(), 0, 2, 4, -1),
                  Error);
}

TEST_CASE("own kernel: every tile shape the tuner may pick, K chunking and work-group sizes") {
  const OwnGemmParams variants[] = {{6, 8, 2, 0, 1, 1}, {4, 4, 3, 16, 1, 3}, {8, 8, 1, 7, 2, 2},
                                    {2, 16, 1, 64, 4, 1}, {1, 4, 1, 5, 1, 4}};
  for (const auto& p : variants)
    for (Trans ta : kTrans)
      for (Trans tb : kTrans) {
        run_case(Case{ta, tb, 37, 45, 50, 1, 2, 3, 4, 5, 6, 0.5f, -2.0f}, GemmEngine::Own, &p);
        run_case(Case{ta, tb, 3, 20, 33}, GemmEngine::Own, &p);  // fewer rows than the tile
      }
}

TEST_CASE("K = 0 gives C = beta * C for every engine") {
  for (GemmEngine e : engines()) {
    run_case(Case{Trans::No, Trans::No, 9, 17, 0, 0, 0, 1, 0, 0, 2, 2.0f, 0.5f}, e);
    run_case(Case{Trans::No, Trans::Yes, 9, 17, 0, 0, 0, 0, 0, 0, 0, 2.0f, 0.0f}, e);
  }
}

TEST_CASE("beta = 0 ignores NaN in C (the CPU engines: own, and host-blas where it runs)") {
  std::vector<GemmEngine> cpu{GemmEngine::Own};
  if (host_blas_usable()) cpu.push_back(GemmEngine::HostBlas);
  for (GemmEngine e : cpu)
    for (Trans ta : kTrans)
      for (Trans tb : kTrans)
        run_case(Case{ta, tb, 13, 21, 9}, e, nullptr, 1.0f, 1.0f, std::numeric_limits<float>::quiet_NaN());
}

TEST_CASE("split-K (forced): CLBlast engines match the reference with uneven tails, offsets, alpha, beta, NaN in C") {
  // Auto splits only on GPUs (few tiles of C, long K); forcing it runs the same path on this device.
  struct Reset {
    ~Reset() { set_gemm_split_k(0); }
  } reset;
  for (int parts : {2, 3, 7}) {
    set_gemm_split_k(parts);
    for (GemmEngine e : {GemmEngine::ClblastTuned, GemmEngine::ClblastDefault})
      for (Trans ta : kTrans)
        for (Trans tb : kTrans) {
          run_case(Case{ta, tb, 9, 13, 100}, e);                                 // 100 = chunks + a shorter tail
          run_case(Case{ta, tb, 19, 37, 23, 3, 5, 2, 7, 13, 5, -1.5f, 0.75f}, e);  // offsets, ld slack, beta
          run_case(Case{ta, tb, 13, 21, 9}, e, nullptr, 1.0f, 1.0f, std::numeric_limits<float>::quiet_NaN());
        }
  }
  CHECK(gemm_split_k_parts(9, 13, 100) == 7);
  CHECK(gemm_split_k_parts(9, 13, 5) == 5);  // never more chunks than K
  set_gemm_split_k(1);
  CHECK(gemm_split_k_parts(9, 13, 1 << 20) == 1);
  set_gemm_split_k(0);
  if (Runtime::instance().device().type & CL_DEVICE_TYPE_CPU) CHECK(gemm_split_k_parts(256, 96, 3 << 20) == 1);
  CHECK(gemm_split_k_parts(64, 64, 1 << 20, 36) == 1);  // Auto runs a batch as one call, unsplit
  CHECK_THROWS_AS(set_gemm_split_k(-1), Error);
}

TEST_CASE("huge and tiny magnitudes stay finite and accurate") {
  // |a b| ~ 1e36 summed over K = 40 stays below FLT_MAX (3.4e38); tiny: |a b| ~ 1e-30, far from denormals.
  for (GemmEngine e : engines())
    for (Trans tb : kTrans) {
      run_case(Case{Trans::No, tb, 17, 33, 40}, e, nullptr, 1e18f, 1e18f);
      run_case(Case{Trans::No, tb, 17, 33, 40}, e, nullptr, 1e-15f, 1e-15f);
    }
}

TEST_CASE("matmul checks shapes") {
  Tensor a = Tensor::zeros({4, 5}), b = Tensor::zeros({6, 3}), c = Tensor::zeros({4, 3});
  CHECK_THROWS_AS(matmul(a, Trans::No, b, Trans::No, c), Error);
  Tensor b2 = Tensor::full({5, 3}, 1.0f);
  Tensor a2 = Tensor::full({4, 5}, 2.0f);
  matmul(a2, Trans::No, b2, Trans::No, c);
  for (float v : c.to_host()) CHECK(v == 10.0f);
}

TEST_CASE("engine names and resolution") {
  CHECK(parse_gemm_engine("own") == GemmEngine::Own);
  CHECK(parse_gemm_engine("host-blas") == GemmEngine::HostBlas);
  CHECK(std::string(gemm_engine_name(GemmEngine::HostBlas)) == "host-blas");
  // host-blas is usable exactly when the build links a CBLAS and the device is a CPU; elsewhere a call
  // naming it is an error that says why, never a silent switch.
  const bool cpu = Runtime::instance().device().type & CL_DEVICE_TYPE_CPU;
  CHECK(host_blas_usable() == (host_blas_linked() && cpu));
  if (!host_blas_usable()) {
    Tensor a = Tensor::full({4}, 1.0f), c = Tensor::zeros({4});
    CHECK_THROWS_AS(gemm(Trans::No, Trans::No, 2, 2, 2, 1.0f, a.mem(), 0, 2, a.mem(), 0, 2, 0.0f, c.mem(), 0, 2,
                         GemmEngine::HostBlas),
                    Error);
  }
  CHECK_THROWS_AS(parse_gemm_engine("fast"), Error);
  CHECK(resolve_gemm_engine(GemmEngine::Auto) != GemmEngine::Auto);
  set_default_gemm_engine(GemmEngine::ClblastDefault);
  CHECK(resolve_gemm_engine(GemmEngine::Auto) == GemmEngine::ClblastDefault);
  set_default_gemm_engine(GemmEngine::Auto);
}

TEST_CASE("tuning database: parse, round trip, errors") {
  const TuningDb embedded = TuningDb::parse(stylerf::host::active_tuning_db().dump(), "active");
  CHECK(TuningDb::parse(embedded.dump(), "round trip").dump() == embedded.dump());

  const std::string text = R"({"format": "stylerf-clblast-tuning-1", "devices": {"dev A": {
      "clblast": {"Copy": {"COPY_DIMX": 8, "COPY_DIMY": 8, "COPY_VW": 4, "COPY_WPT": 1}},
      "recommended_engine": "own", "own_gemm": {"mr": 4, "vw": 8, "nv": 2, "kc": 128, "wg": 1, "qt": 2}}}})";
  TuningDb db = TuningDb::parse(text, "inline");
  REQUIRE(db.find("dev A") != nullptr);
  CHECK(db.find("dev B") == nullptr);
  CHECK(db.find("dev A")->clblast.at("Copy").at("COPY_VW") == 4);
  CHECK(db.find("dev A")->own_gemm->mr == 4);
  CHECK(db.find("dev A")->own_gemm->qt == 2);
  CHECK(db.find("dev A")->recommended_engine == "own");

  TuningDb other = TuningDb::parse(R"({"format": "stylerf-clblast-tuning-1", "devices": {"dev A": {
      "recommended_engine": "clblast-tuned"}}})", "other");
  db.merge_from(other);
  CHECK(db.find("dev A")->recommended_engine == "clblast-tuned");
  CHECK(db.find("dev A")->clblast.empty());  // merge replaces a device's whole entry

  CHECK_THROWS_AS(TuningDb::parse("{", "bad json"), Error);
  CHECK_THROWS_AS(TuningDb::parse(R"({"format": "other"})", "bad format"), Error);
  CHECK_THROWS_AS(TuningDb::parse(R"({"format": "stylerf-clblast-tuning-1", "devices": {"d": {"own_gemm": {"vw": 3}}}})",
                                  "bad own"),
                  Error);
  CHECK_THROWS_AS(
      TuningDb::parse(R"({"format": "stylerf-clblast-tuning-1", "devices": {"d": {"clblast": {"Copy": {"X": -1}}}}})",
                      "negative"),
      Error);
}

TEST_CASE("CLBlast tuner output converts to a parameter set") {
  const std::string tuner = R"({"kernel_family": "xgemm_direct_2", "precision": "32", "device": "dev",
    "results": [
      {"kernel": "XgemmDirectTN", "time": 5.0, "parameters": {"WGD": 8, "PRECISION": 32}},
      {"kernel": "XgemmDirectTN", "time": 2.5, "parameters": {"WGD": 16, "PRECISION": 32}},
      {"kernel": "XgemmDirectTN", "time": 9.0, "parameters": {"WGD": 32, "PRECISION": 32}}]})";
  auto r = parse_clblast_tuner_json(tuner, "inline");
  CHECK(r.kernel == "XgemmDirect");
  CHECK(r.best_ms == 2.5);
  CHECK(r.params.at("WGD") == 16);
  CHECK(r.params.count("PRECISION") == 0);
  CHECK_THROWS_AS(parse_clblast_tuner_json(R"({"kernel_family": "xgemm_1", "results": []})", "empty"), Error);
  CHECK_THROWS_AS(parse_clblast_tuner_json(R"({"kernel_family": "xfoo", "results": [{"time": 1, "parameters": {}}]})",
                                           "family"),
                  Error);
}

TEST_CASE("the tuning database entry for this device applies to CLBlast") {
  // With an entry, clblast-tuned must report that it uses it (OverrideParameters accepted every set);
  // without one, it must say so rather than pretend.
  const std::string status = clblast_tuning_status();
  INFO("status: " << status);
  const DeviceTuning* t = active_device_tuning();
  if (t && !t->clblast.empty())
    CHECK(status.rfind("tuning database (", 0) == 0);
  else
    CHECK(status.find("no CLBlast entry") != std::string::npos);
  CHECK(status.find("skipped") == std::string::npos);
}

// ---- the flush and overflow (docs/design.md's numerical contract: exact down to FLT_MIN, 0 below) ---------
namespace {

// C = A B for A [M, K] and B [K, N] given row-major, through `engine`; an operand passed as transposed is
// stored transposed. beta 0 over a C of NaN (nothing of the old C may show).
std::vector<float> gemm_of(GemmEngine engine, Trans ta, Trans tb, const std::vector<float>& a,
                           const std::vector<float>& b, int M, int N, int K) {
  std::vector<float> sa(a.size()), sb(b.size());
  for (int i = 0; i < M; ++i)
    for (int k = 0; k < K; ++k) sa[ta == Trans::Yes ? size_t(k) * M + i : size_t(i) * K + k] = a[size_t(i) * K + k];
  for (int k = 0; k < K; ++k)
    for (int j = 0; j < N; ++j) sb[tb == Trans::Yes ? size_t(j) * K + k : size_t(k) * N + j] = b[size_t(k) * N + j];
  Tensor ta_ = Tensor::from_host(sa, {int64_t(sa.size())}), tb_ = Tensor::from_host(sb, {int64_t(sb.size())});
  Tensor tc = Tensor::full({int64_t(M) * N}, std::numeric_limits<float>::quiet_NaN());
  gemm(ta, tb, M, N, K, 1.0f, ta_.mem(), 0, ta == Trans::Yes ? M : K, tb_.mem(), 0, tb == Trans::Yes ? K : N, 0.0f,
       tc.mem(), 0, N, engine);
  return tc.to_host();
}

// The contract's model of a float GEMM: every input and every product of magnitude below FLT_MIN is 0, the
// rest is exact float arithmetic. The cases below are built so that any summation order, fused or not,
// gives the same float: the products of one output are exact, their partial sums exact or rounded alike,
// and a product below FLT_MIN is either among zeros only (flushed however it is summed) or under half an
// ulp of the rest (an FMA adds it to a normal sum unflushed, and it must not show).
float flushed(double x) { return std::fabs(x) < double(std::numeric_limits<float>::min()) ? 0.0f : float(x); }

std::vector<float> contract_product(const std::vector<float>& a, const std::vector<float>& b, int M, int N, int K) {
  std::vector<float> c(size_t(M) * N);
  for (int i = 0; i < M; ++i)
    for (int j = 0; j < N; ++j) {
      double s = 0;
      for (int k = 0; k < K; ++k) s += double(flushed(double(flushed(a[size_t(i) * K + k])) * flushed(b[size_t(k) * N + j])));
      c[size_t(i) * N + j] = flushed(s);
    }
  return c;
}

// Compares bitwise up to the sign of 0 (Inf must be Inf of the right sign; NaN is never expected).
void check_exactly(const std::vector<float>& got, const std::vector<float>& want, const std::string& what) {
  REQUIRE(got.size() == want.size());
  int wrong = 0;
  for (size_t i = 0; i < got.size(); ++i)
    if (!(got[i] == want[i])) {
      if (++wrong <= 4) FAIL_CHECK(what << ": element " << i << " got " << got[i] << ", want " << want[i]);
    }
  CHECK_MESSAGE(wrong == 0, what << ": " << wrong << " elements differ");
}

// Tiles a [rows, cols] pattern to [rows * tr, cols * tc] (sizes past the engines' small-size paths).
std::vector<float> tiled(const std::vector<float>& p, int rows, int cols, int tr, int tc) {
  std::vector<float> out(size_t(rows) * tr * cols * tc);
  for (int i = 0; i < rows * tr; ++i)
    for (int j = 0; j < cols * tc; ++j) out[size_t(i) * cols * tc + j] = p[size_t(i % rows) * cols + j % cols];
  return out;
}

}  // namespace

TEST_CASE("subnormal inputs and products flush to 0, FLT_MIN is kept exactly: every engine, every transpose") {
  const float tiny = std::numeric_limits<float>::min();  // 2^-126
  const float dmin = std::numeric_limits<float>::denorm_min();
  auto p2 = [](int e) { return std::ldexp(1.0f, e); };
  const int M = 6, N = 4, K = 3;
  // Rows of A: subnormal inputs; normal inputs whose products with B's columns land on, above and below
  // FLT_MIN; small integers; FLT_MIN itself; cancelling signs.
  const std::vector<float> a = {dmin,     p2(-130), -p2(-127),  // all subnormal: read as 0
                                p2(-64),  p2(-64),  p2(-64),   //
                                1,        2,        3,         //
                                tiny,     tiny,     0,         //
                                -p2(-63), p2(-63),  p2(-62),   //
                                p2(-100), -p2(-100), p2(-27)};
  // Columns of B: ones; 2^-63 (products 2^-126 kept, 2^-127 and below flushed); mixed; a subnormal input.
  const std::vector<float> b = {1, p2(-63), p2(-64), dmin,  //
                                1, p2(-63), 1,       p2(-140),
                                1, p2(-63), p2(-63), 1};
  const std::vector<float> want = contract_product(a, b, M, N, K);
  // The model itself, at a few entries worked by hand.
  CHECK(want[0 * N + 0] == 0.0f);                     // subnormal inputs: 0, not their subnormal sum
  CHECK(want[1 * N + 0] == 3 * p2(-64));              // normal
  CHECK(want[1 * N + 1] == 0.0f);                     // three products of 2^-127: 0, not 1.5 FLT_MIN
  CHECK(want[3 * N + 0] == 2 * tiny);                 // FLT_MIN + FLT_MIN
  CHECK(want[3 * N + 2] == tiny);                     // FLT_MIN * 1 kept exactly
  CHECK(want[3 * N + 1] == 0.0f);                     // FLT_MIN * 2^-63: below FLT_MIN
  CHECK(want[4 * N + 1] == 2 * tiny);                 // -2^-126 + 2^-126 + 2^-125, exact in any order
  CHECK(want[5 * N + 1] == flushed(std::ldexp(1.0, -90)));  // 2^-163 flushed twice, 2^-90 kept
  for (GemmEngine e : engines())
    for (Trans ta : kTrans)
      for (Trans tb : kTrans) {
        const std::string what = std::string(gemm_engine_name(e)) + (ta == Trans::Yes ? " T" : " N") +
                                 (tb == Trans::Yes ? "T" : "N");
        check_exactly(gemm_of(e, ta, tb, a, b, M, N, K), want, what + " 6x4x3");
        // The same pattern tiled to 66 x 68 (K stays 3: each output is still one of the sums above).
        check_exactly(gemm_of(e, ta, tb, tiled(a, M, K, 11, 1), tiled(b, K, N, 1, 17), 11 * M, 17 * N, K),
                      tiled(want, M, N, 11, 17), what + " 66x68x3");
      }
}

TEST_CASE("inputs of ~1e19 overflow to Inf exactly where the exact result does, and nowhere else") {
  const float big = std::ldexp(1.0f, 63);  // 9.2e18; big * big = 2^126 = 8.5e37, FLT_MAX = 3.4e38
  const float inf = std::numeric_limits<float>::infinity();
  const int M = 5, N = 3, K = 4;
  const std::vector<float> a = {big,  big, big,  big,    // four products of 2^126: 2^128 > FLT_MAX
                                big,  big, big,  0,      // three: 3 * 2^126 = 2.6e38, finite
                                -big, -big, -big, -big,  // -2^128: -Inf
                                big,  -big, big, -big,   // +-2^126 twice: 0 in any order (partial sums <= 2^127)
                                1,    2,   0,    big};
  const std::vector<float> b = {1, big, 0,  //
                                1, big, 0,  //
                                1, big, 0,  //
                                1, big, std::ldexp(1.0f, 66)};  // big * 2^66 = 2^129: one product overflows
  // Expected values worked by hand (the exact result, rounded; Inf where it exceeds FLT_MAX).
  const std::vector<float> want = {4 * big, inf,  inf,           //
                                   3 * big,  3 * std::ldexp(1.0f, 126), 0,  //
                                   -4 * big, -inf, -inf,         //
                                   0,        0,    -inf,         //
                                   big,      std::ldexp(1.0f, 126), inf};  // 3 + big and 3 big + 2^126 round
  for (GemmEngine e : engines())
    for (Trans ta : kTrans)
      for (Trans tb : kTrans) {
        const std::string what = std::string(gemm_engine_name(e)) + (ta == Trans::Yes ? " T" : " N") +
                                 (tb == Trans::Yes ? "T" : "N");
        check_exactly(gemm_of(e, ta, tb, a, b, M, N, K), want, what);
      }
}
