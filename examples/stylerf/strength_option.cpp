#include "examples/stylerf/strength_option.hpp"

#include <string>

#include "host/error.hpp"

namespace stylerf::cli {

const char* const kStrengthHelp =
    "stylisation strength in [0, 1]: each ray's stylised features blended with its own (0: 2D AdaIN at "
    "relu4_1 of the scene's features); default: the checkpoint's (1 unless set)";

boost::program_options::typed_value<float>* strength_value(float* v) {
  return boost::program_options::value(v)->default_value(kCheckpointStrength, "checkpoint");
}

void apply_strength(model::StyleModel& m, float v) {
  if (v == kCheckpointStrength) return;
  try {
    m.set_strength(v);
  } catch (const host::Error& e) {
    throw host::Error("--strength: " + std::string(e.what()));
  }
}

}  // namespace stylerf::cli
