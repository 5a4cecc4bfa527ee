// nn::ConvStack and the decoders built on it (lib/nn/decoder.hpp):
//  - a stack from a spec: forward against a double-precision reference (convs, ReLU, x2 upsampling),
//    backward (input and every weight and bias) against central differences of that reference;
//  - the module convention: grads accumulate (two backward calls give twice one), need_dx = false
//    leaves the parameter gradients unchanged, contexts are per call;
//  - hard sizes: a 1x1 input (zero padding runs it; reflect padding refuses it with an error naming the
//    layer, before launching anything), 2x2 (the smallest reflect input), a 1-pixel side after nothing;
//  - files: save/load round trips (AdaIN's Sequential keys, both paddings), checkpoints through
//    Module::save/load, names shared between a spec-built and a file-loaded stack;
//  - the real AdaIN decoder: ConvStack's forward is bit-identical to the op chain the previous
//    AdainDecoder ran, and the fast decoder takes exactly AdaIN's convs 2..9.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <unistd.h>
#include <vector>

#include "host/error.hpp"
#include "lib/io/checkpoint.hpp"
#include "lib/io/safetensors.hpp"
#include "lib/nn/conv_stack.hpp"
#include "lib/nn/decoder.hpp"
#include "lib/nn/weights.hpp"
#include "tests/conv_reference.hpp"
#include "tests/testing.hpp"

namespace fs = std::filesystem;
using namespace stylerf;
using host::Tensor;
using nn::ConvStack;
using nn::ConvStackSpec;
using nn::Padding;
using testing::check_close;
using testing::RefTensor;
using testing::to_double;

