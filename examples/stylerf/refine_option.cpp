#include "examples/stylerf/refine_option.hpp"

#include <sstream>

#include "examples/stylerf/cli_checks.hpp"
#include "host/error.hpp"
#include "lib/model/style_model.hpp"

namespace stylerf::cli {

const char* const kRefineContrastHelp =
    "the --supersample rays only in blocks whose centre ray differs from a neighbour's by more than this "
    "(opacity, or content in units of its spread over the frame); 0: every block";

const char* const kSupersampleHelp =
    "content rays per feature-map block: n (n x n, averaged) or quincunx (the centre ray and the four corner rays, "
    "shared with the neighbouring blocks: about 2 rays a block); anti-aliasing: steadier video for up to n^2 x the "
    "content render; 0: the checkpoint's recipe's";

boost::program_options::typed_value<std::string>* supersample_value(std::string* v) {
  return boost::program_options::value(v)->default_value("0");
}

int supersample_from(const std::string& text) {
  if (text == "0") return 0;
  try {
    return model::parse_supersample(text);
  } catch (const host::Error& e) {
    throw host::Error("--supersample: " + std::string(e.what()));
  }
}

boost::program_options::typed_value<float>* refine_contrast_value(float* v) {
  std::ostringstream shown;
  shown << *v;
  return boost::program_options::value(v)->default_value(*v, shown.str());
}

void check_refine_contrast(float v) { check_range("--refine-contrast", v, 0.0, 1e30); }

}  // namespace stylerf::cli
