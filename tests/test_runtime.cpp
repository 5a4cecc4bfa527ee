// The host runtime: device choice, buffers, kernel launch, errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <set>

#include "host/device.hpp"
#include "host/error.hpp"
#include "host/launch.hpp"
#include "host/runtime.hpp"
#include "host/tensor.hpp"
#include "tests/testing.hpp"

using namespace stylerf::host;

TEST_CASE("devices are listed and chosen by index, type and name") {
  auto devs = list_devices();
  REQUIRE(!devs.empty());
  CHECK(choose_device("0").id == devs[0].id);
  CHECK(choose_device(devs[0].type_name()).type == devs[0].type);
  CHECK(choose_device(devs[0].name.substr(0, 6)).id != nullptr);
}

TEST_CASE("an unknown device spec names the spec and lists devices") {
  try {
    choose_device("no-such-device-xyz");
    FAIL("expected an error");
  } catch (const Error& e) {
    std::string msg = e.what();
    CHECK(msg.find("no-such-device-xyz") != std::string::npos);
    CHECK(msg.find("[0]") != std::string::npos);
  }
}

TEST_CASE("tensor round trip, fill and copy") {
  auto data = stylerf::testing::random_normal(1000, 1);
  Tensor t = Tensor::from_host(data, {10, 100});
  CHECK(t.to_host() == data);
  Tensor c = t.clone();
  t.fill(2.5f);
  CHECK(c.to_host() == data);
  for (float v : t.to_host()) CHECK(v == 2.5f);
  CHECK_THROWS_AS(t.reshape({7, 7}), Error);
  CHECK(t.reshape({1000}).same_buffer(t));
}

TEST_CASE("an allocation beyond the device limit says how many bytes and what the device allows") {
  const auto& d = Runtime::instance().device();
  try {
    Runtime::instance().allocate(d.max_alloc_bytes + 4096, "test buffer");
    FAIL("expected an error");
  } catch (const Error& e) {
    std::string msg = e.what();
    CHECK(msg.find(std::to_string(d.max_alloc_bytes + 4096)) != std::string::npos);
    CHECK(msg.find("test buffer") != std::string::npos);
    CHECK(msg.find("at most") != std::string::npos);
  }
}

TEST_CASE("kernel launch runs, and errors name the kernel") {
  std::vector<float> x = {1, 2, 3}, y = {10, 20, 30};
  Tensor tx = Tensor::from_host(x, {3}), ty = Tensor::from_host(y, {3});
  launch("elementwise", "axpby", {3}, tx, ty, 2.0f, 0.5f, 3);
  auto out = ty.to_host();
  CHECK(out[0] == doctest::Approx(7));
  CHECK(out[2] == doctest::Approx(21));
  try {
    Runtime::instance().kernel("elementwise", "no_such_kernel");
    FAIL("expected an error");
  } catch (const Error& e) {
    CHECK(std::string(e.what()).find("no_such_kernel") != std::string::npos);
  }
  CHECK_THROWS_AS(Runtime::instance().kernel("no_such_program", "k"), Error);
  // An integer argument past the kernel's 32-bit int is refused, naming the kernel and the argument,
  // before anything is enqueued (it used to wrap): y is untouched.
  for (int64_t bad : {int64_t(1) << 31, -(int64_t(1) << 31) - 1}) {
    CHECK_THROWS_WITH_AS(launch("elementwise", "axpby", {3}, tx, ty, 2.0f, 0.5f, bad),
                         doctest::Contains("kernel axpby: argument 4"), Error);
  }
  CHECK_THROWS_WITH_AS(launch("elementwise", "axpby", {3}, tx, ty, 2.0f, 0.5f, size_t(1) << 31),
                       doctest::Contains("32-bit int"), Error);
  CHECK(ty.to_host() == out);
  launch("elementwise", "axpby", {3}, tx, ty, 0.0f, 1.0f, int64_t(3));  // in range: runs
  CHECK(ty.to_host() == out);
}

