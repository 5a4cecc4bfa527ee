// stylerf bench <gemm|conv|ops|field|density|targets|patch|dst|render|decoder-step> [--json FILE] [--repeats N] [--quick] [--device D]
#include <boost/program_options.hpp>
#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "bench/bench.hpp"
#include "bench/bench_density.hpp"
#include "bench/bench_field.hpp"
#include "bench/bench_targets.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "lib/nn/conv_algo.hpp"

namespace po = boost::program_options;

namespace {
// "a,b,c" -> {a, b, c}; an empty string -> {} (an empty item between commas stays, and is refused by the caller).
std::vector<std::string> comma_list(const std::string& s) {
  std::vector<std::string> out;
  for (size_t a = 0; !s.empty() && a <= s.size();) {
    const size_t b = std::min(s.find(',', a), s.size());
    out.push_back(s.substr(a, b - a));
    a = b + 1;
  }
  return out;
}

// The benchmarks, one line each, for --help.
std::string bench_list() {
  return "  gemm  GEMM GFLOP/s: CLBlast defaults, CLBlast tuned, own kernel, OpenBLAS\n"
         "  conv  conv forward/backward time for every decoder and VGG layer at 256x256\n"
         "  ops   perf mode of every NN op kernel (GB/s)\n"
         "  field VM grid sampling, ray marching, compositing (points/s, GB/s)\n"
         "  density  density-stage PSNR against wall time (lego 1/4, fern 1/8) and knob costs\n"
         "  targets  stage-2 target reads: per-ray gather fwd/bwd, patch read (GB/s)\n"
         "  patch    one patch step part by part (s, GFLOP/s): --stage 2|3 --profile fast|paper --size 256\n"
         "  dst      deferred vs per-point style transformation: time, peak memory, ratios (--size 256)\n"
         "  render   rays/s and s/view of rendering, s/step of training, per kernel: --ckpt DENSITY\n"
         "           [--scene DIR] [--max-views N] [--steps K] [--ert 0,1e-4,1e-3]\n"
         "  decoder-step  torch_step.py's work (decoder + VGG + losses + backward + Adam), median s/step:\n"
         "           --size 256 --decoder paper|fast [--conv-algo A]";
}

int run_bench(int argc, char** argv) {
  std::string which, device, parts, erts, decoder, conv_algo, content_skip = "off";
  stylerf::bench::BenchOptions opt;
  double minutes = 0, knob_minutes = 0;  // bench density's budgets; 0: the defaults for --quick or not
  po::options_description desc("stylerf bench <gemm|conv|ops|field|density|targets|patch|dst|render|decoder-step> [options]");
  desc.add_options()("help,h", "show this help")("json", po::value(&opt.json_path), "also write results as JSON to FILE")(
      "repeats", po::value(&opt.repeats)->default_value(3), "timed repetitions after one warm-up")(
      "quick", po::bool_switch(&opt.quick), "smaller shapes (smoke run)")(
      "minutes", po::value(&minutes), "density: training minutes per scene (default 30; with --quick 4)")(
      "knob-minutes", po::value(&knob_minutes), "density: training minutes per knob row (default 5; with --quick 1)")(
      "parts", po::value(&parts), "density: comma list of lego, fern, knobs; ops: of spatial, norm, layout, "
                                  "style, eval, shell (default all)")(
      "ckpt", po::value(&opt.ckpt), "patch: density or feature checkpoint whose geometry to render")(
      "stage", po::value(&opt.stage)->default_value(2), "patch: training stage (2 features, 3 style)")(
      "profile", po::value(&opt.profile)->default_value("fast"), "patch: decoder profile, fast | paper")(
      "size", po::value(&opt.size)->default_value(256), "patch: side in pixels (multiple of 8)")(
      "style-decoder", po::value(&opt.style_decoder)->default_value("stage2"),
      "patch --stage 3: the decoder of stylised maps, stage2 | vgg-adain | vgg-adain-relu4 (train-style --style-decoder)")(
      "decoder-phases", po::bool_switch(&opt.decoder_phases),
      "patch --stage 3 --style-decoder vgg-adain: VGG's pool at all four grid phases (the fast recipe's)")(
      "content-skip", po::value(&content_skip)->default_value("off"),
      "patch --stage 3: on | off, the content skip beside DST (the fast recipe's: on; train-style --content-skip)")(
      "scene", po::value(&opt.scene), "render: scene directory (default: the checkpoint's)")(
      "max-views", po::value(&opt.views)->default_value(3), "render: held-out views to render, evenly spaced")(
      "steps", po::value(&opt.steps)->default_value(10), "render: training steps to time (0: none)")(
      "ert", po::value(&erts), "render: comma list of early-termination thresholds to compare (0: off)")(
      "decoder", po::value(&decoder), "decoder-step: decoder, paper | fast (default paper)")(
      "conv-algo", po::value(&conv_algo), "3x3 conv algorithm: auto, im2col, winograd2, winograd4 (default auto)")(
      "device", po::value(&device), stylerf::cli::kDeviceHelp);
  po::options_description hidden;
  hidden.add_options()("which", po::value(&which));
  po::positional_options_description pos;
  pos.add("which", 1);
  po::options_description all;
  all.add(desc).add(hidden);
  stylerf::cli::apply_renamed_flags("bench", argc, argv, {{"--views", "--max-views"}});
  for (int i = 1; i < argc; ++i)  // a budget in seconds has no alias: its number would be read as minutes
    if (const std::string a = argv[i]; a.rfind("--budget", 0) == 0 || a.rfind("--knob-budget", 0) == 0)
      throw std::runtime_error(a.substr(0, a.find('=')) + " (seconds) is now --" +
                               (a[2] == 'b' ? "minutes" : "knob-minutes") + " (minutes)");
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(all).positional(pos).run(), vm);
  po::notify(vm);
  if (vm.count("help") || which.empty()) {
    stylerf::cli::print_help(std::cout, "bench", desc, bench_list());
    return which.empty() && !vm.count("help") ? 2 : 0;
  }
  if (opt.views < 1 || opt.steps < 0) throw std::runtime_error("--max-views must be >= 1 and --steps >= 0");
  if (content_skip != "on" && content_skip != "off")
    throw std::runtime_error("--content-skip must be on or off, got '" + content_skip + "'");
  opt.content_skip = content_skip == "on";
  for (const std::string& e : comma_list(erts)) {
    size_t used = 0;
    float v = -1;
    try {
      v = std::stof(e, &used);
    } catch (const std::exception&) {
    }
    if (used != e.size() || !(v >= 0.0f && v < 1.0f))
      throw std::runtime_error("--ert: '" + e + "' is not a threshold in [0, 1) (0 turns early termination off)");
    opt.erts.push_back(v);
  }
  if (opt.repeats < 1) throw std::runtime_error("--repeats must be at least 1");
  if (!(minutes >= 0) || !(knob_minutes >= 0)) throw std::runtime_error("--minutes and --knob-minutes must be >= 0");
  opt.budget_s = minutes * 60.0;
  opt.knob_budget_s = knob_minutes * 60.0;
  for (const std::string& p : comma_list(parts)) {
    const bool ops = which == "ops";
    const bool known = ops ? (p == "spatial" || p == "norm" || p == "layout" || p == "style" || p == "eval" || p == "shell")
                           : (p == "lego" || p == "fern" || p == "knobs");
    if (!known)
      throw std::runtime_error("--parts: unknown part '" + p + "' for bench " + which +
                               (ops ? " (spatial, norm, layout, style, eval, shell)" : " (lego, fern, knobs)"));
    opt.parts.push_back(p);
  }
  if (!decoder.empty()) {
    if (which != "decoder-step") throw std::runtime_error("--decoder is an option of bench decoder-step (patch takes --profile)");
    if (decoder != "paper" && decoder != "fast")
      throw std::runtime_error("--decoder: '" + decoder + "' is not a decoder (paper, fast)");
    opt.profile = decoder;
  } else if (which == "decoder-step") {
    opt.profile = "paper";
  }
  if (!conv_algo.empty()) stylerf::nn::set_default_conv_algo(stylerf::nn::parse_conv_algo(conv_algo));
  stylerf::cli::init_runtime(device, false);
  if (which == "gemm") return stylerf::bench::bench_gemm(opt);
  if (which == "conv") return stylerf::bench::bench_conv(opt);
  if (which == "ops") return stylerf::bench::bench_ops(opt);
  if (which == "field") return stylerf::bench::bench_field(opt);
  if (which == "density") return stylerf::bench::bench_density(opt);
  if (which == "targets") return stylerf::bench::bench_targets(opt);
  if (which == "patch") return stylerf::bench::bench_patch(opt);
  if (which == "dst") return stylerf::bench::bench_dst(opt);
  if (which == "render") return stylerf::bench::bench_render(opt);
  if (which == "decoder-step") return stylerf::bench::bench_decoder_step(opt);
  std::cerr << "stylerf bench: unknown benchmark '" << which << "' (gemm, conv, ops, field, density, targets, patch, dst, render, decoder-step)\n";
  return 2;
}
stylerf::cli::Register reg("bench", run_bench);
}  // namespace
