// Test helpers: seeded random data, comparison against double-precision references with stated
// tolerances, and central finite differences of those references.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace stylerf::testing {

std::vector<float> random_normal(size_t n, uint64_t seed, float stddev = 1.0f, float mean = 0.0f);
std::vector<float> random_uniform(size_t n, uint64_t seed, float lo, float hi);
std::vector<double> to_double(const std::vector<float>& v);

// Largest |got - want| / (atol + rtol * |want|) over all elements; <= 1 means within tolerance.
// A NaN or Inf on either side fails (a NaN compares false with everything, so a plain maximum would skip it).
// On failure the doctest message names the worst index and both values.
void check_close(const std::vector<float>& got, const std::vector<double>& want, double rtol, double atol,
                 const std::string& what);

// Central differences of a scalar function of many inputs: d f / d x_i ~ (f(x+h e_i) - f(x-h e_i)) / 2h.
std::vector<double> finite_difference(const std::function<double(const std::vector<double>&)>& f,
                                      const std::vector<double>& x, double h = 1e-4);
// Same, for only the listed indices (large tensors: probe a sample).
std::vector<double> finite_difference_at(const std::function<double(const std::vector<double>&)>& f,
                                         const std::vector<double>& x, const std::vector<size_t>& indices,
                                         double h = 1e-4);

// Sum of elementwise products: the scalar loss <g, y> whose gradient w.r.t. y is g; tests use it
// to turn a tensor-valued op into a scalar for finite differences.
double dot(const std::vector<double>& a, const std::vector<double>& b);

bool all_finite(const std::vector<float>& v);

// The larger of two error measures, NaN if either is NaN. std::max(err, NaN) returns err, which lets a NaN
// result pass an error-maximum check; with this one `CHECK(err <= tol)` fails on it.
double max_or_nan(double a, double b);
// Largest |got[i] - want[i]|: NaN when any element on either side is NaN, Inf when one is infinite.
double max_abs_error(const std::vector<float>& got, const std::vector<double>& want);

// Cases that need ../shared are in doctest's test suite "shared" (decorator `* doctest::test_suite("shared")`);
// CTest runs them as their own entry, <suite>_shared. Where the data is absent such a case calls this and
// returns: it prints the marker CTest's SKIP_REGULAR_EXPRESSION matches, so the entry reads as skipped, never
// as passed.
void report_skipped(const std::string& why);
constexpr const char* kSkippedMarker = "[stylerf test skipped]";

// A fresh folder <temp>/stylerf_test_<suite>_<tag>_<pid>, removed at scope exit.
struct TempDir {
  std::filesystem::path path;
  TempDir(const std::string& suite, const std::string& tag);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string str(const std::string& sub = "") const { return (sub.empty() ? path : path / sub).string(); }
};

// The message of the host::Error that f() throws, or "" when it throws none. Bad-input tests then check
// that the message names the file / op and what is wrong.
std::string error_of(const std::function<void()>& f);
// Checks (doctest CHECK) that f() throws a host::Error whose message contains `needle`.
void expect_error(const std::function<void()>& f, const std::string& needle);

// True under STYLERF_TEST_SMALL=1 (scripts/oclgrind.sh: a simulated device ~1000x slower than PoCL). The
// heavy suites then run the same cases with the same checks at smaller sizes; normal runs are unchanged.
bool small_run();

// Directory of ../shared/data, or "" if absent (tests needing it say so and fail loudly, not skip).
std::string shared_data_dir();

// ../shared/reference/<name> (values from official code), or "" when ../shared is absent.
std::string shared_reference_dir(const std::string& name);

// An image file for tests that need a real photo: `rel` under ../shared/data when it is there, else a
// procedural stand-in written once per process (kind "content": a rendered scene, "style": a painted
// pattern; lib/demo/procedural_images), so the suite also runs on a machine without ../shared.
std::string image_file_or_procedural(const std::string& rel, const std::string& kind);

}  // namespace stylerf::testing
