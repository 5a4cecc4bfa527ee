// --refine-contrast, shared by the commands that render StyleRF frames (stylize, eval-style, eval
// consistency, eval table): the --supersample rays only in the blocks at edges (lib/model/block_refine.hpp).
#pragma once
#include <boost/program_options.hpp>
#include <string>

namespace stylerf::cli {

extern const char* const kRefineContrastHelp;
// The option's value, defaulting to *v and shown as "0.15" rather than the float's 9 digits.
boost::program_options::typed_value<float>* refine_contrast_value(float* v);
// Finite and >= 0, else an error naming the option.
void check_refine_contrast(float v);

}  // namespace stylerf::cli
