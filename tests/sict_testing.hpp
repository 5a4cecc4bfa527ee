// What the SICT suites (test_sict_dst, test_sict_factored) share: the reference's mode for a library mode.
#pragma once
#include "lib/style/sict.hpp"
#include "tests/style_reference.hpp"

namespace stylerf::testing {

inline style_ref::Mode ref_mode(style::SictMode m) {
  return m == style::SictMode::VolumeAdaptive ? style_ref::Mode::VolumeAdaptive
                                               : (m == style::SictMode::VanillaIn ? style_ref::Mode::VanillaIn
                                                                                  : style_ref::Mode::None);
}

}  // namespace stylerf::testing
