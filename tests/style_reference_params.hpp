// The bridge from a device DST module to the double reference's parameters (tests/style_reference.hpp):
// kept apart so the reference itself shares nothing with the device code.
#pragma once
#include "lib/style/dst.hpp"
#include "tests/style_reference.hpp"
#include "tests/testing.hpp"

namespace stylerf::testing {

inline style_ref::DstParams dst_ref_params(const style::Dst& d) {
  return {to_double(d.w0.value.to_host()),   to_double(d.b0.value.to_host()),   to_double(d.w2.value.to_host()),
          to_double(d.b2.value.to_host()),   to_double(d.w4.value.to_host()),   to_double(d.b4.value.to_host()),
          to_double(d.fc_w.value.to_host()), to_double(d.fc_b.value.to_host()), to_double(d.unzip_w.value.to_host())};
}

}  // namespace stylerf::testing
