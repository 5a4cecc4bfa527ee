// The ray pipeline (lib/model/ray_pipeline.hpp) as a whole: the composed render backward (march ->
// density -> weights -> keep -> head -> weighted sum -> background) against central finite differences of
// the forward, for the density grid and every head parameter; the feature field's two orders (basis per
// ray after compositing vs per point before) agree; hard cases (rays missing the box, an empty geometry).
#include <doctest/doctest.h>

#include <cmath>
#include <random>
#include <vector>

#include "host/tensor.hpp"
#include "lib/field/appearance_head.hpp"
#include "lib/model/density_model.hpp"
#include "lib/model/feature_field.hpp"
#include "lib/model/ray_pipeline.hpp"
#include "lib/model/rgb_head.hpp"
#include "tests/testing.hpp"

using namespace stylerf;
using host::Tensor;

namespace {

// A small geometry whose density is positive and moderate everywhere (planes and lines ~ N(1, 0.3): the
// relu never sits at its kink), distance scale 1 so rays stay partly transparent, and every sample kept
// (weight threshold 0), so the forward is a smooth function of every parameter.
model::Geometry small_geometry() {
  model::Geometry g;
  g.box_lo = {-1, -1, -1};
  g.box_hi = {1, 1, 1};
  g.near = 0;
  g.far = 10;
  g.act = field::DensityActivation::Relu;
  g.distance_scale = 1.0f;
  g.weight_threshold = 0.0f;
  g.density = field::VMGrid::create({6, 7, 5}, {2, 2, 2}, 0.3f, 11);
  auto v = g.density.params.to_host();
  for (auto& x : v) x += 0.6f;
  g.density.params.upload(v);
  g.update_step();
  return g;
}

// 6 rays from outside the box towards random points inside it, and one that misses the box.
void make_rays(Tensor& o, Tensor& d) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.7f, 0.7f);
  std::vector<float> ov, dv;
  for (int i = 0; i < 6; ++i) {
    const float origin[3] = {u(rng) + 3.0f * (i % 2 ? 1 : -1), u(rng), u(rng) - 2.5f};
    const float target[3] = {u(rng), u(rng), u(rng)};
    float dir[3], n = 0;
    for (int a = 0; a < 3; ++a) dir[a] = target[a] - origin[a], n += dir[a] * dir[a];
    for (int a = 0; a < 3; ++a) ov.push_back(origin[a]), dv.push_back(dir[a] / std::sqrt(n));
  }
  ov.insert(ov.end(), {5.0f, 5.0f, 5.0f});
  dv.insert(dv.end(), {0.0f, 0.0f, 1.0f});
  o = Tensor::from_host(ov, {7, 3});
  d = Tensor::from_host(dv, {7, 3});
}

// An RGB head over g's grid (6 appearance features, basis 5, hidden 8). Hidden biases of +3 keep every ReLU
// of the MLP active: with ~100 samples x 8 units, some pre-activation would otherwise sit within any
// finite-difference step of a kink (the MLP alone is tested at its kinks' sides in test_appearance).
model::RgbHead small_rgb_head(const model::Geometry& g, bool deferred) {
  field::AppearanceHeadConfig hc;
  hc.features = 6;
  hc.basis_dim = 5;
  hc.hidden = 8;
  field::AppearanceHead mlp = field::AppearanceHead::create(hc, 13);
  mlp.b1.fill(3.0f);
  mlp.b2.fill(3.0f);
  return model::RgbHead(field::VMGrid::create(g.res(), {2, 2, 2}, 0.5f, 12), mlp, deferred);
}

