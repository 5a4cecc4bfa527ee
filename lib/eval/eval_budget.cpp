#include "lib/eval/eval_budget.hpp"

#include <algorithm>
#include <cmath>

namespace stylerf::eval {

namespace {
constexpr double kStartupPerStep = 8.0;  // seconds: weights, checkpoint, scene, style codes (lego 1/4 runs)
constexpr int kMixCells = 25;
// Fitted to fern at 1008x756 (where a unit measured a style2d) and two runs at 504x378; not extrapolated:
// a smaller frame keeps 504x378's unit, a larger one 1008x756's.
constexpr double kFullSizePixels = 1008.0 * 756.0, kSmallestFittedPixels = 504.0 * 378.0;
constexpr double kPixelExponent = 0.4;
// An AlexNet LPIPS pair over a VGG-16 one, within the table: `eval consistency` on lego's RGB frames, 24
// pairs 1.3 vs 6.4 s (0.20); milk carton 1/4's table of 3 styles x 16 frames, 28 vs ~122 s over its 105 s
// without LPIPS (0.23; 2026-11-30).
constexpr double kAlexOverVgg = 0.2;
}  // namespace

double aux_unit(const FrameCost& c) {
  if (!(c.pixels > 0)) return c.style2d;
  const double px = std::clamp(c.pixels, kSmallestFittedPixels, kFullSizePixels);
  return c.style2d * std::pow(px / kFullSizePixels, kPixelExponent);
}

double eval_seconds(const FrameCost& c, const EvalCounts& n) {
  // s: the probed frame's own 2D work (the videos' and the mix sheet's frames); u: the other 2D work.
  const double k = c.content, s = c.style2d, u = aux_unit(c), rgb = c.rgb > 0 ? c.rgb : c.style2d;
  // eval-style: each view's content once; per style ours, AdaIN's (an encoder and a decoder), the VGG
  // losses of both and their structure score (an LPIPS pair each, against the true view).
  const double style_eval = n.eval_views * (k + n.holdout * (4.0 + 2.0 * n.structure_pair) * u);
  // videos: each frame's content once, then each shown style.
  const double videos = n.video_frames * (k + n.shown * s);
  const double mix = k + kMixCells * s;
  // table: the RGB floor's frames (their render gives the warps too) and their LPIPS pairs (t-1 and t-7);
  // the content of its frames once (eval table shares it between styles); per style our frames and
  // AdaIN's, and LPIPS pairs for both.
  const int pairs = (n.table_frames - 1) + std::max(0, n.table_frames - 7);
  const double lp = n.lpips_pair;
  const double table = n.table_frames * rgb + pairs * lp * u + n.table_frames * k +
                       n.table_styles * (2.0 * n.table_frames * u + 2.0 * pairs * lp * u);
  // Scene statistics: each of the 4 steps renders its views' content at the frames' rays a block (a content
  // each); per style (eval-style's held-out ones, the videos', the mix sheet's 25 cells, the table's) DST and
  // the tail on each view, counted as half a unit (no decoder, no losses).
  const double stats_k = n.stats_one_ray ? k / std::max(1, c.rays_per_block) : k;
  const double stats =
      n.scene_stats_views * (4.0 * stats_k + (n.holdout + n.shown + n.table_styles + kMixCells) * 0.5 * u);
  return style_eval + videos + mix + table + stats + 4 * kStartupPerStep;
}

double lpips_pair_units(LpipsNet net) { return net == LpipsNet::Vgg ? 2.0 : 2.0 * kAlexOverVgg; }

EvalCounts fit_eval(const FrameCost& c, const EvalCounts& wanted, double seconds) {
  // Each stage lowers one count down to its least (never below what was wanted), in this order, until the
  // evaluation fits: the videos first, then the scores by halves before their least useful sizes.
  struct Stage {
    int EvalCounts::*count;
    int least;
  };
  static constexpr Stage kStages[] = {
      {&EvalCounts::video_frames, 24}, {&EvalCounts::shown, 1},        {&EvalCounts::video_frames, 8},
      {&EvalCounts::holdout, 6},       {&EvalCounts::table_frames, 12}, {&EvalCounts::eval_views, 3},
      {&EvalCounts::holdout, 4},       {&EvalCounts::eval_views, 2},    {&EvalCounts::table_frames, 8},
      {&EvalCounts::table_styles, 1},
  };
  EvalCounts n = wanted;
  for (const Stage& st : kStages)
    while (eval_seconds(c, n) > seconds && n.*st.count > std::min(st.least, wanted.*st.count)) --(n.*st.count);
  return n;
}

double eval_share_seconds(double left_s, double nominal_style_s, double report_left_s) {
  if (!(left_s > 0)) return 0;
  const double style_minimum = std::clamp(kStyleSecondsEnough, 0.35 * left_s, 0.65 * left_s);
  const double share = std::max(left_s - nominal_style_s, left_s - style_minimum);
  return std::clamp(std::min(share, report_left_s), 0.0, left_s);
}

std::string describe_cuts(const EvalCounts& wanted, const EvalCounts& got) {
  std::string s;
  if (got.video_frames < wanted.video_frames)
    s += "video frames " + std::to_string(wanted.video_frames) + " -> " + std::to_string(got.video_frames);
  auto cut = [&](const char* what, int from, int to) {
    if (to < from) s += std::string(s.empty() ? "" : ", ") + what + " " + std::to_string(from) + " -> " + std::to_string(to);
  };
  cut("video styles", wanted.shown, got.shown);
  cut("held-out styles scored", wanted.holdout, got.holdout);
  cut("views scored", wanted.eval_views, got.eval_views);
  cut("table frames", wanted.table_frames, got.table_frames);
  cut("table styles", wanted.table_styles, got.table_styles);
  return s;
}

}  // namespace stylerf::eval
