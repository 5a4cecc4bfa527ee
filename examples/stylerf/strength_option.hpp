// --strength, shared by the commands that stylise frames from a style checkpoint (stylize, view, eval style,
// eval consistency, eval table): how much of the stylised features a frame draws (StyleModel::strength).
#pragma once
#include <boost/program_options.hpp>

#include "lib/model/style_model.hpp"

namespace stylerf::cli {

extern const char* const kStrengthHelp;
// The option's value; its default, kCheckpointStrength, keeps the checkpoint's (1 unless set).
constexpr float kCheckpointStrength = -1.0f;
boost::program_options::typed_value<float>* strength_value(float* v);
// Sets m's strength unless v is kCheckpointStrength; an error naming --strength when it is out of [0, 1] or
// the model cannot blend.
void apply_strength(model::StyleModel& m, float v);

}  // namespace stylerf::cli
