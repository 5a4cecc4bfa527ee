// Conv algorithm choice (conv_algo.hpp).
#include "lib/nn/conv_algo.hpp"

#include <algorithm>
#include <cstdlib>

#include "host/error.hpp"
#include "lib/nn/conv_internal.hpp"

namespace stylerf::nn {
namespace {
ConvAlgo g_default = ConvAlgo::Auto;
}

const char* conv_algo_name(ConvAlgo a) {
  switch (a) {
    case ConvAlgo::Auto: return "auto";
    case ConvAlgo::Im2col: return "im2col";
    case ConvAlgo::Winograd2: return "winograd2";
    case ConvAlgo::Winograd4: return "winograd4";
  }
  return "?";
}

ConvAlgo parse_conv_algo(const std::string& name) {
  for (ConvAlgo a : {ConvAlgo::Auto, ConvAlgo::Im2col, ConvAlgo::Winograd2, ConvAlgo::Winograd4})
    if (name == conv_algo_name(a)) return a;
  throw host::Error("unknown conv algorithm '" + name + "' (auto, im2col, winograd2, winograd4)");
}

void set_default_conv_algo(ConvAlgo a) { g_default = a; }
ConvAlgo default_conv_algo() { return g_default; }

ConvAlgo resolve_conv_algo(ConvAlgo a, int cin, int cout, int h, int w, int n) {
  if (a == ConvAlgo::Auto) a = g_default;
  if (a == ConvAlgo::Auto) {
    if (const char* env = std::getenv("STYLERF_CONV_ALGO"); env && *env) {
      try {
        a = parse_conv_algo(env);
      } catch (const host::Error& e) {
        throw host::Error(std::string("STYLERF_CONV_ALGO: ") + e.what());
      }
    }
  }
  if (a == ConvAlgo::Auto) a = ConvAlgo::Winograd2;
  if (a == ConvAlgo::Im2col) return a;
  // The transformed input / output tiles: alpha^2 * channels * tiles floats each.
  const int m = a == ConvAlgo::Winograd2 ? 2 : 4, alpha = m + 2;
  const int64_t tiles = int64_t(n) * ((h + m - 1) / m) * ((w + m - 1) / m);
  const int64_t floats = int64_t(alpha) * alpha * std::max(cin, cout) * tiles;
  if (floats * int64_t(sizeof(float)) > int64_t(detail::conv_scratch_limit_bytes()) || floats >= (int64_t(1) << 31))
    return ConvAlgo::Im2col;
  return a;
}

}  // namespace stylerf::nn
