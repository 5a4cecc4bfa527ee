// --supersample and --refine-contrast, shared by the commands that render StyleRF frames (stylize, eval-style, eval
// consistency, eval table): the --supersample rays only in the blocks at edges (lib/model/block_refine.hpp).
#pragma once
#include <boost/program_options.hpp>
#include <string>

namespace stylerf::cli {

extern const char* const kRefineContrastHelp;
// --supersample: "0" (the checkpoint's recipe's), "1".."8" (n x n rays a block) or "quincunx".
extern const char* const kSupersampleHelp;
boost::program_options::typed_value<std::string>* supersample_value(std::string* v);
// 0 for "0" (the checkpoint's), else model::parse_supersample's value; an error naming --supersample.
int supersample_from(const std::string& text);
// The option's value, defaulting to *v and shown as "0.15" rather than the float's 9 digits.
boost::program_options::typed_value<float>* refine_contrast_value(float* v);
// Finite and >= 0, else an error naming the option.
void check_refine_contrast(float v);

}  // namespace stylerf::cli
