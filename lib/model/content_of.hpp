// A renderer result as the style-independent content the style stage reads: shared by StyleModel's
// training render (style_model.cpp) and its inference over a whole camera (camera_content.cpp).
#pragma once
#include "lib/model/style_model.hpp"

namespace stylerf::model {

// r: a RayResult or a GroupResult (the same per-ray fields).
template <class Result>
StyleModel::Content content_of(const Result& r) {
  StyleModel::Content c;
  c.c = r.value;
  c.kept_acc = r.kept_acc;
  c.acc = r.acc;
  c.depth = r.depth;
  c.samples = r.samples;
  c.kept = r.kept;
  return c;
}

}  // namespace stylerf::model
