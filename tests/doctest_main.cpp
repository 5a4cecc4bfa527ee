#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <chrono>
#include <iostream>
#include <string>

#include "host/runtime.hpp"

namespace {

// Under STYLERF_PROFILE=1: each test case's per-kernel device time and peak device memory, printed when the
// case ends (what to shrink for a slow device such as Oclgrind's simulator; scripts/oclgrind.sh).
struct KernelTimes : doctest::IReporter {
  explicit KernelTimes(const doctest::ContextOptions&) {}
  void report_query(const doctest::QueryData&) override {}
  void test_run_start() override {}
  void test_run_end(const doctest::TestRunStats&) override {}
  void test_case_start(const doctest::TestCaseData& tc) override {
    name_ = tc.m_name;
    start_ = std::chrono::steady_clock::now();
  }
  void test_case_reenter(const doctest::TestCaseData&) override {}
  void test_case_end(const doctest::CurrentTestCaseStats&) override {
    auto& rt = stylerf::host::Runtime::instance();
    if (!rt.profiling()) return;
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::cout << rt.timing_report() << "device memory: peak live " << (rt.peak_live_bytes() >> 20) << " MiB, pooled "
              << (rt.pooled_bytes() >> 20) << " MiB; " << secs << " s: " << name_ << std::endl;
    rt.reset_timings();
    rt.reset_peak();
  }
  void test_case_exception(const doctest::TestCaseException&) override {}
  void subcase_start(const doctest::SubcaseSignature&) override {}
  void subcase_end() override {}
  void log_assert(const doctest::AssertData&) override {}
  void log_message(const doctest::MessageData&) override {}
  void test_case_skipped(const doctest::TestCaseData&) override {}

 private:
  std::string name_;
  std::chrono::steady_clock::time_point start_;
};
REGISTER_LISTENER("kernel_times", 1, KernelTimes);

}  // namespace

int main(int argc, char** argv) {
  // One device for the whole suite; STYLERF_DEVICE picks it like the CLI does.
  auto& rt = stylerf::host::Runtime::init();
  std::cout << "device: " << rt.device().describe() << std::endl;
  doctest::Context ctx(argc, argv);
  int rc = ctx.run();
  stylerf::host::Runtime::shutdown();
  return rc;
}