// Compares p's accumulated gradient with central differences of loss() at a few entries of p.
void check_param_fd(nn::Param& p, const std::function<double()>& loss, int probes, double h, const std::string& what) {
  const auto grad = p.grad.to_host();
  auto values = p.value.to_host();
  std::mt19937 rng(17);
  std::vector<float> got;
  std::vector<double> want;
  for (int i = 0; i < probes; ++i) {
    const size_t k = rng() % values.size();
    const float x0 = values[k];
    values[k] = x0 + float(h);
    p.value.upload(values);
    const double lp = loss();
    values[k] = x0 - float(h);
    p.value.upload(values);
    const double lm = loss();
    values[k] = x0;
    p.value.upload(values);
    got.push_back(grad[k]);
    want.push_back((lp - lm) / (2 * h));
  }
  // Float forward, h 1e-2: rounding noise ~1e-5 / 2e-2 in the quotient, truncation O(h^2).
  testing::check_close(got, want, 2e-2, 2e-3, what);
}

double dot_host(const Tensor& t, const std::vector<double>& g) {
  const auto v = t.to_host();
  double s = 0;
  for (size_t i = 0; i < v.size(); ++i) s += v[i] * g[i];
  return s;
}

}  // namespace

TEST_CASE("ray pipeline: the composed render backward (RGB head, background) matches finite differences") {
  model::Geometry g = small_geometry();
  model::RgbHead head = small_rgb_head(g, false);
  Tensor o, d;
  make_rays(o, d);
  model::RayOptions opt;
  opt.background = Tensor::from_host({0.9f, 0.2f, 0.4f}, {3});
  const auto G = testing::to_double(testing::random_normal(7 * 3, 21));
  nn::Param density("density", 0, g.density.params);
  auto loss = [&] {
    g.density.params = density.value;
    return dot_host(model::render_rays(g, head, o, d, opt, nullptr).value, G);
  };
  model::RayContext ctx;
  auto out = model::render_rays(g, head, o, d, opt, &ctx);
  CHECK(out.samples > 20);
  CHECK(out.kept == out.samples);  // threshold 0: every sample kept
  // The missing ray shows the background exactly.
  const auto val = out.value.to_host();
  CHECK(val[18] == doctest::Approx(0.9f));
  CHECK(val[20] == doctest::Approx(0.4f));
  head.zero_grad();
  model::render_rays_backward(g, head, ctx, Tensor::from_host(std::vector<float>(G.begin(), G.end()), {7, 3}),
                              Tensor(), &density.grad_buffer());
  check_param_fd(density, loss, 24, 1e-2, "d density grid");
  for (nn::Param* p : head.params()) check_param_fd(*p, loss, 12, 1e-2, "d " + p->name);
}

TEST_CASE("ray pipeline: the feature field's backward (grid, basis, background, kept opacity) matches FD") {
  model::Geometry g = small_geometry();
  g.has_background = true;  // the field learns a background feature
  model::FeatureFieldConfig fc;
  fc.rank = {3, 2, 2};
  fc.channels = 16;
  fc.init_scale = 0.5f;
  model::FeatureField f = model::FeatureField::create(g, fc, 3);
  REQUIRE(f.background.value.defined());
  f.background.value.upload(testing::random_normal(16, 29));
  Tensor o, d;
  make_rays(o, d);
  const auto G = testing::to_double(testing::random_normal(7 * 16, 22));
  const auto Ga = testing::to_double(testing::random_normal(7, 23));
  auto loss = [&] {
    auto r = f.render(g, o, d, {}, nullptr);
    return dot_host(r.value, G) + dot_host(r.kept_acc, Ga);
  };
  model::FeatureField::Context ctx;
  f.render(g, o, d, {}, &ctx);
  f.zero_grad();
  f.render_backward(g, ctx, Tensor::from_host(std::vector<float>(G.begin(), G.end()), {7, 16}),
                    Tensor::from_host(std::vector<float>(Ga.begin(), Ga.end()), {7}));
  for (nn::Param* p : f.params()) check_param_fd(*p, loss, 24, 1e-2, "d " + p->name);

  // The density gradient through the feature head (stage 2 freezes it, the pipeline still supports it).
  nn::Param density("density", 0, g.density.params);
  auto loss_d = [&] {
    g.density.params = density.value;
    auto r = model::render_rays(g, f.head, o, d, {}, nullptr);
    return dot_host(r.value, std::vector<double>(G.begin(), G.begin() + 7 * 7)) + dot_host(r.kept_acc, Ga);
  };
  model::RayContext rc;
  model::render_rays(g, f.head, o, d, {}, &rc);
  f.zero_grad();
  std::vector<float> g7(G.begin(), G.begin() + 7 * 7);
  model::render_rays_backward(g, f.head, rc, Tensor::from_host(g7, {7, 7}),
                              Tensor::from_host(std::vector<float>(Ga.begin(), Ga.end()), {7}),
                              &density.grad_buffer());
  check_param_fd(density, loss_d, 24, 1e-2, "d density grid (feature head)");
}