TEST_CASE("a launch without a local size gets a power-of-two group in dimension 0, from a few sizes") {
  // PoCL compiles a kernel anew for every local size it meets: the driver's range-dependent choice
  // compiled channel attention once per frame. Over 1D ranges ours is one of three sizes.
  std::set<size_t> sizes;
  for (size_t g = 1; g <= 200000; g += (g < 5000 ? 1 : 997)) {
    const size_t l = auto_local_size_x(g, 1, 4096);
    CHECK((l == 1 || l == 32 || l == 256));
    CHECK((g + l - 1) / l >= std::min<size_t>(g, 8));  // eight groups or more where the range allows
    sizes.insert(l);
  }
  CHECK(sizes.size() == 3);
  CHECK(auto_local_size_x(1000000, 1, 4096) == 256);
  CHECK(auto_local_size_x(1000000, 1, 100) == 32);  // a kernel allowing fewer work-items
  CHECK(auto_local_size_x(1000000, 1, 1) == 1);
  CHECK(auto_local_size_x(255, 1, 4096) == 1);
  // 2D: the other dimension gives the groups, one group spans dimension 0 (up to 256).
  CHECK(auto_local_size_x(32, 100003, 4096) == 32);
  CHECK(auto_local_size_x(33, 100003, 4096) == 64);
  CHECK(auto_local_size_x(5000, 64, 4096) == 256);
  CHECK(auto_local_size_x(32, 4, 4096) == 1);  // too few groups from dimension 1: the 1D rule

  // The padded work-items return at the kernel's guard: a range of 1009 (prime) writes 1009 floats, not
  // the 1024 its groups span.
  const int n = 1009;
  std::vector<float> x(1100, 1.0f), y(1100, 5.0f);
  Tensor tx = Tensor::from_host(x, {1100}), ty = Tensor::from_host(y, {1100});
  launch("elementwise", "axpby", {size_t(n)}, tx, ty, 2.0f, 1.0f, n);
  const auto out = ty.to_host();
  CHECK(out[0] == 7.0f);
  CHECK(out[n - 1] == 7.0f);
  for (int i = n; i < 1100; ++i) REQUIRE(out[i] == 5.0f);
}

TEST_CASE("a program built ahead of its first launch is built once; the launch builds nothing more") {
  Runtime& rt = Runtime::instance();
  const size_t before = rt.programs_built();
  rt.build({"elementwise", "-DAHEAD_OF_LAUNCH=1"});  // options no launch uses: a build of its own
  CHECK(rt.programs_built() == before + 1);
  rt.build({"elementwise", "-DAHEAD_OF_LAUNCH=1"});
  CHECK(rt.programs_built() == before + 1);
  Tensor t = Tensor::from_host(std::vector<float>{1, 2}, {2});
  launch_with_local("elementwise", "axpby", "-DAHEAD_OF_LAUNCH=1", {2}, Range(0), t, t, 1.0f, 1.0f, 2);
  CHECK(t.to_host()[1] == doctest::Approx(4));
  CHECK(rt.programs_built() == before + 1);
  try {
    rt.build({"no_such_program", ""});
    FAIL("expected an error");
  } catch (const Error& e) {
    CHECK(std::string(e.what()).find("no_such_program") != std::string::npos);
  }
}

TEST_CASE("profiling sums time per kernel") {
  auto& rt = Runtime::instance();
  rt.reset_timings();
  rt.set_profiling(true);
  Tensor a = Tensor::full({1024}, 1.0f), b = Tensor::full({1024}, 1.0f);
  for (int i = 0; i < 3; ++i) launch("elementwise", "axpby", {1024}, a, b, 1.0f, 1.0f, 1024);
  auto t = rt.timings();
  rt.set_profiling(false);
  REQUIRE(t.size() == 1);
  CHECK(t[0].kernel == "axpby");
  CHECK(t[0].launches == 3);
  CHECK(b.to_host()[5] == doctest::Approx(4.0f));
}

TEST_CASE("the pool's default cap: CPU devices keep a step's ~2 GiB of freed tensors, GPUs at most 1 GiB") {
  constexpr size_t GiB = size_t(1) << 30;
  using stylerf::host::default_pool_cap_bytes;
  CHECK(default_pool_cap_bytes(true, 6 * GiB + GiB / 2) == 3 * GiB + GiB / 4);  // PoCL's 6.5 GiB: half
  CHECK(default_pool_cap_bytes(true, 32 * GiB) == 8 * GiB);                     // large: a quarter
  CHECK(default_pool_cap_bytes(true, 12 * GiB) == 4 * GiB);                     // between: 4 GiB
  CHECK(default_pool_cap_bytes(true, 2 * GiB) == GiB);                          // small: half
  CHECK(default_pool_cap_bytes(false, 80 * GiB) == GiB);
  CHECK(default_pool_cap_bytes(false, 2 * GiB) == GiB / 2);
}

TEST_CASE("freed buffers are pooled and reused for the same size class") {
  auto& rt = Runtime::instance();
  rt.trim_buffer_pool();
  cl_mem first = nullptr;
  {
    Tensor a({1000, 100}, "pool test");
    first = a.mem();
  }
  CHECK(rt.pooled_bytes() >= 400000);
  Tensor b({1000, 100}, "pool test");
  CHECK(b.mem() == first);  // same buffer handed out again
  CHECK(rt.pooled_bytes() == 0);
  Tensor c({7}, "small");  // a different size class gets a new buffer
  CHECK(c.mem() != first);
  rt.trim_buffer_pool();
  CHECK(rt.pooled_bytes() == 0);
}

