// The metrics' guard against failed renders: a NaN or infinite pixel reaching a score is an Error naming
// where it is, never a NaN (or a silently smaller) score.
#pragma once
#include <string>

#include "lib/io/image.hpp"

namespace stylerf::eval {

// The first NaN or infinite value of an image, described for an error message ("a NaN value at pixel x,y,
// channel c", "an infinite value at ..."); "" when every value is finite.
std::string non_finite_at(const io::Image& im);

}  // namespace stylerf::eval