TEST_CASE("feature field: compositing first and applying the basis per ray equals the per-point order") {
  model::Geometry g = small_geometry();
  g.weight_threshold = 1e-4f;  // as in training: dropped samples are dropped in both orders alike
  g.has_background = true;
  model::FeatureFieldConfig fc;
  fc.rank = {8, 8, 8};
  model::FeatureField f = model::FeatureField::create(g, fc, 4);
  f.background.value.upload(testing::random_normal(256, 30));
  Tensor o, d;
  make_rays(o, d);
  const auto a = f.render(g, o, d, {}, nullptr), b = f.render_per_point(g, o, d, {});
  CHECK(a.value.shape() == host::Shape{7, 256});
  std::vector<double> want;
  for (float x : b.value.to_host()) want.push_back(x);
  testing::check_close(a.value.to_host(), want, 1e-5, 1e-6, "basis per ray vs per point");
  CHECK(a.kept_acc.to_host() == b.kept_acc.to_host());
}

TEST_CASE("ray pipeline: no samples at all (every ray misses) gives the background, zero opacity, no gradient") {
  model::Geometry g = small_geometry();
  model::FeatureField f = model::FeatureField::create(g, {}, 5);
  Tensor o = Tensor::from_host({5, 5, 5, -5, 5, 5}, {2, 3}), d = Tensor::from_host({0, 0, 1, 0, 1, 0}, {2, 3});
  model::FeatureField::Context ctx;
  auto r = f.render(g, o, d, {}, &ctx);
  CHECK(r.samples == 0);
  CHECK(r.value.to_host() == std::vector<float>(2 * 256, 0.0f));
  CHECK(r.acc.to_host() == std::vector<float>{0.0f, 0.0f});
  f.zero_grad();
  f.render_backward(g, ctx, Tensor::full({2, 256}, 1.0f), Tensor());
  CHECK(f.basis.grad.to_host() == std::vector<float>(f.basis.value.numel(), 0.0f));
}

namespace {

// A density model on small_geometry with the given shading.
model::DensityModel small_density_model(bool deferred, bool background) {
  model::DensityModel m;
  m.geo = small_geometry();
  m.geo.has_background = background;
  m.geo.background = {0.9f, 0.2f, 0.4f};
  m.cfg.deferred_shading = deferred;
  m.cfg.view_dependent = false;
  m.rgb = small_rgb_head(m.geo, deferred);
  return m;
}

// Every parameter of m (density grid, appearance grid, MLP) against central differences of G . render().
void check_model_fd(model::DensityModel& m, const Tensor& o, const Tensor& d, const std::vector<double>& G) {
  const int64_t R = o.dim(0);
  auto loss = [&] { return dot_host(m.render(o, d, false, 0, nullptr).value, G); };
  model::RayContext ctx;
  m.render(o, d, false, 0, &ctx);
  m.zero_grad();
  m.render_backward(ctx, Tensor::from_host(std::vector<float>(G.begin(), G.end()), {R, 3}));
  for (nn::Param* p : m.params()) check_param_fd(*p, loss, p->name == "density" ? 24 : 12, 1e-2, "d " + p->name);
}

}  // namespace

