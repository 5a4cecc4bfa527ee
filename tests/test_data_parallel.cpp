// Data parallelism in one process (lib/train/data_parallel.hpp, host/dist.hpp): a step's gradient summed over
// its sub-batches and averaged, the sub-batches' moves of running statistics averaged, a rank's share of
// sub-batches, and the slices of a ray batch. The same calls over several ranks are tested under mpirun
// (tests/python/test_mpi.py).
#include <doctest/doctest.h>

#include "host/dist.hpp"
#include "host/error.hpp"
#include "lib/features/feature_sampler.hpp"
#include "lib/nn/module.hpp"
#include "lib/scene/rays.hpp"
#include "lib/train/data_parallel.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;

namespace {
struct TwoParams : nn::Module {
  nn::Param a{"a", 0, Tensor::full({3}, 1.0f)};
  nn::Param b{"b", 1, Tensor::full({2, 2}, 1.0f)};
  nn::StateBuffer running{"running", Tensor::full({2}, 0.5f)};
  void collect_params(std::vector<nn::Param*>& out) override { out.push_back(&a), out.push_back(&b); }
  void collect_buffers(std::vector<nn::StateBuffer*>& out) override { out.push_back(&running); }
};
}  // namespace

TEST_CASE("one process is rank 0 of 1: every sub-batch is its own, collectives return what they are given") {
  host::Dist& dist = host::Dist::world();
  REQUIRE(dist.size() == 1);
  for (int j = 0; j < 5; ++j) CHECK(train::my_share(j, dist));
  CHECK(dist.broadcast(2.5) == 2.5);
  std::vector<double> v{1, -2};
  dist.allreduce_sum(v);
  CHECK(v == std::vector<double>{1, -2});
}

TEST_CASE("GradientSum: the mean of the sub-batches' gradients, each taken off and zeroed; none is an error") {
  TwoParams m;
  host::Dist& dist = host::Dist::world();
  train::GradientSum sum;
  m.a.accumulate(Tensor::from_host({1, 2, 3}, {3}));
  m.b.accumulate(Tensor::full({2, 2}, 4.0f));
  sum.add(m.params());
  CHECK(m.a.grad.to_host() == std::vector<float>(3, 0.0f));  // the next sub-batch starts from zero
  m.a.accumulate(Tensor::from_host({3, 2, 1}, {3}));          // b: no gradient in this sub-batch
  sum.add(m.params());
  const train::SyncCost c = sum.average(m.params(), 2, dist);
  CHECK(m.a.grad.to_host() == std::vector<float>{2, 2, 2});
  CHECK(m.b.grad.to_host() == std::vector<float>(4, 2.0f));
  CHECK(c.bytes == 7 * int64_t(sizeof(float)));
  // A rank with no sub-batch in the step contributes zeros.
  train::GradientSum none;
  none.average(m.params(), 1, dist);
  CHECK(m.a.grad.to_host() == std::vector<float>(3, 0.0f));
  testing::expect_error([&] { none.average(m.params(), 0, dist); }, "no sub-batch");
  train::GradientSum mixed;
  mixed.add(m.params());
  testing::expect_error([&] { mixed.add({&m.a}); }, "the params changed within a step");
}

TEST_CASE("BufferMoves: each sub-batch moves the statistics from the step's start; the step keeps their mean") {
  TwoParams m;
  host::Dist& dist = host::Dist::world();
  {
    train::BufferMoves moves(m.buffers());
    moves.restart();
    m.running.value.upload({1.0f, 0.0f});
    moves.add();
    moves.restart();
    CHECK(m.running.value.to_host() == std::vector<float>{0.5f, 0.5f});  // back at the start
    m.running.value.upload({0.0f, 2.0f});
    moves.add();
    moves.finish(dist);
    CHECK(m.running.value.to_host() == std::vector<float>{0.5f, 1.0f});
  }
  {
    train::BufferMoves moves(m.buffers());
    m.running.value.upload({9.0f, 9.0f});  // a sub-batch that moved them, then was skipped (no add)
    moves.finish(dist);
    CHECK(m.running.value.to_host() == std::vector<float>{0.5f, 1.0f});
  }
}

TEST_CASE("slices of a ray batch keep every field's rows together; out-of-range slices are refused") {
  scene::Rays r;
  for (int i = 0; i < 4; ++i) {
    for (int k = 0; k < 3; ++k) {
      r.origins.push_back(float(10 * i + k));
      r.directions.push_back(float(-10 * i - k));
      r.rgb.push_back(float(i));
    }
    r.pixel.push_back(100 + i);
  }
  const scene::Rays s = scene::slice(r, 1, 2);
  CHECK(s.size() == 2);
  CHECK(s.origins == std::vector<float>{10, 11, 12, 20, 21, 22});
  CHECK(s.directions == std::vector<float>{-10, -11, -12, -20, -21, -22});
  CHECK(s.rgb == std::vector<float>{1, 1, 1, 2, 2, 2});
  CHECK(s.pixel == std::vector<int>{101, 102});
  CHECK(scene::slice(r, 0, 4).origins == r.origins);
  testing::expect_error([&] { scene::slice(r, 3, 2); }, "slice [3, 5) of a batch of 4");
  features::FeatureRays f;
  f.rays = r;
  f.view = {0, 1, 2, 3};
  f.pixel_xy = {0, 0, 1, 1, 2, 2, 3, 3};
  const features::FeatureRays g = features::slice(f, 2, 2);
  CHECK(g.view == std::vector<int32_t>{2, 3});
  CHECK(g.pixel_xy == std::vector<float>{2, 2, 3, 3});
  CHECK(g.rays.pixel == std::vector<int>{102, 103});
}
