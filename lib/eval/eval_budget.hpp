// How `stylerf run --minutes M` keeps to M (lib/eval so that tests and research code reach it): what its evaluation will cost, predicted from a measured
// frame, and what it can keep when that does not fit.
//
// Evaluation cost grows with the image and the scene: 4 minutes for lego at 200x200, about 35 at 800x800,
// and hours for fern at 1008x756 (a frame there is 40 s, 35 of them the style-independent content). A
// fixed share of the budget cannot hold that, so the run measures, after the feature stage, what one
// frame costs on this machine with this scene (a probe: a one-step style checkpoint and a 3-frame
// stylize; the frame's cost does not depend on the trained weights' values), predicts the evaluation
// from the counts below, gives the style stage what is left, and shrinks the counts when the evaluation
// would take more than its share.
#pragma once
#include <limits>
#include <string>

#include "lib/eval/lpips.hpp"

namespace stylerf::eval {

// Measured costs on this machine and scene, in seconds.
struct FrameCost {
  double content = 0;  // one frame's content (SICT output, opacity, depth) at the recipe's rays per block
  double style2d = 0;  // one style's DST and decoder on it, at the frame's size
  // The rays per block `content` was measured at (n x n). The scene statistics render their views at the
  // same rays, so each costs a `content` (before 2026-11-30 at one ray a block: EvalCounts::stats_one_ray).
  int rays_per_block = 1;
  // One RGB view of the density stage at the frame's size (the consistency table's RGB floor, whose
  // render also gives every method's warps); 0: not measured, counted as a style2d. Fern at 1008x756:
  // ~30 s, 14x its style2d, so counting it as one left 8 minutes of the table out of the plan.
  double rgb = 0;
  // The frame's pixels (width x height); 0: unknown, the 2D work beyond the frame counted at full style2d.
  double pixels = 0;
};

// The 2D work of the evaluation beyond the probed frame (AdaIN frames, VGG losses, LPIPS pairs, the scene
// statistics' DST and tail) in seconds of one unit, from the probed style2d. Measured: that work shrinks
// with the pixels faster than the probed style2d does (likely a per-frame cost in the latter, launches and
// the PNG, not timed apart). At and above fern's 1008x756 a unit is a style2d; below, style2d x
// (pixels / 1008x756)^0.4 (fern at 504x378: 0.57 style2d; without it one run's plan took 1102 s for an
// evaluation of 664), held at 504x378's value for smaller frames (nothing smaller was measured).
double aux_unit(const FrameCost& c);

// What the evaluation renders.
struct EvalCounts {
  int eval_views = 5;     // eval-style's test views
  int holdout = 12;       // held-out styles eval-style scores on each
  int video_frames = 60;  // frames of each video
  int shown = 3;          // styles with a video
  int table_styles = 3;   // styles with a consistency row (the table scores each against per-frame AdaIN)
  int table_frames = 16;  // frames the consistency table scores
  // Training views whose content each step renders once more for the scene's relu4_1 statistics (the
  // vgg-adain-relu4 decoder: model::SceneStyleStats), and under each of its styles runs DST and VGG's
  // tail on; 0 for decoders that read none.
  int scene_stats_views = 0;
  // Whether those views render at one ray a block, as before 2026-11-30 (the runs the fits below were made
  // on), rather than at the frames' rays.
  bool stats_one_ray = false;
  // Units an LPIPS pair of the table costs (lpips_pair_units; the fits below were made with VGG-16's).
  double lpips_pair = 2.0;
  // Units an LPIPS pair of eval-style's structure score costs (two a style and view: ours and AdaIN's
  // against the true view); 0 for evaluations that do not score it (the runs the fits below were made on).
  double structure_pair = 0.0;
};
// An LPIPS pair of the consistency table in aux_units, by trunk: VGG-16's 2 is the fitted value (the
// three 90-minute fern runs below); AlexNet's is that times the two trunks' ratio measured on the same
// table (docs/results.md, the LPIPS trunk row).
double lpips_pair_units(LpipsNet net);

// Predicted seconds of the evaluation steps after the style stage (eval-style, videos, mix sheet,
// consistency table), from the frame's costs, with each step's scene statistics where the decoder reads
// them (the mix sheet's for each of its 25 cells). What a step does beyond frames is counted in frames of
// the same size: a 2D AdaIN frame, a VGG loss evaluation and an LPIPS pair each about an aux_unit, plus a
// start-up allowance per step (loading weights, the scene, encoding styles). Checked against three 90-minute
// fern runs (tests/test_eval_budget.cpp): at 1008x756, 2118 s predicted for the 2161 s its steps took
// (each step within 11%); at 504x378, two runs whose probes measured a style2d of 1.68 and 1.13 s (the
// same frames: the probe's two timed frames are noisy), 789 s for 664 and 944 s for 1015 (+19%, -7%).
double eval_seconds(const FrameCost& c, const EvalCounts& n);

// The counts to evaluate with in `seconds`: `wanted` when it fits, else fewer video frames (down to 24),
// then fewer video styles (down to 1), then fewer video frames (down to 8); then the scores, first to about
// half: held-out styles scored to 6, table frames to 12, views scored to 3; then to their least useful
// sizes: held-out styles to 4, views to 2, table frames to 8 (its long range needs t - 7); and last the
// table's styles, to 1. The table's styles go last because its consistency ratios are averaged over them:
// tied to the videos' styles, a 544x960 run's table scored one style where 3 were asked for. A table style
// costs about what two held-out styles scored on 5 views do; there a plan now scores 6 held-out styles on 4
// views and a table of 3 styles x 12 frames, where it scored 7 on 5 and a table of 1 style x 16.
// At 800x800 the scores alone (12 styles x 5 views, 16 table frames) are ~20 minutes on a 2-core CPU.
// The result may still not fit: the caller says so.
EvalCounts fit_eval(const FrameCost& c, const EvalCounts& wanted, double seconds);

// The most of `left_s` (the run's seconds left when the style stage is planned) the evaluation may take;
// the style stage gets the rest. The style stage keeps `nominal_style_s` (the --minutes split's share)
// where that leaves the evaluation more, and otherwise a minimum: kStyleSecondsEnough, held between 35%
// and 65% of what is left. Why a minimum and not a share: the held-out style loss gains at most ~3% after
// ~300 steps (checked every 100 steps in three 90-minute runs at 504x378: fern 15.24 at step 300 -> 14.73
// at 719 and 14.81 -> 14.40 at 676, horns 17.00 at 300 -> 16.81 at 608), while the evaluation's cuts take
// what a user sees: with 35% of what was left, horns 1/8's videos were cut to 8 frames of one style.
// `report_left_s` caps it: what is left of the report's share of the run (kReportShare of --minutes, less
// what the report has already taken: the held-out renders and the probe), so that training keeps the run.
// A 90-minute run on an 800x800 scene took 25 of its minutes for the report under the rule above alone
// (held-out renders of all 200 test views, 3 videos of 60 frames) and left the style stage 16.
double eval_share_seconds(double left_s, double nominal_style_s,
                          double report_left_s = std::numeric_limits<double>::infinity());
// The most of a run's time its report (held-out renders, probe, evaluation, videos, table) may take.
constexpr double kReportShare = 0.15;
// `stylerf run` plans with its predictions x this: the probe's two timed frames are noisy (see above).
constexpr double kEvalMargin = 1.15;
constexpr double kStyleSecondsEnough = 15 * 60.0;  // ~360 steps at 504x378 (2.3-2.5 s a step), ~900 on lego 1/4

// One line naming what was cut from `wanted` to get `got` ("" when nothing was).
std::string describe_cuts(const EvalCounts& wanted, const EvalCounts& got);

}  // namespace stylerf::eval
