// Conv algorithm choice (conv_algo.hpp).
#include "lib/nn/conv_algo.hpp"

#include <algorithm>
#include <cstdlib>

#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/nn/conv_internal.hpp"

namespace stylerf::nn {
namespace {
ConvAlgo g_default = ConvAlgo::Auto;

// The largest transformed tensor Winograd may allocate: 1 GiB, or STYLERF_CONV_SCRATCH_BYTES when set,
// never above the device's max allocation. Larger convs (full-resolution renders through the paper
// decoder) run im2col in bounded row chunks instead.
size_t winograd_limit_bytes() {
  size_t limit = std::min(host::Runtime::instance().device().max_alloc_bytes, size_t(1) << 30);
  if (const char* env = std::getenv("STYLERF_CONV_SCRATCH_BYTES")) {
    long long v = std::atoll(env);
    if (v > 0) limit = std::min(host::Runtime::instance().device().max_alloc_bytes, static_cast<size_t>(v));
  }
  return limit;
}
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
  // Measured (bench decoder-step, bench conv): F(4x4) is the fastest on the paper and fast decoders at
  // 256x256, with errors ~2e-5 of the output scale against im2col's ~1e-6.
  if (a == ConvAlgo::Auto) a = ConvAlgo::Winograd4;
  if (a == ConvAlgo::Im2col) return a;
  // The transformed input / output tiles: alpha^2 * channels * tiles floats each.
  const int m = a == ConvAlgo::Winograd2 ? 2 : 4, alpha = m + 2;
  const int64_t tiles = int64_t(n) * ((h + m - 1) / m) * ((w + m - 1) / m);
  const int64_t floats = int64_t(alpha) * alpha * std::max(cin, cout) * tiles;
  if (floats * int64_t(sizeof(float)) > int64_t(winograd_limit_bytes()) || floats >= (int64_t(1) << 31))
    return ConvAlgo::Im2col;
  return a;
}

std::string winograd_build_options(int m) { return "-DWINO_M=" + std::to_string(m); }

std::vector<std::string> winograd_build_variants() { return {winograd_build_options(2), winograd_build_options(4)}; }

}  // namespace stylerf::nn
