#include "lib/nn/conv_stack.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "host/error.hpp"
#include "lib/nn/weights.hpp"

namespace stylerf::nn {
namespace {

using host::Error;

// Module indices of the equivalent nn.Sequential (see the header): where the first conv sits and how
// far apart two convs are without an upsampling between them (one more with one).
int first_index(Padding pad) { return pad == Padding::Reflect ? 1 : 0; }
int plain_gap(Padding pad) { return pad == Padding::Reflect ? 3 : 2; }

const char* padding_name(Padding pad) { return pad == Padding::Reflect ? "reflect" : "zero"; }

bool is_digits(const std::string& s) {
  return !s.empty() && s.size() < 9 && std::all_of(s.begin(), s.end(), [](unsigned char ch) { return ch >= '0' && ch <= '9'; });
}

}  // namespace

// ---- spec ----------------------------------------------------------------------------------------------
bool ConvStackSpec::same_architecture(const ConvStackSpec& o) const {
  auto ups = [](const ConvStackSpec& s) {
    std::vector<bool> u = s.upsample_after;
    u.resize(s.channels.empty() ? 0 : s.channels.size() - 1, false);
    return u;
  };
  return channels == o.channels && pad == o.pad && ups(*this) == ups(o);
}

std::string ConvStackSpec::describe() const {
  std::string s = std::string(padding_name(pad)) + " ";
  for (size_t i = 0; i < channels.size(); ++i) s += (i ? "-" : "") + std::to_string(channels[i]);
  std::string ups;
  for (size_t i = 0; i < upsample_after.size(); ++i)
    if (upsample_after[i]) ups += (ups.empty() ? "" : ", ") + std::to_string(i + 1);
  return s + (ups.empty() ? ", no upsampling" : ", x2 after conv " + ups);
}

// ---- construction ----------------------------------------------------------------------------------------
ConvStack::ConvStack(const ConvStackSpec& spec, uint64_t seed)
    : pad_(spec.pad), prefix_(spec.name_prefix), group_(spec.group) {
  const std::string what = "ConvStack '" + spec.name_prefix + "'";
  if (spec.channels.size() < 2)
    throw Error(what + ": a spec needs at least two channel counts (one conv), got " +
                std::to_string(spec.channels.size()));
  const size_t n = spec.channels.size() - 1;
  for (int c : spec.channels)
    if (c < 1) throw Error(what + ": channel counts must be >= 1, spec is " + spec.describe());
  if (!spec.upsample_after.empty() && spec.upsample_after.size() != n)
    throw Error(what + ": upsample_after has " + std::to_string(spec.upsample_after.size()) + " entries for " +
                std::to_string(n) + " convs");
  if (!spec.upsample_after.empty() && spec.upsample_after.back())
    throw Error(what + ": an upsampling after the last conv is not supported (a stack ends with its last conv, "
                       "as a stack file can only express upsamplings between convs)");
  for (size_t i = 0; i < n; ++i) {
    Layer l;
    const int cin = spec.channels[i], cout = spec.channels[i + 1];
    l.w.value = Tensor({cout, cin, 3, 3}, what + " weight");
    l.b.value = Tensor({cout}, what + " bias");
    l.relu = i + 1 < n;
    l.upsample = !spec.upsample_after.empty() && spec.upsample_after[i];
    layers_.push_back(std::move(l));
  }
  name_params();
  init_he(seed);
}

ConvStack ConvStack::from_file(const std::string& path, const std::string& name_prefix, int group) {
  io::SafeTensors st = load_weights(path);
  ConvStack s;
  s.prefix_ = name_prefix;
  s.group_ = group;
  auto meta = st.metadata().find("padding");
  if (meta != st.metadata().end() && meta->second != "reflect" && meta->second != "zero")
    throw Error(path + ": metadata padding = '" + meta->second + "', expected 'reflect' or 'zero'");
  s.pad_ = meta != st.metadata().end() && meta->second == "zero" ? Padding::Zero : Padding::Reflect;

  std::map<int, std::string> convs;  // module index -> key stem
  for (const std::string& name : st.names()) {
    auto dot = name.find('.');
    if (dot == std::string::npos || name.substr(dot) != ".weight" || !is_digits(name.substr(0, dot))) continue;
    convs[std::stoi(name.substr(0, dot))] = name.substr(0, dot);
  }
  if (convs.empty())
    throw Error(path + ": not a conv stack: no \"<index>.weight\" tensors (expected e.g. AdaIN's decoder, "
                       "\"1.weight\", \"5.weight\", ...)");
  for (auto it = convs.begin(); it != convs.end(); ++it) {
    Layer l;
    const auto& w = st.get(it->second + ".weight");
    if (w.shape.size() != 4 || w.shape[2] != 3 || w.shape[3] != 3)
      throw Error(path + ": tensor '" + it->second + ".weight' has shape " + host::shape_str(w.shape) +
                  ", expected [Cout, Cin, 3, 3]");
    if (!s.layers_.empty() && w.shape[1] != s.layers_.back().w.value.dim(0))
      throw Error(path + ": tensor '" + it->second + ".weight' has " + std::to_string(w.shape[1]) +
                  " input channels but the previous conv outputs " + std::to_string(s.layers_.back().w.value.dim(0)));
    const auto& b = st.get(it->second + ".bias", {w.shape[0]});
    l.w.value = Tensor::from_host(w.data, w.shape, path + " " + it->second + ".weight");
    l.b.value = Tensor::from_host(b.data, b.shape, path + " " + it->second + ".bias");
    auto next = std::next(it);
    l.relu = next != convs.end();
    if (next != convs.end()) {
      const int extra = next->first - it->first - plain_gap(s.pad_);
      if (extra != 0 && extra != 1)
        throw Error(path + ": convs " + it->second + " and " + next->second + " are not separated by " +
                    (s.pad_ == Padding::Reflect ? "(relu, pad) or (relu, upsample, pad)"
                                                : "(relu) or (relu, upsample)") +
                    " (" + padding_name(s.pad_) + " padding): cannot tell the architecture");
      l.upsample = extra == 1;
    }
    s.layers_.push_back(std::move(l));
  }
  s.name_params();
  return s;
}

void ConvStack::save_file(const std::string& path) const {
  if (empty()) throw Error(where() + ": save_file(" + path + ") of an empty stack");
  std::map<std::string, io::HostTensor> out;
  for (const Layer& l : layers_) {
    out[std::to_string(l.index) + ".weight"] = {l.w.value.shape(), l.w.value.to_host()};
    out[std::to_string(l.index) + ".bias"] = {l.b.value.shape(), l.b.value.to_host()};
  }
  io::save_safetensors(path, out, {{"format", "pt"}, {"model", "conv_stack"}, {"padding", padding_name(pad_)}});
}

void ConvStack::name_params() {
  int index = first_index(pad_);
  for (Layer& l : layers_) {
    l.index = index;
    l.w.name = prefix_ + std::to_string(index) + ".weight";
    l.b.name = prefix_ + std::to_string(index) + ".bias";
    l.w.group = l.b.group = group_;
    index += plain_gap(pad_) + (l.upsample ? 1 : 0);
  }
}

void ConvStack::init_he(uint64_t seed) {
  unfreeze();  // the weights are written in place
  std::mt19937_64 rng(seed);
  for (Layer& l : layers_) {
    const Tensor& w = l.w.value;
    const int64_t fan_in = w.dim(1) * w.dim(2) * w.dim(3);
    std::normal_distribution<float> dist(0.0f, std::sqrt(2.0f / float(fan_in)));
    std::vector<float> v(size_t(w.numel()));
    for (float& x : v) x = dist(rng);
    l.w.value.upload(v);
    l.b.value.zero();
  }
}

ConvStack ConvStack::tail(int first, const std::string& name_prefix, int group) const {
  if (first < 0 || first >= int(layers_.size()))
    throw Error(where() + ": tail(" + std::to_string(first) + ") of a stack of " + std::to_string(layers_.size()) +
                " convs");
  ConvStack s;
  s.pad_ = pad_;
  s.prefix_ = name_prefix;
  s.group_ = group;
  for (size_t i = size_t(first); i < layers_.size(); ++i) {
    Layer l;
    l.w.value = layers_[i].w.value.clone();
    l.b.value = layers_[i].b.value.clone();
    l.relu = layers_[i].relu;
    l.upsample = layers_[i].upsample;
    s.layers_.push_back(std::move(l));
  }
  s.name_params();
  return s;
}

// ---- properties --------------------------------------------------------------------------------------
std::string ConvStack::where() const { return "ConvStack '" + prefix_ + "'"; }

ConvStackSpec ConvStack::spec() const {
  ConvStackSpec s;
  s.pad = pad_;
  s.name_prefix = prefix_;
  s.group = group_;
  if (empty()) return s;
  s.channels.push_back(in_channels());
  for (const Layer& l : layers_) {
    s.channels.push_back(int(l.w.value.dim(0)));
    s.upsample_after.push_back(l.upsample);
  }
  return s;
}

int ConvStack::in_channels() const {
  if (empty()) throw Error(where() + ": empty stack (no weights loaded)");
  return int(layers_.front().w.value.dim(1));
}

int ConvStack::out_channels() const {
  if (empty()) throw Error(where() + ": empty stack (no weights loaded)");
  return int(layers_.back().w.value.dim(0));
}

int ConvStack::upsamplings() const {
  return int(std::count_if(layers_.begin(), layers_.end(), [](const Layer& l) { return l.upsample; }));
}

void ConvStack::collect_params(std::vector<Param*>& out) {
  unfreeze();
  for (Layer& l : layers_) {
    out.push_back(&l.w);
    out.push_back(&l.b);
  }
}

void ConvStack::freeze() {
  frozen_ = true;
  frozen_filters_.assign(layers_.size(), ConvFilterCache());
}

void ConvStack::unfreeze() {
  frozen_ = false;
  frozen_filters_.clear();
}

// ---- forward / backward ---------------------------------------------------------------------------
namespace {
// Every layer's input size for an input of h x w, checking that reflect padding can run on it.
std::vector<std::pair<int64_t, int64_t>> layer_sizes(const std::vector<ConvStack::Layer>& layers, Padding pad,
                                                     int64_t h, int64_t w, const std::string& where) {
  std::vector<std::pair<int64_t, int64_t>> sizes;
  for (size_t i = 0; i < layers.size(); ++i) {
    if (pad == Padding::Reflect && (h < 2 || w < 2))
      throw Error(where + ": conv " + std::to_string(i + 1) + " of " + std::to_string(layers.size()) + " ('" +
                  layers[i].w.name + "') would get a " + std::to_string(h) + "x" + std::to_string(w) +
                  " input; reflect padding needs H, W >= 2 (as PyTorch's ReflectionPad2d)");
    sizes.push_back({h, w});
    if (layers[i].upsample) h *= 2, w *= 2;
  }
  sizes.push_back({h, w});  // the output
  return sizes;
}
}  // namespace

Tensor ConvStack::forward(const Tensor& x, Ctx* ctx, bool phase_input) const {
  if (empty()) throw Error(where() + "::forward: empty stack (no weights loaded)");
  if (!x.defined() || x.ndim() != 4 || x.dim(1) != in_channels() || x.numel() == 0)
    throw Error(where() + "::forward: input must be a non-empty [N, " + std::to_string(in_channels()) +
                ", H, W], got " + (x.defined() ? host::shape_str(x.shape()) : std::string("an undefined tensor")));
  if (phase_input && (x.dim(0) % 4 || upsamplings() == 0))
    throw Error(where() + "::forward: phase input needs a batch of 4 phase blocks and an upsampling to "
                          "interleave them, got " + host::shape_str(x.shape()) + " and " +
                std::to_string(upsamplings()) + " upsamplings");
  layer_sizes(layers_, pad_, x.dim(2), x.dim(3), where() + "::forward");  // before any launch
  if (ctx) {
    *ctx = Ctx();
    ctx->phase_input = phase_input;
    if (!frozen_) ctx->filters.resize(layers_.size());
  }
  Tensor h = x;
  bool interleave = phase_input;
  for (size_t i = 0; i < layers_.size(); ++i) {
    const Layer& l = layers_[i];
    if (ctx) ctx->inputs.push_back(h);
    h = conv2d_forward(h, l.w.value, l.b.value, pad_, ConvAlgo::Auto, filters_for(i, ctx));
    if (l.relu) h = relu_forward(h);
    if (ctx) ctx->relu_out.push_back(l.relu ? h : Tensor());
    if (l.upsample) h = interleave ? phase_interleave_forward(h) : upsample2x_forward(h);
    if (l.upsample) interleave = false;
  }
  return h;
}

// Layer i's filter cache for this call: the frozen stack's own, else the context's (forward fills it,
// backward reads it), else none (an unfrozen inference forward transforms per call).
ConvFilterCache* ConvStack::filters_for(size_t i, const Ctx* ctx) const {
  if (frozen_) return &frozen_filters_[i];
  if (ctx && i < ctx->filters.size()) return &ctx->filters[i];
  return nullptr;
}

Tensor ConvStack::backward(const Ctx& ctx, const Tensor& dy, bool need_dx) {
  const std::string op = where() + "::backward";
  if (ctx.inputs.size() != layers_.size() || ctx.relu_out.size() != layers_.size() || !ctx.inputs[0].defined())
    throw Error(op + ": the context does not come from this stack's forward(x, &ctx) (" +
                std::to_string(ctx.inputs.size()) + " inputs kept, the stack has " + std::to_string(layers_.size()) +
                " convs)");
  const Tensor& x = ctx.inputs[0];
  auto sizes = layer_sizes(layers_, pad_, x.dim(2), x.dim(3), op);
  const int64_t n = ctx.phase_input ? x.dim(0) / 4 : x.dim(0);
  host::expect_shape(dy, {n, out_channels(), sizes.back().first, sizes.back().second}, op.c_str(), "dy");
  int first_upsample = -1;
  for (int i = 0; i < int(layers_.size()) && first_upsample < 0; ++i)
    if (layers_[size_t(i)].upsample) first_upsample = i;
  Tensor d = dy;
  for (int i = int(layers_.size()) - 1; i >= 0; --i) {
    Layer& l = layers_[i];
    if (l.upsample)
      d = ctx.phase_input && i == first_upsample ? phase_interleave_backward(d) : upsample2x_backward(d);
    if (l.relu) d = relu_backward(ctx.relu_out[i], d);
    Conv2dGrads g = conv2d_backward(ctx.inputs[i], l.w.value, d, pad_, /*need_dx=*/i > 0 || need_dx,
                                    /*need_params=*/true, ConvAlgo::Auto, filters_for(size_t(i), &ctx));
    l.w.accumulate(g.dw);
    l.b.accumulate(g.db);
    d = g.dx;
  }
  return d;
}

}  // namespace stylerf::nn