TEST_CASE("a buffer over a quarter of the pool's cap is released, not pooled") {
  auto& rt = Runtime::instance();
  rt.trim_buffer_pool();
  const int64_t quarter_floats = int64_t(rt.pool_cap_bytes() / 4 / sizeof(float));
  { Tensor big({quarter_floats + (int64_t(1) << 20)}, "one-off"); }  // untouched: no pages committed
  CHECK(rt.pooled_bytes() == 0);
  { Tensor small({1000}, "step temporary"); }
  CHECK(rt.pooled_bytes() > 0);
  rt.trim_buffer_pool();
}

TEST_CASE("the pool hands a buffer up to twice as large to a smaller request, and files it back by its own size") {
  auto& rt = Runtime::instance();
  rt.trim_buffer_pool();
  // Classes above 64 KiB step by 1/16 of the power of two: 4 MiB and 3.5 MiB lie in neighbouring classes.
  const int64_t big = int64_t(1) << 20, smaller = big - big / 8;  // floats: 4 MiB, 3.5 MiB
  cl_mem first = nullptr;
  {
    Tensor a({big}, "pool test");
    first = a.mem();
  }
  CHECK(rt.pooled_bytes() == size_t(4) << 20);
  {
    Tensor b({smaller}, "pool test");  // a smaller request reuses the 4 MiB buffer
    CHECK(b.mem() == first);
    CHECK(rt.pooled_bytes() == 0);
    b.fill(1.0f);
    CHECK(b.to_host()[size_t(smaller - 1)] == 1.0f);
  }
  // Filed back under 4 MiB (its real size), so a 4 MiB request finds it again.
  CHECK(rt.pooled_bytes() == size_t(4) << 20);
  {
    Tensor c({big}, "pool test");
    CHECK(c.mem() == first);
  }
  {
    Tensor d({big / 2}, "pool test");  // half the size: still the 4 MiB buffer
    CHECK(d.mem() == first);
  }
  {
    Tensor e({big / 4}, "pool test");  // a quarter: past twice its size, so a new buffer
    CHECK(e.mem() != first);
  }
  rt.trim_buffer_pool();
  CHECK(rt.pooled_bytes() == 0);
}

TEST_CASE("a fresh larger buffer releases the pooled ones it will serve from then on") {
  auto& rt = Runtime::instance();
  rt.trim_buffer_pool();
  const int64_t mib = int64_t(1) << 18;  // floats
  { Tensor small({2 * mib}, "pool test"); }  // 2 MiB, pooled
  { Tensor tiny({16}, "pool test"); }        // a small class: never superseded
  const size_t tiny_bytes = rt.pooled_bytes() - (size_t(2) << 20);
  {
    Tensor larger({3 * mib}, "pool test");  // 3 MiB: the 2 MiB buffer cannot serve it, so a fresh one
    CHECK(rt.pooled_bytes() == tiny_bytes);  // ... and the 2 MiB one goes
  }
  {
    Tensor again({2 * mib}, "pool test");  // served by the 3 MiB buffer
    CHECK(rt.pooled_bytes() == tiny_bytes);
  }
  { Tensor much_larger({5 * mib}, "pool test"); }  // 5 MiB: the pooled 3 MiB buffer is over half of it, so it goes
  CHECK(rt.pooled_bytes() == tiny_bytes + (size_t(5) << 20));
  rt.trim_buffer_pool();
}

TEST_CASE("a pooled buffer that no request takes for a while is released") {
  auto& rt = Runtime::instance();
  rt.trim_buffer_pool();
  { Tensor idle({int64_t(1) << 20}, "pool test"); }  // 4 MiB, pooled, then never asked for again
  CHECK(rt.pooled_bytes() == size_t(4) << 20);
  // Small tensors of another class keep allocating (one pooled buffer, handed out again and again).
  for (uint64_t i = 0; i < Runtime::kPoolIdleAllocations / 2; ++i) { Tensor t({16}, "step temporary"); }
  CHECK(rt.pooled_bytes() > size_t(4) << 20);  // half the idle time: still pooled
  for (uint64_t i = 0; i < Runtime::kPoolIdleAllocations; ++i) { Tensor t({16}, "step temporary"); }
  CHECK(rt.pooled_bytes() < size_t(4) << 20);  // released; the small one stays
  CHECK(rt.pooled_bytes() > 0);
  rt.trim_buffer_pool();
}