namespace {

std::string temp_file(const std::string& name) {
  return (fs::temp_directory_path() / ("stylerf_test_conv_stack_" + std::to_string(::getpid()) + "_" + name)).string();
}

ConvStackSpec spec_of(std::vector<int> channels, std::vector<bool> ups, Padding pad, const std::string& prefix = "s.") {
  ConvStackSpec s;
  s.channels = std::move(channels);
  s.upsample_after = std::move(ups);
  s.pad = pad;
  s.name_prefix = prefix;
  return s;
}

// A stack's parameters in double, by layer: what the reference runs on (and what FD perturbs).
struct RefParams {
  std::vector<std::vector<double>> w, b;
};

RefParams params_of(const ConvStack& s) {
  RefParams p;
  for (const auto& l : s.layers()) {
    p.w.push_back(to_double(l.w.value.to_host()));
    p.b.push_back(to_double(l.b.value.to_host()));
  }
  return p;
}

// The stack in double for one image [C,H,W], written from the spec (not from ConvStack's layers).
RefTensor ref_stack(const ConvStackSpec& spec, const RefParams& p, RefTensor x) {
  const size_t n = spec.channels.size() - 1;
  for (size_t i = 0; i < n; ++i) {
    x = testing::ref_conv(x, p.w[i], p.b[i], spec.channels[i + 1], 3, spec.pad == Padding::Reflect);
    if (i + 1 < n) testing::ref_relu(x);
    if (!spec.upsample_after.empty() && spec.upsample_after[i]) x = testing::ref_upsample(x);
  }
  return x;
}

std::vector<float> pick(const std::vector<float>& v, const std::vector<size_t>& idx) {
  std::vector<float> out;
  for (size_t i : idx) out.push_back(v[i]);
  return out;
}

// Forward vs the reference, then every gradient vs central differences of L = <g, stack(x)>, for an
// input of H x W (N = 1). The stack is piecewise linear (ReLU); h = 1e-5 in double keeps every
// perturbation away from the kinks for these random values, so the quotients are exact to ~1e-9.
// Tolerances: float convs over <= 9 * 6 = 54 terms per output, chained over 3 layers: 1e-4.
void check_stack(const ConvStackSpec& spec, int H, int W, uint64_t seed) {
  CAPTURE(spec.describe());
  CAPTURE(H);
  CAPTURE(W);
  ConvStack s(spec, seed);
  // Non-zero biases, so the bias gradient and its use in forward are exercised too.
  for (nn::Param* q : s.params())
    if (q->name.size() > 5 && q->name.compare(q->name.size() - 5, 5, ".bias") == 0)
      q->value.upload(testing::random_normal(size_t(q->value.numel()), seed + 7, 0.2f));
  const RefParams p = params_of(s);
  const int cin = spec.channels.front();
  auto x = testing::random_normal(size_t(cin) * H * W, seed + 1);
  ConvStack::Ctx ctx;
  Tensor y = s.forward(Tensor::from_host(x, {1, cin, H, W}), &ctx);
  const RefTensor yr = ref_stack(spec, p, RefTensor{cin, H, W, to_double(x)});
  REQUIRE(y.shape() == host::Shape{1, yr.C, yr.H, yr.W});
  check_close(y.to_host(), yr.v, 1e-4, 1e-4, "stack forward");

  auto g = testing::random_normal(yr.v.size(), seed + 2);
  const auto gd = to_double(g);
  Tensor dx = s.backward(ctx, Tensor::from_host(g, y.shape()));
  auto loss_x = [&](const std::vector<double>& v) { return testing::dot(gd, ref_stack(spec, p, {cin, H, W, v}).v); };
  check_close(dx.to_host(), testing::finite_difference(loss_x, to_double(x), 1e-5), 1e-4, 1e-4, "stack dx");

  for (size_t i = 0; i < s.layers().size(); ++i) {
    const auto& l = s.layers()[i];
    REQUIRE(l.w.grad.defined());
    REQUIRE(l.b.grad.defined());
    auto idx = std::vector<size_t>{0, p.w[i].size() / 3, p.w[i].size() / 2, p.w[i].size() - 1};
    auto fw = testing::finite_difference_at(
        [&](const std::vector<double>& v) {
          RefParams q = p;
          q.w[i] = v;
          return testing::dot(gd, ref_stack(spec, q, {cin, H, W, to_double(x)}).v);
        },
        p.w[i], idx, 1e-5);
    check_close(pick(l.w.grad.to_host(), idx), fw, 1e-4, 1e-4, "stack d" + l.w.name);
    auto fb = testing::finite_difference(
        [&](const std::vector<double>& v) {
          RefParams q = p;
          q.b[i] = v;
          return testing::dot(gd, ref_stack(spec, q, {cin, H, W, to_double(x)}).v);
        },
        p.b[i], 1e-5);
    check_close(l.b.grad.to_host(), fb, 1e-4, 1e-4, "stack d" + l.b.name);
  }
}

// The stack fed the four grid phases of one map (forward's phase_input), in double: each phase through
// the layers up to the first upsampling, interleaved there (testing::ref_interleave), then the rest.
RefTensor ref_stack_phases(const ConvStackSpec& spec, const RefParams& p, std::vector<RefTensor> ph) {
  const size_t n = spec.channels.size() - 1;
  size_t i = 0;
  bool interleaved = false;
  for (; i < n && !interleaved; ++i) {
    for (RefTensor& x : ph) {
      x = testing::ref_conv(x, p.w[i], p.b[i], spec.channels[i + 1], 3, spec.pad == Padding::Reflect);
      if (i + 1 < n) testing::ref_relu(x);
    }
    interleaved = spec.upsample_after[i];
  }
  RefTensor x = testing::ref_interleave(ph);
  for (; i < n; ++i) {
    x = testing::ref_conv(x, p.w[i], p.b[i], spec.channels[i + 1], 3, spec.pad == Padding::Reflect);
    if (i + 1 < n) testing::ref_relu(x);
    if (spec.upsample_after[i]) x = testing::ref_upsample(x);
  }
  return x;
}

std::vector<RefTensor> split_phases(const std::vector<double>& v, int C, int H, int W) {
  std::vector<RefTensor> ph;
  const size_t n = size_t(C) * H * W;
  for (size_t k = 0; k < 4; ++k) ph.push_back({C, H, W, std::vector<double>(v.begin() + long(k * n), v.begin() + long((k + 1) * n))});
  return ph;
}

std::vector<float> host_of(const Tensor& t) { return t.to_host(); }

}  // namespace

TEST_CASE("conv stack: forward and backward against the reference (reflect and zero padding, upsampling)") {
  check_stack(spec_of({3, 5, 4, 2}, {true, false, false}, Padding::Reflect), 3, 4, 10);
  check_stack(spec_of({2, 4, 3}, {false, false}, Padding::Zero), 4, 3, 20);
  check_stack(spec_of({4, 3}, {}, Padding::Reflect), 5, 6, 30);  // a single conv: no ReLU at all
  // The smallest reflect input, with an upsampling between.
  check_stack(spec_of({2, 3, 2}, {true, false}, Padding::Reflect), 2, 2, 40);
}

