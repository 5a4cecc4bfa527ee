// The module convention (lib/nn/module.hpp) and Adam over named parameters (lib/nn/adam.hpp): gradient
// accumulation, per-group learning rates, moments keyed by name through save/load and a remap, params
// without gradients skipped, checkpoint round trip by name, non-finite detection, clear errors.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/nn/adam.hpp"
#include "lib/nn/module.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;

namespace {
struct TwoParams : nn::Module {
  nn::Param grid{"grid", 0, Tensor::full({4}, 1.0f)};
  nn::Param net{"net", 1, Tensor::full({2, 3}, 1.0f)};
  nn::StateBuffer running{"running", Tensor::full({3}, 0.5f)};
  void collect_params(std::vector<nn::Param*>& out) override { out.push_back(&grid), out.push_back(&net); }
  void collect_buffers(std::vector<nn::StateBuffer*>& out) override { out.push_back(&running); }
};
}  // namespace

TEST_CASE("Param: backward accumulates; zero_grad clears; shape mismatch is an error naming the parameter") {
  TwoParams m;
  m.grid.accumulate(Tensor::full({4}, 2.0f));
  m.grid.accumulate(Tensor::full({4}, 0.5f));
  CHECK(m.grid.grad.to_host() == std::vector<float>(4, 2.5f));
  m.zero_grad();
  CHECK(m.grid.grad.to_host() == std::vector<float>(4, 0.0f));
  testing::expect_error([&] { m.net.accumulate(Tensor::zeros({5})); }, "gradient of net");
  CHECK(m.param_count() == 10);
}

TEST_CASE("Adam: per-group learning rates, the first step moves by lr, params without a gradient are skipped") {
  TwoParams m;
  nn::Adam adam({{"grid", 0.1f}, {"net", 0.01f}}, 0.9f, 0.99f);
  m.grid.accumulate(Tensor::full({4}, 3.0f));  // net has no gradient: untouched
  adam.step(m.params(), 0.5f);
  for (float x : m.grid.value.to_host()) CHECK(x == doctest::Approx(1.0f - 0.05f).epsilon(1e-5));
  CHECK(m.net.value.to_host() == std::vector<float>(6, 1.0f));
  m.net.accumulate(Tensor::full({2, 3}, -1.0f));
  adam.step({&m.net}, 1.0f);
  for (float x : m.net.value.to_host()) CHECK(x == doctest::Approx(1.0f + 0.01f).epsilon(1e-4));
  nn::Param stray("stray", 7, Tensor::zeros({1}));
  stray.accumulate(Tensor::zeros({1}));
  testing::expect_error([&] { adam.step({&stray}); }, "stray");
}

TEST_CASE("Adam: state saved and loaded by name continues exactly; remap carries moments through a reshape") {
  const auto dir = std::filesystem::temp_directory_path() / "stylerf_test_module_adam";
  std::filesystem::create_directories(dir);
  TwoParams a;
  nn::Adam oa({{"grid", 0.1f}, {"net", 0.01f}});
  for (int i = 0; i < 3; ++i) {
    a.zero_grad();
    a.grid.accumulate(Tensor::from_host({1, -2, 3, -4}, {4}));
    a.net.accumulate(Tensor::full({2, 3}, 0.3f));
    oa.step(a.params());
  }
  io::Checkpoint ck;
  ck.kind = "test";
  a.save(ck, "m.");
  oa.save(ck, "opt.");
  const std::string path = (dir / "adam.ckpt").string();
  io::save_checkpoint(path, ck);
  const auto back = io::load_checkpoint(path, "test");
  TwoParams b;
  b.load(back, "m.");
  nn::Adam ob({{"grid", 0.1f}, {"net", 0.01f}});
  ob.load(back, "opt.", b.params());
  CHECK(ob.steps() == 3);
  CHECK(b.running.value.to_host() == a.running.value.to_host());
  for (TwoParams* m : {&a, &b}) {
    m->zero_grad();
    m->grid.accumulate(Tensor::from_host({1, -2, 3, -4}, {4}));
    m->net.accumulate(Tensor::full({2, 3}, 0.3f));
  }
  oa.step(a.params());
  ob.step(b.params());
  CHECK(a.grid.value.to_host() == b.grid.value.to_host());
  CHECK(a.net.value.to_host() == b.net.value.to_host());

  // remap: the grid grows to 8 entries; its moments are carried by the same function.
  oa.remap("grid", [](const Tensor& t) {
    auto v = t.to_host();
    v.insert(v.end(), v.begin(), v.end());
    return Tensor::from_host(v, {8});
  });
  a.grid.value = Tensor::full({8}, 1.0f);
  a.grid.grad = Tensor();
  a.grid.accumulate(Tensor::full({8}, 1.0f));
  oa.step({&a.grid});
  CHECK(testing::all_finite(a.grid.value.to_host()));
  // A checkpoint whose parameter has another shape is refused with the names.
  TwoParams c;
  c.grid.value = Tensor::zeros({5});
  testing::expect_error([&] { c.load(back, "m."); }, "m.grid");
  std::filesystem::remove_all(dir);
}

TEST_CASE("Module: the first non-finite parameter or buffer is named") {
  TwoParams m;
  CHECK(m.first_nonfinite().empty());
  m.running.value = Tensor::from_host({0.0f, NAN, 1.0f}, {3});
  CHECK(m.first_nonfinite() == "running");
  m.net.value = Tensor::full({2, 3}, INFINITY);
  CHECK(m.first_nonfinite() == "net");
}