TEST_CASE("deferred shading: the density model's backward (features, opacity, MLP, background) matches FD") {
  for (bool background : {false, true}) {
    CAPTURE(background);
    model::DensityModel m = small_density_model(true, background);
    Tensor o, d;
    make_rays(o, d);
    const auto out = m.render(o, d, false, 0, nullptr);
    CHECK(out.value.dim(1) == 3);
    // The ray that misses the box: opacity 0, so the colour is the background (or 0 without one).
    const auto v = out.value.to_host();
    CHECK(v[18] == doctest::Approx(background ? 0.9f : 0.0f));
    check_model_fd(m, o, d, testing::to_double(testing::random_normal(7 * 3, 22)));
  }
}

TEST_CASE("an opacity term (the backdrop's): its gradient through the density model matches FD, both shadings") {
  // loss = G . colour + A . acc: the density stage's backdrop term is A = weight / R on backdrop rays.
  for (bool deferred : {false, true}) {
    CAPTURE(deferred);
    model::DensityModel m = small_density_model(deferred, true);
    Tensor o, d;
    make_rays(o, d);
    const auto G = testing::to_double(testing::random_normal(7 * 3, 23));
    const auto A = testing::to_double(testing::random_normal(7, 24));
    auto loss = [&] {
      const auto r = m.render(o, d, false, 0, nullptr);
      return dot_host(r.value, G) + dot_host(r.acc, A);
    };
    model::RayContext ctx;
    m.render(o, d, false, 0, &ctx);
    m.zero_grad();
    m.render_backward(ctx, Tensor::from_host(std::vector<float>(G.begin(), G.end()), {7, 3}),
                      Tensor::from_host(std::vector<float>(A.begin(), A.end()), {7}));
    check_param_fd(m.density_param(), loss, 24, 1e-2, "d density grid");
    // The term reaches only the geometry: the colour head's gradients are those of G alone.
    std::vector<std::vector<float>> with_term;
    for (nn::Param* p : m.params())
      if (p->name != "density") with_term.push_back(p->grad.to_host());
    m.zero_grad();
    m.render_backward(ctx, Tensor::from_host(std::vector<float>(G.begin(), G.end()), {7, 3}));
    size_t k = 0;
    for (nn::Param* p : m.params())
      if (p->name != "density") {
        const auto& want = with_term[k++];
        testing::check_close(p->grad.to_host(), std::vector<double>(want.begin(), want.end()), 1e-6, 1e-6, "d " + p->name);
      }
  }
}

TEST_CASE("deferred shading equals per-sample shading when one sample carries each ray") {
  // A very dense grid stops every ray at its first sample (weight ~1), so shading the weighted mean feature
  // is shading that sample: the two models agree.
  model::DensityModel per = small_density_model(false, true), def = small_density_model(true, true);
  for (model::DensityModel* m : {&per, &def}) m->geo.density.params.fill(30.0f);
  Tensor o, d;
  make_rays(o, d);
  testing::check_close(def.render(o, d, false, 0, nullptr).value.to_host(),
                       testing::to_double(per.render(o, d, false, 0, nullptr).value.to_host()), 1e-4, 1e-5,
                       "deferred vs per-sample colour");
}

TEST_CASE("early termination: the render backward is exact for the samples kept (FD), and the colour barely moves") {
  // Density high enough that rays stop inside the box: the cut is a fixed set under the FD steps.
  model::DensityModel m = small_density_model(false, true);
  auto v = m.geo.density.params.to_host();
  for (auto& x : v) x += 0.6f;
  m.geo.density.params.upload(v);
  m.geo.weight_threshold = 1e-4f;
  Tensor o, d;
  make_rays(o, d);
  m.geo.ert_threshold = 0.0f;
  const auto full = m.render(o, d, false, 0, nullptr);
  m.geo.ert_threshold = 1e-4f;
  const auto cut = m.render(o, d, false, 0, nullptr);
  CHECK(cut.samples < full.samples * 3 / 4);
  CHECK(cut.kept == full.kept);  // every sample past the stop weighs < 1e-4: none was kept anyway
  testing::check_close(cut.value.to_host(), testing::to_double(full.value.to_host()), 0, 1e-4, "colour with/without");
  check_model_fd(m, o, d, testing::to_double(testing::random_normal(7 * 3, 23)));
}