TEST_CASE("conv stack: a 1x1 input runs with zero padding and is refused with reflect padding") {
  // Zero padding: every tap but the centre is a zero; an upsampling makes the next conv see 2x2.
  check_stack(spec_of({3, 4, 2}, {true, false}, Padding::Zero), 1, 1, 50);
  // Reflect padding of a 1-pixel side would read index 1 of a 1-element row (out of bounds). PyTorch's
  // ReflectionPad2d refuses it; so does the stack, before any kernel runs, naming the layer.
  ConvStack r(spec_of({3, 4, 2}, {true, false}, Padding::Reflect, "dec."), 1);
  testing::expect_error([&] { r.forward(Tensor::zeros({1, 3, 1, 1})); },
                        "ConvStack 'dec.'::forward: conv 1 of 2 ('dec.1.weight') would get a 1x1 input; reflect "
                        "padding needs H, W >= 2");
  testing::expect_error([&] { r.forward(Tensor::zeros({1, 3, 5, 1})); }, "would get a 5x1 input");
  ConvStack::Ctx ctx;
  r.forward(Tensor::zeros({1, 3, 2, 2}), &ctx);  // fine: 2x2 is the smallest reflect input
  CHECK(ctx.inputs.size() == 2);
  CHECK(ctx.inputs[1].shape() == host::Shape{1, 4, 4, 4});
}

TEST_CASE("conv stack: gradients accumulate over backward calls; need_dx = false; per-call contexts") {
  const ConvStackSpec spec = spec_of({3, 4, 4, 3}, {false, true, false}, Padding::Reflect);
  ConvStack s(spec, 7);
  auto x1 = testing::random_normal(3 * 4 * 5, 1), x2 = testing::random_normal(3 * 4 * 5, 2);
  ConvStack::Ctx c1, c2;
  Tensor y1 = s.forward(Tensor::from_host(x1, {1, 3, 4, 5}), &c1);
  Tensor y2 = s.forward(Tensor::from_host(x2, {1, 3, 4, 5}), &c2);  // c1 stays valid
  Tensor g1 = Tensor::from_host(testing::random_normal(size_t(y1.numel()), 3), y1.shape());
  Tensor g2 = Tensor::from_host(testing::random_normal(size_t(y2.numel()), 4), y2.shape());

  s.zero_grad();
  s.backward(c1, g1);
  std::vector<std::vector<float>> once;
  for (nn::Param* p : s.params()) once.push_back(p->grad.to_host());
  Tensor dx = s.backward(c1, g1, /*need_dx=*/false);
  CHECK(!dx.defined());
  auto params = s.params();
  REQUIRE(params.size() == 6);
  for (size_t i = 0; i < params.size(); ++i) {
    std::vector<double> want = to_double(once[i]);
    for (double& v : want) v *= 2;
    // The same float values added: 2a is exact, a + a too.
    check_close(params[i]->grad.to_host(), want, 0.0, 1e-30, "twice " + params[i]->name);
  }

  // Two different inputs through their own contexts add up to the sum of separate runs.
  s.zero_grad();
  s.backward(c2, g2);
  std::vector<std::vector<float>> second;
  for (nn::Param* p : s.params()) second.push_back(p->grad.to_host());
  s.backward(c1, g1);
  for (size_t i = 0; i < params.size(); ++i) {
    std::vector<double> want(once[i].size());
    for (size_t k = 0; k < want.size(); ++k) want[k] = double(once[i][k]) + second[i][k];
    check_close(params[i]->grad.to_host(), want, 1e-6, 1e-6, "sum of two inputs " + params[i]->name);
  }

  // Misuse: an empty context, a context of another stack, a dy of the wrong shape.
  testing::expect_error([&] { s.backward(ConvStack::Ctx(), g1); }, "the context does not come from this stack");
  ConvStack other(spec_of({3, 4}, {}, Padding::Reflect), 1);
  ConvStack::Ctx co;
  other.forward(Tensor::zeros({1, 3, 4, 5}), &co);
  testing::expect_error([&] { s.backward(co, g1); }, "1 inputs kept, the stack has 3 convs");
  testing::expect_error([&] { s.backward(c1, Tensor::zeros({1, 3, 4, 5})); }, "dy has shape [1, 3, 4, 5], expected [1, 3, 8, 10]");
  testing::expect_error([&] { s.forward(Tensor::zeros({1, 2, 4, 5})); }, "input must be a non-empty [N, 3, H, W]");
}

