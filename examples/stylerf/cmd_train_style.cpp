// stylerf train-style --features CKPT --styles DIR [--holdout-styles N] [--recipe fast|paper]
//                     [--minutes M | --iters N] -o CKPT [--resume]:
// the style stage (StyleRF stage 3) over a feature checkpoint: SICT + DST trained on many style images,
// the decoder fine-tuned, the grids frozen. Progress lines print the losses, the held-out styles' losses
// every --eval-every steps, s/it and ETA; checkpoints are atomic and store which styles were trained on.
#include <boost/program_options.hpp>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <set>
#include <sstream>

#include "examples/stylerf/cli_checks.hpp"
#include "examples/stylerf/commands.hpp"
#include "examples/stylerf/help.hpp"
#include "host/dist.hpp"
#include "host/error.hpp"
#include "host/runtime.hpp"
#include "lib/model/map_decoder.hpp"
#include "lib/scene/scene.hpp"
#include "lib/scene/scene_meta.hpp"
#include "lib/train/recipes.hpp"
#include "lib/train/style_trainer.hpp"

namespace po = boost::program_options;
namespace fs = std::filesystem;

namespace {

using stylerf::host::Error;

namespace train = stylerf::train;
namespace model = stylerf::model;

// All of train-style's options, as parsed (`given`: the options set on the command line).
struct StyleArgs {
  std::string features_path, styles_dir, out, device, sict_name = "volume-adaptive", dst_name = "bias", content_skip_name,
              warm_maps_name, style_decoder_name, recipe_name;
  int holdout = 12, iters = 0, log_every = 10, eval_every = 100, eval_styles = 0, ckpt_every = 200, warm = 0,
      decoder_warm = 0, styles_per_step = 1;
  int patch = 256, style_size = 512;
  double minutes = 0;
  float lr_stylizer = 1e-4f, lr_decoder = 1e-5f, lr_decay = 1.0f, warm_share = 1.0f, content_weight = 1.0f;
  uint64_t seed = 0;
  bool resume = false, force = false, timing = false;
  std::set<std::string> given;
  bool has(const char* option) const { return given.count(option) > 0; }
};

// Parses argv into a. --help lists what a user sets; --help-all adds the ablations and the run's plumbing.
// Returns -1 to go on, else the exit code (a help was shown).
int parse_style_args(int argc, char** argv, StyleArgs& a) {
  po::options_description desc("stylerf train-style --features CKPT --styles DIR -o CKPT [options]");
  desc.add_options()("help,h", "show this help")("help-all", "also show the ablation and logging options")(
      "features", po::value(&a.features_path), "feature-stage checkpoint")(
      "styles", po::value(&a.styles_dir), "folder of style images (.jpg/.png)")(
      "holdout-styles", po::value(&a.holdout)->default_value(12), "styles held out of training (evaluated, never trained on)")(
      "output,o", po::value(&a.out), "style checkpoint to write")(
      "iters", po::value(&a.iters), "iterations (default 25000, the paper's)")(
      "minutes", po::value(&a.minutes), "train for this many minutes (replaces --iters)")(
      "recipe", po::value(&a.recipe_name),
      "fast | paper: the settings below that a flag does not give (default: the feature checkpoint's profile's "
      "name; fast is the best measured, paper the paper's)")(
      "style-size", po::value(&a.style_size),
      "each style image is resized to this square, then a random 256 x 256 crop of it is the step's style; 512: "
      "the paper's; 256: the whole image, the scale eval-style and stylize feed the model")(
      "warm-start", po::value(&a.warm),
      "first N steps in 2D on a map per training view (no rendering; fast profile)")(
      "warm-maps", po::value(&a.warm_maps_name),
      "the warm start's maps: vgg (stage 2's cached relu3_1 targets of the photographs) | rendered (the feature "
      "field rendered once per training view: what rendered steps and inference feed the stylizer)")(
      "style-decoder", po::value(&a.style_decoder_name),
      "what draws the stylised maps: stage2 (the feature stage's decoder, fine-tuned: the paper's) | vgg-adain "
      "(VGG's frozen relu3_1 -> relu4_1, then AdaIN's pretrained decoder, fine-tuned at --lr-decoder; fast profile) | "
      "vgg-adain-relu4 (vgg-adain with relu4_1 re-normalised to the style's relu4_1 statistics: not the "
      "paper's; docs/results.md)")(
      "lr-stylizer", po::value(&a.lr_stylizer), "stylizer learning rate")(
      "lr-decoder", po::value(&a.lr_decoder), "decoder fine-tuning learning rate")(
      "lr-decay", po::value(&a.lr_decay),
      "both learning rates at the end of the run over their start, exponential in the run's progress (its "
      "time with --minutes; the stylizer's from its first step, after --decoder-warm); 1: constant, the paper's")(
      "styles-per-step", po::value(&a.styles_per_step),
      "styles (each with its own patch) whose gradients a step averages (default: one per MPI rank, 1 without "
      "MPI); the ranks share them round robin, and a resumed run keeps its checkpoint's unless given")(
      "seed", po::value(&a.seed)->default_value(0), "random seed")(
      "resume", po::bool_switch(&a.resume), "continue from the checkpoint at -o")(
      "force", po::bool_switch(&a.force), "overwrite an existing checkpoint at -o")(
      "device", po::value(&a.device), stylerf::cli::kDeviceHelp);
  po::options_description more("ablations and plumbing (--help-all)");
  more.add_options()("sict", po::value(&a.sict_name)->default_value("volume-adaptive"),
                     "volume-adaptive | vanilla-in | none (the paper's Fig. 7 ablations)")(
      "dst", po::value(&a.dst_name)->default_value("bias"), "bias | no-bias (ablation: DST without the adaptive bias)")(
      "content-skip", po::value(&a.content_skip_name),
      "on | off: beside DST, the composited features channel by channel, moved to the style's relu3_1 "
      "statistics (default: the recipe's)")(
      "decoder-warm", po::value(&a.decoder_warm)->default_value(0),
      "first N steps train the decoder alone to invert VGG relu3_1 of style crops (before --warm-start's; fast "
      "profile)")(
      "warm-share", po::value(&a.warm_share),
      "with --minutes, the warm start also ends once this fraction of the minutes is spent (1: its steps only)")(
      "content-weight", po::value(&a.content_weight),
      "the content loss's weight against the style loss's 20 (default: the recipe's; fast 3, paper 1, the "
      "paper's)")(
      "patch", po::value(&a.patch)->default_value(256), "patch side in pixels (multiple of 8)")(
      "log-every", po::value(&a.log_every)->default_value(10), "iterations between progress lines")(
      "eval-every", po::value(&a.eval_every)->default_value(100), "iterations between held-out evaluations (0: never)")(
      "eval-styles", po::value(&a.eval_styles)->default_value(0), "held-out styles in each evaluation (0: all)")(
      "ckpt-every", po::value(&a.ckpt_every)->default_value(200), "iterations between checkpoints")(
      "timing", po::bool_switch(&a.timing), "print per-kernel times at the end");
  po::options_description all;
  all.add(desc).add(more);
  po::variables_map vm;
  po::store(po::parse_command_line(argc, argv, all), vm);
  po::notify(vm);
  for (const auto& kv : vm)
    if (!kv.second.defaulted()) a.given.insert(kv.first);
  if (vm.count("help-all")) {
    stylerf::cli::print_help(std::cout, "train-style", all);
    return 0;
  }
  if (vm.count("help") || a.out.empty() || (!a.resume && (a.features_path.empty() || a.styles_dir.empty()))) {
    stylerf::cli::print_help(std::cout, "train-style", desc,
                             "(also --sict, --dst, --content-skip, --decoder-warm, --warm-share, --content-weight, --patch, --log-every, "
                             "--eval-every, --eval-styles, --ckpt-every, --timing: --help-all)");
    return vm.count("help") ? 0 : 2;
  }
  return -1;
}

// The flags given, over a recipe's config.
void apply_style_flags(const StyleArgs& a, train::StyleTrainConfig& cfg) {
  cfg.sict = stylerf::style::parse_sict_mode(a.sict_name);
  cfg.dst_bias = a.dst_name == "bias";
  if (a.has("content-skip")) cfg.content_skip = a.content_skip_name == "on";
  if (a.has("iters")) cfg.iters = a.iters;
  cfg.patch = a.patch;
  if (a.has("style-size")) cfg.style_size = a.style_size;
  if (a.has("lr-stylizer")) cfg.lr_stylizer = a.lr_stylizer;
  if (a.has("lr-decoder")) cfg.lr_decoder = a.lr_decoder;
  if (a.has("lr-decay")) cfg.lr_decay_ratio = a.lr_decay;
  if (a.has("warm-start")) cfg.warm_start = a.warm;
  if (a.has("warm-share")) cfg.warm_share = a.warm_share;
  if (a.has("content-weight")) cfg.weights.content = a.content_weight;
  if (a.has("warm-maps")) cfg.warm_maps = train::parse_warm_maps(a.warm_maps_name);
  if (a.has("style-decoder")) cfg.style_decoder = model::parse_style_decoder(a.style_decoder_name);
  // The recipe's grid phases belong to the vgg-adain decoders' VGG pool (the stage2 decoder has none).
  if (!model::map_decoder_for(cfg.style_decoder).has_vgg_pool()) cfg.decoder_phases = false;
  cfg.decoder_warm = a.decoder_warm;
  cfg.seed = a.seed;
  cfg.styles_per_step = a.has("styles-per-step") ? a.styles_per_step : stylerf::host::Dist::world().size();
}

// Every option checked before anything loads (names and values): the run's own here, the config's by the
// library's rules (StyleTrainConfig::validate) on the flags over the fast recipe.
void check_style_args(const StyleArgs& a) {
  if (a.has("minutes") && !(a.minutes > 0 && std::isfinite(a.minutes)))
    throw Error("--minutes must be a positive number of minutes");
  if (a.minutes > 0 && a.has("iters")) throw Error("--minutes and --iters exclude each other");
  if (a.log_every < 0 || a.eval_every < 0 || a.ckpt_every < 0 || a.eval_styles < 0)
    throw Error("--log-every, --eval-every, --eval-styles and --ckpt-every must be >= 0");
  if (a.dst_name != "bias" && a.dst_name != "no-bias")
    throw Error("--dst must be bias or no-bias, got '" + a.dst_name + "'");
  if (a.has("content-skip") && a.content_skip_name != "on" && a.content_skip_name != "off")
    throw Error("--content-skip must be on or off, got '" + a.content_skip_name + "'");
  if (!a.recipe_name.empty()) train::parse_recipe(a.recipe_name);
  if (!a.resume) {
    train::StyleTrainConfig probe = train::style_recipe(train::Recipe::Fast);
    apply_style_flags(a, probe);
    probe.validate();
  }
  stylerf::cli::check_checkpoint_output(a.out, a.resume, a.force);
}

// A new trainer: the recipe's settings (default: the feature checkpoint's profile's name), then every flag
// given over them.
std::unique_ptr<train::StyleTrainer> new_style_trainer(const StyleArgs& a, const stylerf::scene::Scene& scene,
                                                      const stylerf::io::Checkpoint& ck) {
  model::FeatureModel fm = model::FeatureModel::load(ck);
  const auto recipe = train::style_recipe_for(fm, a.recipe_name, a.features_path);
  train::StyleTrainConfig cfg = train::style_recipe(recipe);
  apply_style_flags(a, cfg);
  std::cout << "recipe " << train::recipe_name(recipe) << "\n";
  auto styles = train::StyleSet::from_dir(a.styles_dir, a.holdout, &std::cout);
  return std::make_unique<train::StyleTrainer>(scene, std::move(fm), std::move(styles), cfg, &std::cout);
}

// A setting as a person types it: 0.1 (std::to_string prints 0.100000).
std::string short_number(float v) {
  std::ostringstream o;
  o << v;
  return o.str();
}

void print_style_setup(train::StyleTrainer& trainer) {
  const auto& cfg = trainer.config();
  auto& m = trainer.model();
  std::cout << "style stage, " << model::decoder_profile_name(m.features.profile) << " profile (features at 1/"
            << m.stride() << " resolution); SICT " << stylerf::style::sict_mode_name(cfg.sict) << ", DST "
            << (cfg.dst_bias ? "with" : "without") << " bias" << (cfg.content_skip ? ", content skip" : "")
            << "; style decoder "
            << model::style_decoder_name(cfg.style_decoder) << (cfg.decoder_phases ? ", VGG's pool at its 4 grid phases" : "")
            << "\n"
            << "  " << cfg.styles_per_step << (cfg.styles_per_step == 1 ? " style" : " styles") << " a step"
            << (stylerf::host::Dist::world().size() > 1
                    ? ", dealt round robin over " + std::to_string(stylerf::host::Dist::world().size()) + " ranks"
                    : std::string())
            << "; " << trainer.styles().train.size() << " training styles, " << trainer.styles().holdout.size()
            << " held out; style images resized to " << cfg.style_size << " then cropped to " << cfg.style_crop << "\n"
            << "  losses: content (relu4_1) x" << cfg.weights.content << " + style (relu1_1..relu4_1 mean/std) x"
            << cfg.weights.style << (m.features.geo.has_background ? ", masked by opacity" : "") << "\n"
            << "  Adam lr stylizer " << cfg.lr_stylizer << ", decoder " << cfg.lr_decoder
            << (cfg.lr_decay_ratio < 1 ? " (decaying to " + short_number(cfg.lr_decay_ratio) + "x)" : std::string())
            << "; grids frozen; " << m.param_count() / 1e6 << "M trained parameters"
            << (cfg.warm_start > 0 ? "; " + std::to_string(cfg.warm_start) + " 2D warm-start steps first (" +
                                         train::warm_maps_name(cfg.warm_maps) + " maps" +
                                         (cfg.warm_share < 1
                                              ? "; with --minutes, ends at " +
                                                    std::to_string(int(std::lround(100 * cfg.warm_share))) +
                                                    "% of them if sooner)"
                                              : ")")
                                   : "")
            << (cfg.decoder_warm > 0 ? "; " + std::to_string(cfg.decoder_warm) + " decoder warm-up steps before them" : "")
            << std::endl;
}

int run_train_style(int argc, char** argv) {
  StyleArgs a;
  if (const int code = parse_style_args(argc, argv, a); code >= 0) return code;
  check_style_args(a);
  stylerf::cli::init_runtime(a.device, a.timing);

  const auto ck = a.resume ? stylerf::io::load_checkpoint(a.out, "style")
                           : stylerf::io::load_checkpoint(a.features_path, "features");
  const nlohmann::json scene_meta = ck.meta.value("scene", nlohmann::json::object());
  stylerf::scene::SceneOverrides o;
  o.log = &std::cout;
  const auto scene = stylerf::scene::open_scene_for(scene_meta, a.resume ? a.out : a.features_path, o).scene;

  std::unique_ptr<train::StyleTrainer> trainer;
  if (a.resume) {
    trainer = std::make_unique<train::StyleTrainer>(scene, ck, &std::cout);
    std::cout << "resuming from " << a.out << " at iteration " << trainer->iteration() << "\n";
    if (a.has("iters")) {
      train::StyleTrainConfig longer = trainer->config();
      longer.iters = a.iters;
      longer.validate();
      trainer->set_total_iters(a.iters);
    }
    if (a.has("styles-per-step")) trainer->set_styles_per_step(a.styles_per_step);
    if (trainer->done() && a.minutes <= 0)
      throw Error("--resume: checkpoint " + a.out + " is already at iteration " + std::to_string(trainer->iteration()) +
                  "; pass a larger --iters to continue");
  } else {
    trainer = new_style_trainer(a, scene, ck);
  }
  print_style_setup(*trainer);

  train::StyleRunOptions ro;
  ro.log = &std::cout;
  ro.log_every = a.log_every;
  ro.eval_every = a.eval_every;
  ro.eval_styles = a.eval_styles;
  ro.checkpoint = a.out;
  ro.checkpoint_every = a.ckpt_every;
  ro.time_budget_s = a.minutes * 60.0;
  ro.scene_meta = scene_meta;
  if (a.minutes > 0 && !a.resume) trainer->set_total_iters(1000000);  // refitted from the measured rate
  const auto sum = train::run_style_training(*trainer, ro);
  std::cout << "trained " << sum.iterations << " iterations in " << std::fixed << std::setprecision(1) << sum.seconds
            << " s (" << std::setprecision(2) << sum.seconds / std::max(1, sum.iterations) << " s/it); checkpoint "
            << a.out << std::endl;
  if (trainer->sync().steps > 0)
    std::cout << "gradients averaged over " << trainer->config().styles_per_step << " styles a step on "
              << train::sync_summary(trainer->sync(), stylerf::host::Dist::world().size()) << std::endl;
  std::cout << "peak RSS " << std::fixed << std::setprecision(0) << stylerf::cli::peak_rss_mb() << " MB" << std::endl;
  if (a.timing) std::cout << stylerf::host::Runtime::instance().timing_report();
  return 0;
}

stylerf::cli::Register reg("train-style", run_train_style);
}  // namespace
