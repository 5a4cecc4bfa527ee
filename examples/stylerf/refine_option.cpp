#include "examples/stylerf/refine_option.hpp"

#include <sstream>

#include "examples/stylerf/cli_checks.hpp"

namespace stylerf::cli {

const char* const kRefineContrastHelp =
    "the --supersample rays only in blocks whose centre ray differs from a neighbour's by more than this "
    "(opacity, or content in units of its spread over the frame); 0: every block";

boost::program_options::typed_value<float>* refine_contrast_value(float* v) {
  std::ostringstream shown;
  shown << *v;
  return boost::program_options::value(v)->default_value(*v, shown.str());
}

void check_refine_contrast(float v) { check_range("--refine-contrast", v, 0.0, 1e30); }

}  // namespace stylerf::cli