TEST_CASE("conv stack: frozen, the same outputs and gradients from kept filter transforms; writable paths unfreeze") {
  struct AlgoScope {  // every 3x3 conv of this test runs Winograd F(4x4): the only convs that keep a transform
    AlgoScope() { nn::set_default_conv_algo(nn::ConvAlgo::Winograd4); }
    ~AlgoScope() { nn::set_default_conv_algo(nn::ConvAlgo::Auto); }
  } algo;
  const ConvStackSpec spec = spec_of({6, 8, 8, 3}, {false, true, false}, Padding::Reflect);
  const Tensor x = Tensor::from_host(testing::random_normal(2 * 6 * 6 * 5, 5), {2, 6, 6, 5});
  const Tensor g = Tensor::from_host(testing::random_normal(2 * 3 * 12 * 10, 6), {2, 3, 12, 10});
  // One training step's output, dx and weight gradients (each stack's grads start undefined).
  auto step = [&](ConvStack& st) {
    ConvStack::Ctx ctx;
    std::vector<std::vector<float>> out{st.forward(x, &ctx).to_host()};
    out.push_back(st.backward(ctx, g).to_host());
    for (const auto& l : st.layers()) out.push_back(l.w.grad.to_host());
    return out;
  };
  ConvStack plain(spec, 11), s(spec, 11);
  const std::vector<float> y_infer = plain.forward(x).to_host();
  CHECK(!s.frozen());
  s.freeze();
  CHECK(s.frozen());
  CHECK(s.forward(x).to_host() == y_infer);
  CHECK(step(s) == step(plain));  // unfrozen, forward's transforms serve backward through the context
  CHECK(s.forward(x).to_host() == y_infer);
  CHECK(s.frozen());

  // A frozen stack really serves kept transforms: a write that bypasses every writable path (misuse) is
  // not seen until the stack is unfrozen.
  Tensor w0 = s.layers()[0].w.value;  // a handle on the same buffer
  std::vector<float> wv = w0.to_host();
  for (float& v : wv) v *= 0.5f;
  w0.upload(wv);
  CHECK(s.forward(x).to_host() == y_infer);
  s.unfreeze();
  const std::vector<float> y_halved = s.forward(x).to_host();
  CHECK(y_halved != y_infer);

  // Taking the params (an optimiser, Module::load) and He init unfreeze it: what comes next is fresh.
  s.freeze();
  CHECK(s.forward(x).to_host() == y_halved);
  s.params();
  CHECK(!s.frozen());
  s.freeze();
  s.init_he(12);
  CHECK(!s.frozen());
  CHECK(s.forward(x).to_host() == ConvStack(spec, 12).forward(x).to_host());
}

