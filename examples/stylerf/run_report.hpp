// What `stylerf run` leaves for people and programs: OUT/summary.json (the numbers) and OUT/index.html
// (the numbers beside the pictures and videos), read from the outputs of the run's steps.
#pragma once
#include <iosfwd>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace stylerf::cli {

struct RunReportInput {
  std::string out, recipe, scene;
  std::string styles;                     // the style images' folder (the held-out styles shown beside their results)
  nlohmann::json recipe_settings;         // what the recipe set (its stages' settings)
  std::string command_line;               // the run's, as a shell would take it (shell_command_line)
  nlohmann::json device;                  // device_record(): the OpenCL device the steps ran on
  nlohmann::json build;                   // build_record(): stylerf's version and commit
  double minutes = 0;                     // the training budget asked for
  nlohmann::json steps;                   // PipelineSteps::record(): seconds per step
  std::vector<std::string> shown_styles;  // the videos' styles (the table names its own)
  std::vector<std::string> corners;       // the mix sheet's four styles
  nlohmann::json plan;                    // under --minutes: the measured frame, the predicted evaluation
                                          // and what was cut to fit (null otherwise)
};

// The degeneracy limits `stylerf run --check` (and the demo) hold a run to: a stylizer that ignores its
// style input, or one whose frames flicker, fails one of them.
struct RunLimits {
  double style_loss_ratio = 1.5;       // held-out style loss over 2D AdaIN's, at most
  double mix_corner_min = 0.01;        // mean absolute difference of the closest mix-sheet corners, at least
  double short_rmse_ratio = 0.8;       // StyleRF / per-frame AdaIN short-range RMSE, at most
};

struct RunSummary {
  nlohmann::json json;                // what summary.json holds
  std::vector<std::string> failures;  // the RunLimits not met, each with its value
};

// Reads the steps' outputs under in.out, writes summary.json and index.html there (atomically).
RunSummary write_run_report(const RunReportInput& in, const RunLimits& limits = {});
void print_run_summary(const RunSummary& s, std::ostream& os);

}  // namespace stylerf::cli
