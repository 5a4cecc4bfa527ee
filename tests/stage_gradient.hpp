// Directional-derivative checks of a training stage's loss over its parameters: the analytic gradient g
// (what the library's backward accumulated) against central differences along a random direction d,
//   g . d   vs   (L(p + h d) - L(p - h d)) / 2h,
// over every trainable parameter at once and over each layer alone (a dropped term in one small block
// cannot hide in the total). d is N(0, 1) per element times the RMS of that tensor's values (1 for a zero
// tensor), so h is a relative step, the same for a 1M-element weight and a 32-element bias. A gap is judged
// in units of the block's spread, the standard deviation of g . d over such directions: one direction may be
// almost orthogonal to g, and a relative error of its tiny g . d would measure rounding alone.
#pragma once
#include <doctest/doctest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "lib/nn/module.hpp"

namespace stylerf::testing {

using ParamFilter = std::function<bool(const nn::Param&)>;

// A parameter's layer: its name up to the last '.' ("style.decoder.conv3.w" -> "style.decoder.conv3").
inline std::string layer_of(const nn::Param& p) {
  const size_t dot = p.name.rfind('.');
  return dot == std::string::npos ? p.name : p.name.substr(0, dot);
}

// The parameters under test, their values at the base point, and directions through them.
class ParamPoint {
 public:
  explicit ParamPoint(std::vector<nn::Param*> params) : params_(std::move(params)) {
    for (nn::Param* p : params_) base_.push_back(p->value.to_host());
  }
  const std::vector<nn::Param*>& params() const { return params_; }

  // Puts the base values back (after a trainer's optimiser step, or a perturbation).
  void restore() const {
    for (size_t i = 0; i < params_.size(); ++i) params_[i]->value.upload(base_[i]);
  }

  // Each parameter's gradient as it is now (zeros for one without a gradient).
  std::vector<std::vector<float>> grads() const {
    std::vector<std::vector<float>> g;
    for (size_t i = 0; i < params_.size(); ++i)
      g.push_back(params_[i]->grad.defined() ? params_[i]->grad.to_host() : std::vector<float>(base_[i].size(), 0.0f));
    return g;
  }

  // The RMS of parameter i's values (1 for a zero tensor): the scale of its direction's elements.
  float scale(size_t i) const {
    double ss = 0;
    for (float x : base_[i]) ss += double(x) * x;
    return ss > 0 ? float(std::sqrt(ss / double(base_[i].size()))) : 1.0f;
  }

  // N(0, 1) x the tensor's RMS on the selected parameters, zero elsewhere (seeded).
  std::vector<std::vector<float>> direction(const ParamFilter& select, uint64_t seed) const {
    std::mt19937_64 rng(seed);
    std::normal_distribution<float> n(0.0f, 1.0f);
    std::vector<std::vector<float>> d(params_.size());
    for (size_t i = 0; i < params_.size(); ++i) {
      if (!select(*params_[i])) continue;
      const float s = scale(i);
      d[i].resize(base_[i].size());
      for (float& x : d[i]) x = s * n(rng);
    }
    return d;
  }

  // The standard deviation of g . d over such random directions: sqrt(sum (g_i scale_i)^2) over the
  // selected parameters. The yardstick of a directional derivative: one direction may be almost
  // orthogonal to g, and its g . d is then judged against this rather than against itself.
  double spread(const std::vector<std::vector<float>>& grad, const ParamFilter& select) const {
    double ss = 0;
    for (size_t i = 0; i < params_.size(); ++i) {
      if (!select(*params_[i])) continue;
      const double s = scale(i);
      for (float g : grad[i]) ss += double(g) * g * s * s;
    }
    return std::sqrt(ss);
  }

  // Sets the parameters to base + h d.
  void move(const std::vector<std::vector<float>>& d, double h) const {
    for (size_t i = 0; i < params_.size(); ++i) {
      if (d[i].empty()) continue;
      std::vector<float> v(base_[i].size());
      for (size_t j = 0; j < v.size(); ++j) v[j] = float(double(base_[i][j]) + h * double(d[i][j]));
      params_[i]->value.upload(v);
    }
  }

  // Names of the selected parameters, for messages.
  std::string names(const ParamFilter& select) const {
    std::string s;
    for (nn::Param* p : params_)
      if (select(*p)) s += (s.empty() ? "" : ", ") + p->name;
    return s;
  }

  // The blocks checked one at a time: each layer (its weight and bias together), in order; a parameter
  // that `alone` selects is a block of its own.
  struct Block {
    std::string name;
    ParamFilter select;
  };
  std::vector<Block> blocks(const ParamFilter& alone = [](const nn::Param&) { return false; }) const {
    std::vector<Block> out;
    for (nn::Param* p : params_) {
      if (alone(*p)) {
        const std::string name = p->name;
        out.push_back({name, [name](const nn::Param& q) { return q.name == name; }});
        continue;
      }
      const std::string l = layer_of(*p);
      if (!out.empty() && out.back().name == l) continue;
      out.push_back({l, [l, alone](const nn::Param& q) { return !alone(q) && layer_of(q) == l; }});
    }
    return out;
  }

 private:
  std::vector<nn::Param*> params_;
  std::vector<std::vector<float>> base_;
};

inline double dot(const std::vector<std::vector<float>>& a, const std::vector<std::vector<float>>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i)
    for (size_t j = 0; j < a[i].size() && j < b[i].size(); ++j) s += double(a[i][j]) * double(b[i][j]);
  return s;
}

struct Directional {
  double analytic = 0, numeric = 0;
  double spread = 0;  // ParamPoint::spread of the block (or the like for a direction of some other input)
  // |analytic - numeric| / spread: NaN when a side is not finite; infinite when the analytic gradient is 0
  // on the block (spread 0) while the loss moves.
  double gap() const {
    if (!std::isfinite(analytic) || !std::isfinite(numeric) || !std::isfinite(spread)) return std::nan("");
    const double e = std::abs(analytic - numeric);
    if (spread <= 0) return e == 0 ? 0.0 : HUGE_VAL;
    return e / spread;
  }
};

// g . d against (L(base + h d) - L(base - h d)) / 2h; the parameters are back at base afterwards.
inline Directional directional(const ParamPoint& at, const std::vector<std::vector<float>>& grad,
                               const std::vector<std::vector<float>>& d, double h, double spread,
                               const std::function<double()>& loss) {
  Directional r;
  r.analytic = dot(grad, d);
  r.spread = spread;
  at.move(d, h);
  const double up = loss();
  at.move(d, -h);
  const double down = loss();
  at.restore();
  r.numeric = (up - down) / (2 * h);
  return r;
}

// The check: |g . d - central difference| <= tol x the block's spread (a NaN fails), with the values in the
// message. tol is stated per check, from measured gaps at the chosen h.
inline void check_directional(const std::string& what, const Directional& r, double tol) {
  const double gap = r.gap();
  CHECK_MESSAGE(gap <= tol, what << ": analytic g.d " << r.analytic << ", central difference " << r.numeric
                                  << ", spread of g.d " << r.spread << " (gap " << gap << " spreads, allowed " << tol
                                  << ")");
}

}  // namespace stylerf::testing