TEST_CASE("conv stack: spec checks, names, groups, He init") {
  testing::expect_error([] { ConvStack(spec_of({3}, {}, Padding::Reflect, "x."), 1); }, "ConvStack 'x.': a spec needs at least two");
  testing::expect_error([] { ConvStack(spec_of({3, 0, 2}, {}, Padding::Reflect), 1); }, "channel counts must be >= 1");
  testing::expect_error([] { ConvStack(spec_of({3, 4, 2}, {true}, Padding::Reflect), 1); }, "upsample_after has 1 entries for 2 convs");
  testing::expect_error([] { ConvStack(spec_of({3, 4, 2}, {false, true}, Padding::Reflect), 1); }, "an upsampling after the last conv");

  ConvStackSpec spec = spec_of({3, 4, 4, 2}, {true, false, false}, Padding::Reflect, "dec.");
  spec.group = 2;
  ConvStack s(spec, 5);
  std::vector<std::string> names;
  for (nn::Param* p : s.params()) {
    names.push_back(p->name);
    CHECK(p->group == 2);
  }
  // AdaIN's module numbering: conv 1, (relu, upsample, pad) -> 5, (relu, pad) -> 8.
  CHECK(names == std::vector<std::string>{"dec.1.weight", "dec.1.bias", "dec.5.weight", "dec.5.bias", "dec.8.weight",
                                          "dec.8.bias"});
  CHECK(s.param_count() == 4 * 3 * 9 + 4 + 4 * 4 * 9 + 4 + 2 * 4 * 9 + 2);
  CHECK(s.spec().same_architecture(spec));
  CHECK(s.upsamplings() == 1);
  CHECK(s.in_channels() == 3);
  CHECK(s.out_channels() == 2);
  ConvStack z(spec_of({3, 4, 2}, {true, false}, Padding::Zero, "z."), 5);
  CHECK(z.layers()[0].w.name == "z.0.weight");  // zero padding: no pad modules, conv 0, (relu, up) -> 3
  CHECK(z.layers()[1].w.name == "z.3.weight");

  // He normal: std sqrt(2 / fan_in), zero bias; the same seed gives the same weights.
  ConvStack big(spec_of({64, 64}, {}, Padding::Reflect), 9);
  auto w = big.layers()[0].w.value.to_host();
  double m = 0, q = 0;
  for (float v : w) m += v;
  m /= w.size();
  for (float v : w) q += (v - m) * (v - m);
  const double want_std = std::sqrt(2.0 / (64 * 9));
  CHECK(std::fabs(std::sqrt(q / w.size()) / want_std - 1) < 0.02);  // 36864 draws: std error ~0.4%
  CHECK(std::fabs(m) < 4 * want_std / std::sqrt(double(w.size())));
  for (float v : big.layers()[0].b.value.to_host()) CHECK(v == 0.0f);
  CHECK(ConvStack(spec_of({64, 64}, {}, Padding::Reflect), 9).layers()[0].w.value.to_host() == w);
  CHECK(ConvStack(spec_of({64, 64}, {}, Padding::Reflect), 10).layers()[0].w.value.to_host() != w);
}

TEST_CASE("conv stack: files keep the architecture, the values and AdaIN's keys; checkpoints by name") {
  for (Padding pad : {Padding::Reflect, Padding::Zero}) {
    ConvStack s(spec_of({3, 4, 4, 2}, {false, true, false}, pad, "a."), 11);
    const std::string path = temp_file("stack.safetensors");
    s.save_file(path);
    io::SafeTensors st = io::SafeTensors::load(path);
    const std::vector<std::string> keys = pad == Padding::Reflect
                                              ? std::vector<std::string>{"1.bias", "1.weight", "4.bias", "4.weight",
                                                                         "8.bias", "8.weight"}
                                              : std::vector<std::string>{"0.bias", "0.weight", "2.bias", "2.weight",
                                                                         "5.bias", "5.weight"};
    CHECK(st.names() == keys);
    ConvStack l = ConvStack::from_file(path, "a.");
    fs::remove(path);
    CHECK(l.spec().same_architecture(s.spec()));
    CHECK(l.padding() == pad);
    for (size_t i = 0; i < 3; ++i) {
      CHECK(l.layers()[i].w.name == s.layers()[i].w.name);
      CHECK(l.layers()[i].w.value.to_host() == s.layers()[i].w.value.to_host());
      CHECK(l.layers()[i].b.value.to_host() == s.layers()[i].b.value.to_host());
    }
  }

  // Through a checkpoint: a spec-built stack of the same architecture takes the values by name.
  ConvStack a(spec_of({3, 4, 2}, {true, false}, Padding::Reflect, "decoder."), 1);
  ConvStack b(spec_of({3, 4, 2}, {true, false}, Padding::Reflect, "decoder."), 2);
  io::Checkpoint ck;
  a.save(ck, "stage2.");
  CHECK(ck.tensors.count("stage2.decoder.5.weight") == 1);
  b.load(ck, "stage2.");
  for (size_t i = 0; i < 2; ++i) CHECK(b.layers()[i].w.value.to_host() == a.layers()[i].w.value.to_host());
  ConvStack c(spec_of({3, 5, 2}, {true, false}, Padding::Reflect, "decoder."), 2);
  testing::expect_error([&] { c.load(ck, "stage2."); }, "decoder.1.weight");

  // Files we cannot read as a stack say why, naming the file.
  const std::string bad = temp_file("bad.safetensors");
  io::save_safetensors(bad, {{"1.weight", {{4, 3, 3, 3}, std::vector<float>(108)}},
                             {"1.bias", {{4}, std::vector<float>(4)}},
                             {"9.weight", {{2, 4, 3, 3}, std::vector<float>(72)}},
                             {"9.bias", {{2}, std::vector<float>(2)}}});
  testing::expect_error([&] { ConvStack::from_file(bad); }, bad + ": convs 1 and 9 are not separated by (relu, pad)");
  io::save_safetensors(bad, {{"1.weight", {{4, 3, 3, 3}, std::vector<float>(108)}}});
  testing::expect_error([&] { ConvStack::from_file(bad); }, "1.bias");
  io::save_safetensors(bad, {{"1.weight", {{4, 3, 3, 3}, std::vector<float>(108)}},
                             {"1.bias", {{4}, std::vector<float>(4)}},
                             {"4.weight", {{2, 5, 3, 3}, std::vector<float>(90)}},
                             {"4.bias", {{2}, std::vector<float>(2)}}});
  testing::expect_error([&] { ConvStack::from_file(bad); }, "'4.weight' has 5 input channels but the previous conv outputs 4");
  io::save_safetensors(bad, {{"1.weight", {{4, 3, 3, 3}, std::vector<float>(108)}},
                             {"1.bias", {{4}, std::vector<float>(4)}},
                             {"4.weight", {{2, 4, 3, 3}, std::vector<float>(72)}},
                             {"4.bias", {{2}, std::vector<float>(2)}}});
  CHECK(ConvStack::from_file(bad).spec().describe() == "reflect 3-4-2, no upsampling");  // a valid stack ...
  testing::expect_error([&] { nn::load_adain_decoder(bad); },  // ... but not AdaIN's
                        bad + ": not AdaIN's decoder: the file holds reflect 3-4-2, no upsampling, expected reflect "
                              "512-256-256-256-256-128-128-64-64-3, x2 after conv 1, 5, 7");
  io::save_safetensors(bad, {{"features", {{2}, std::vector<float>(2)}}});
  testing::expect_error([&] { ConvStack::from_file(bad); }, "not a conv stack");
  fs::remove(bad);
}