namespace {

// Heads for the grouped renderer: the sample's position as its attributes, and a shading of them done on
// the host in double (any function will do; the renderer only moves rows around it).
class PositionHead : public model::SampleHead {
 public:
  int channels() const override { return 3; }
  Tensor forward(const Tensor& pos, const Tensor&, std::unique_ptr<Context>*) const override { return pos.clone(); }
  void backward(const Context&, const Tensor&) override {}
  void collect_params(std::vector<nn::Param*>&) override {}
};

using HostShade = std::function<std::vector<double>(const std::vector<double>& x)>;  // 3 -> 2 channels
Tensor shade_rows(const Tensor& x, const HostShade& f) {
  const auto v = x.to_host();
  std::vector<float> out;
  for (size_t i = 0; i < v.size(); i += 3)
    for (double y : f({v[i], v[i + 1], v[i + 2]})) out.push_back(float(y));
  return Tensor::from_host(out, {x.dim(0), 2});
}

// The per-sample order: shade each kept sample, composite per ray (what the groups approximate).
class ShadedHead : public model::SampleHead {
 public:
  explicit ShadedHead(HostShade f) : f_(std::move(f)) {}
  int channels() const override { return 2; }
  Tensor forward(const Tensor& pos, const Tensor&, std::unique_ptr<Context>*) const override { return shade_rows(pos, f_); }
  void backward(const Context&, const Tensor&) override {}
  void collect_params(std::vector<nn::Param*>&) override {}

 private:
  HostShade f_;
};

// Rays [R, 3] repeated `times` times each, consecutively.
Tensor repeat_rows(const Tensor& x, int times) {
  const auto v = x.to_host();
  std::vector<float> out;
  for (size_t i = 0; i < v.size(); i += 3)
    for (int k = 0; k < times; ++k) out.insert(out.end(), v.begin() + i, v.begin() + i + 3);
  return Tensor::from_host(out, {x.dim(0) * times, 3});
}

}  // namespace