TEST_CASE("decoders: the paper's PlainDecoder and the fast decoder's specs") {
  ConvStack plain(nn::plain_decoder_spec(), 1);
  CHECK(plain.spec().describe() == "reflect 256-256-256-256-128-128-64-64-3, no upsampling");
  CHECK(plain.upsamplings() == 0);
  CHECK(plain.layers().size() == 8);
  CHECK(plain.layers()[7].w.name == "decoder.22.weight");
  CHECK(!plain.layers()[7].relu);
  CHECK(plain.layers()[6].relu);
  CHECK(nn::fast_decoder_spec().describe() == "reflect 256-256-256-256-128-128-64-64-3, x2 after conv 4, 6");
  CHECK(nn::adain_decoder_spec().describe() == "reflect 512-256-256-256-256-128-128-64-64-3, x2 after conv 1, 5, 7");
  // A 16x16 input runs through the plain decoder at full resolution.
  CHECK(plain.forward(Tensor::zeros({1, 256, 4, 4})).shape() == host::Shape{1, 3, 4, 4});
  testing::expect_error([&] { nn::fast_decoder_from_adain(plain); }, "fast_decoder_from_adain: the source is not AdaIN's decoder");
}

TEST_CASE("decoders: AdaIN's decoder is bit-identical to the previous op chain; the fast decoder takes convs 2..9") {
  const std::string path = nn::weights_path(nn::kDecoderWeightsFile);
  REQUIRE_MESSAGE(fs::exists(path), "pretrained weights missing: " << path << " — run `" << std::string(nn::kFetchWeightsCommand)
                                                                   << "` first");
  ConvStack adain = nn::load_adain_decoder();
  CHECK(adain.layers()[0].index == 1);
  CHECK(adain.layers()[8].index == 28);  // AdaIN's last conv is Sequential module 28
  io::SafeTensors st = io::SafeTensors::load(path);

  // The chain AdainDecoder::forward ran before it became a ConvStack: conv, relu (not after the last),
  // upsample after modules 1, 14, 21. Same ops in the same order on the same data: identical bits.
  // 4x6 (2x3 under STYLERF_TEST_SMALL: the decoder's 8x upsampling is most of the suite's simulated time).
  const int xh = testing::small_run() ? 2 : 4, xw = testing::small_run() ? 3 : 6;
  auto x = testing::random_normal(size_t(512) * xh * xw, 77, 0.5f);
  Tensor xt = Tensor::from_host(x, {1, 512, xh, xw});
  Tensor h = xt;
  const int modules[9] = {1, 5, 8, 11, 14, 18, 21, 25, 28};
  for (int i = 0; i < 9; ++i) {
    const auto& w = st.get(std::to_string(modules[i]) + ".weight");
    const auto& b = st.get(std::to_string(modules[i]) + ".bias");
    h = nn::conv2d_forward(h, Tensor::from_host(w.data, w.shape), Tensor::from_host(b.data, b.shape), Padding::Reflect);
    if (i < 8) h = nn::relu_forward(h);
    if (modules[i] == 1 || modules[i] == 14 || modules[i] == 21) h = nn::upsample2x_forward(h);
  }
  Tensor y = adain.forward(xt);
  REQUIRE(y.shape() == host::Shape{1, 3, 8 * xh, 8 * xw});
  CHECK(host_of(y) == host_of(h));

  // Saving writes AdaIN's keys with AdaIN's values.
  const std::string out = temp_file("adain_copy.safetensors");
  adain.save_file(out);
  io::SafeTensors copy = io::SafeTensors::load(out);
  fs::remove(out);
  for (const std::string& k : st.names()) {
    REQUIRE(copy.has(k));
    CHECK(copy.get(k).data == st.get(k).data);
  }
  CHECK(copy.names().size() == st.names().size());

  // The fast decoder: AdaIN's convs 2..9 (modules 5 ... 28), renumbered as a stack of its own.
  ConvStack fast = nn::fast_decoder_from_adain(adain, "decoder.", 1);
  CHECK(fast.spec().same_architecture(nn::fast_decoder_spec()));
  REQUIRE(fast.layers().size() == 8);
  for (int i = 0; i < 8; ++i) {
    CAPTURE(i);
    CHECK(fast.layers()[i].w.value.to_host() == st.get(std::to_string(modules[i + 1]) + ".weight").data);
    CHECK(fast.layers()[i].b.value.to_host() == st.get(std::to_string(modules[i + 1]) + ".bias").data);
    CHECK(fast.layers()[i].w.group == 1);
  }
  CHECK(fast.layers()[0].w.name == "decoder.1.weight");
  // Same names as a fast decoder built from its spec, so a checkpoint fills either.
  ConvStack from_spec(nn::fast_decoder_spec(), 3);
  for (size_t i = 0; i < 8; ++i) CHECK(from_spec.layers()[i].w.name == fast.layers()[i].w.name);
  // relu3_1-sized features at 1/4 -> full size.
  CHECK(fast.forward(Tensor::zeros({1, 256, 4, 5})).shape() == host::Shape{1, 3, 16, 20});
  // The copy is not shared: re-initialising the fast decoder leaves AdaIN's weights alone.
  fast.init_he(1);
  CHECK(adain.layers()[1].w.value.to_host() == st.get("5.weight").data);
}

TEST_CASE("conv stack: phase input interleaves at the first upsampling; forward and backward against the reference") {
  // Upsamplings after convs 1 and 2: the first interleaves the phases, the second repeats as always.
  const ConvStackSpec spec = spec_of({3, 4, 4, 2}, {true, true, false}, Padding::Reflect);
  const int H = 3, W = 4, cin = 3;
  ConvStack s(spec, 80);
  for (nn::Param* q : s.params())
    if (q->name.size() > 5 && q->name.compare(q->name.size() - 5, 5, ".bias") == 0)
      q->value.upload(testing::random_normal(size_t(q->value.numel()), 87, 0.2f));
  const RefParams p = params_of(s);
  auto x = testing::random_normal(size_t(4 * cin * H * W), 81);
  ConvStack::Ctx ctx;
  Tensor y = s.forward(Tensor::from_host(x, {4, cin, H, W}), &ctx, /*phase_input=*/true);
  const RefTensor yr = ref_stack_phases(spec, p, split_phases(to_double(x), cin, H, W));
  REQUIRE(y.shape() == host::Shape{1, yr.C, yr.H, yr.W});
  REQUIRE(yr.H == 4 * H);
  check_close(y.to_host(), yr.v, 1e-4, 1e-4, "phase stack forward");

  auto g = testing::random_normal(yr.v.size(), 82);
  const auto gd = to_double(g);
  Tensor dx = s.backward(ctx, Tensor::from_host(g, y.shape()));
  REQUIRE(dx.shape() == host::Shape{4, cin, H, W});
  auto loss_x = [&](const std::vector<double>& v) {
    return testing::dot(gd, ref_stack_phases(spec, p, split_phases(v, cin, H, W)).v);
  };
  check_close(dx.to_host(), testing::finite_difference(loss_x, to_double(x), 1e-5), 1e-4, 1e-4, "phase stack dx");
  // The first conv runs on all four phases: its weight gradient sums them.
  auto idx = std::vector<size_t>{0, p.w[0].size() / 2, p.w[0].size() - 1};
  auto fw = testing::finite_difference_at(
      [&](const std::vector<double>& v) {
        RefParams q = p;
        q.w[0] = v;
        return testing::dot(gd, ref_stack_phases(spec, q, split_phases(to_double(x), cin, H, W)).v);
      },
      p.w[0], idx, 1e-5);
  check_close(pick(s.layers()[0].w.grad.to_host(), idx), fw, 1e-4, 1e-4, "phase stack dw0");

  CHECK(testing::error_of([&] { s.forward(Tensor::zeros({2, cin, H, W}), nullptr, true); }).find("4 phase blocks") !=
        std::string::npos);
}