TEST_CASE("grouped rays: geometry per sub-ray, the shade once per depth step; exact for linear shades") {
  model::Geometry g = small_geometry();
  g.weight_threshold = 1e-3f;
  Tensor o, d;
  make_rays(o, d);  // 7 rays, the last one missing the box
  const PositionHead position;
  const HostShade linear = [](const std::vector<double>& x) {
    return std::vector<double>{2 * x[0] - x[1] + 0.5, x[2] + 3 * x[1]};
  };
  const HostShade curved = [](const std::vector<double>& x) {
    return std::vector<double>{std::exp(2 * x[0]) * x[1], std::sin(3 * x[2]) + x[0] * x[0]};
  };
  auto shade_fn = [](const HostShade& f) { return model::ShadeFn([f](const Tensor& x) { return shade_rows(x, f); }); };
  auto per_ray = [&](const Tensor& oo, const Tensor& dd, const HostShade& f) {
    return model::render_rays(g, ShadedHead(f), oo, dd, {}, nullptr);
  };
  auto as_double = [](const Tensor& t) { return testing::to_double(t.to_host()); };

  // One ray a group: render_rays exactly, whatever the shade.
  for (const HostShade* f : {&linear, &curved}) {
    const auto got = model::render_ray_groups(g, position, shade_fn(*f), 2, o, d, 1);
    const auto want = per_ray(o, d, *f);
    testing::check_close(got.value.to_host(), as_double(want.value), 1e-6, 1e-7, "group of 1: values");
    CHECK(got.kept_acc.to_host() == want.kept_acc.to_host());
    CHECK(got.acc.to_host() == want.acc.to_host());
    CHECK(got.depth.to_host() == want.depth.to_host());
    CHECK(got.merged == got.kept);
  }
  // A group of 4 copies of each ray: every step merges 4 identical samples into the ray's own sample.
  {
    const auto got = model::render_ray_groups(g, position, shade_fn(curved), 2, repeat_rows(o, 4), repeat_rows(d, 4), 4);
    const auto want = per_ray(o, d, curved);
    CHECK(got.value.shape() == host::Shape{7, 2});
    CHECK(got.merged * 4 == got.kept);
    testing::check_close(got.value.to_host(), as_double(want.value), 1e-5, 1e-6, "identical sub-rays: values");
    testing::check_close(got.kept_acc.to_host(), as_double(want.kept_acc), 1e-5, 1e-7, "identical sub-rays: kept acc");
  }
  // Distinct rays in groups of 3 (rays 0-2, 3-5): opacity and depth stay per sub-ray; the kept opacity and
  // a linear shade are exactly the groups' means of the per-ray renders; a curved shade is not (the test
  // rays do share steps), but stays close.
  const auto oh = o.to_host(), dh = d.to_host();
  const Tensor o6 = Tensor::from_host(std::vector<float>(oh.begin(), oh.begin() + 18), {6, 3});
  const Tensor d6 = Tensor::from_host(std::vector<float>(dh.begin(), dh.begin() + 18), {6, 3});
  auto group_mean = [](const Tensor& t, int C) {
    const auto v = t.to_host();
    std::vector<double> m(size_t(2 * C), 0.0);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < C; ++c) m[size_t((r / 3) * C + c)] += v[size_t(r * C + c)] / 3.0;
    return m;
  };
  const auto lin = model::render_ray_groups(g, position, shade_fn(linear), 2, o6, d6, 3);
  const auto lin_rays = per_ray(o6, d6, linear);
  CHECK(lin.merged < lin.kept);
  testing::check_close(lin.value.to_host(), group_mean(lin_rays.value, 2), 1e-5, 1e-6, "linear shade: group means");
  testing::check_close(lin.kept_acc.to_host(), group_mean(lin_rays.kept_acc, 1), 1e-5, 1e-7, "kept acc: group means");
  CHECK(lin.acc.to_host() == lin_rays.acc.to_host());
  CHECK(lin.depth.to_host() == lin_rays.depth.to_host());
  // Slabs of 3 steps merge more (samples of one ray too) and stay exact for a linear shade.
  const auto slab = model::render_ray_groups(g, position, shade_fn(linear), 2, o6, d6, 3, 3);
  CHECK(slab.merged < lin.merged);
  testing::check_close(slab.value.to_host(), group_mean(lin_rays.value, 2), 1e-5, 1e-6, "3-step slabs: group means");
  testing::check_close(slab.kept_acc.to_host(), group_mean(lin_rays.kept_acc, 1), 1e-5, 1e-7, "3-step slabs: kept acc");
  const auto cur = model::render_ray_groups(g, position, shade_fn(curved), 2, o6, d6, 3);
  const auto cur_mean = group_mean(per_ray(o6, d6, curved).value, 2);
  double worst = 0, differs = 0;
  const auto cv = cur.value.to_host();
  for (size_t i = 0; i < cv.size(); ++i) {
    worst = testing::max_or_nan(worst, std::abs(cv[i] - cur_mean[i]) / (1 + std::abs(cur_mean[i])));
    differs = std::max(differs, std::abs(cv[i] - cur_mean[i]));
  }
  CHECK(differs > 1e-4);
  CHECK(worst < 0.5);
  // Rays that all miss: zeros, no samples; a ray count that is not whole groups: a clear error.
  const Tensor miss_o = Tensor::from_host({5, 5, 5, 5, 5, 5}, {2, 3}), miss_d = Tensor::from_host({0, 0, 1, 0, 0, 1}, {2, 3});
  const auto none = model::render_ray_groups(g, position, shade_fn(linear), 2, miss_o, miss_d, 2);
  CHECK(none.samples == 0);
  CHECK(none.value.to_host() == std::vector<float>{0.0f, 0.0f});
  CHECK(none.acc.to_host() == std::vector<float>{0.0f, 0.0f});
  testing::expect_error([&] { model::render_ray_groups(g, position, shade_fn(linear), 2, o, d, 2); }, "whole groups");
  testing::expect_error([&] { model::render_ray_groups(g, position, shade_fn(linear), 2, o, d, 1, 0); }, "steps_per_point");
}