// What the vgg-adain decoder's lattice of strokes came from (docs/experiments.md), at toy size: VGG's
// tail pools with stride 2, and AdaIN's decoder repeats each pooled pixel over 2 x 2, so the picture is
// painted on a grid fixed to the image and a one-pixel move of the input changes it, not only moves it.
// With the pool's four phases interleaved at the upsampling, a one-pixel move only moves it.
TEST_CASE("phases: conv, pool, convs and an upsampling move with their input by one pixel; one phase does not") {
  const int C = 3, H = 16, W = 32;
  const auto w1 = testing::random_normal(size_t(4 * C * 9), 90, 0.3f), b1 = testing::random_normal(4, 91, 0.1f);
  const Tensor tw1 = Tensor::from_host(w1, {4, C, 3, 3}), tb1 = Tensor::from_host(b1, {4});
  const ConvStack stack(spec_of({4, 6, 5, 3}, {true, false, false}, Padding::Reflect), 92);
  auto x0 = testing::random_normal(size_t(C * H * W), 93);
  std::vector<float> x1(x0.size());  // x0 moved left by one pixel (the last column repeated)
  for (int c = 0; c < C; ++c)
    for (int yy = 0; yy < H; ++yy)
      for (int xx = 0; xx < W; ++xx) x1[(size_t(c) * H + yy) * W + xx] = x0[(size_t(c) * H + yy) * W + std::min(xx + 1, W - 1)];
  auto run = [&](const std::vector<float>& x, bool phases) {
    Tensor h = nn::relu_forward(nn::conv2d_forward(Tensor::from_host(x, {1, C, H, W}), tw1, tb1, Padding::Reflect));
    h = phases ? nn::maxpool2x2_phases_forward(h) : nn::maxpool2x2_forward(h);
    return stack.forward(h, nullptr, phases).to_host();
  };
  // Output columns far enough from the borders that padding does not reach them (receptive field < 10 px).
  auto moved_by_one = [&](bool phases) {
    const auto y0 = run(x0, phases), y1 = run(x1, phases);
    double worst = 0, scale = 0;
    for (int c = 0; c < 3; ++c)
      for (int yy = 0; yy < H; ++yy)
        for (int xx = 10; xx < W - 11; ++xx) {
          const size_t i = (size_t(c) * H + yy) * W + xx;
          worst = testing::max_or_nan(worst, double(std::abs(y1[i] - y0[i + 1])));
          scale = std::max(scale, double(std::abs(y0[i])));
        }
    return worst / scale;
  };
  CHECK(moved_by_one(true) < 1e-5);
  CHECK(moved_by_one(false) > 0.05);
}
