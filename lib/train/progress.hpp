// Small formatting shared by the training loops' progress lines.
#pragma once
#include <string>

namespace stylerf::train {

// Seconds as "1h2m3s" / "2m3s" / "3s"; "?" when not finite or negative (an ETA not known yet).
std::string hms(double seconds);

}  // namespace stylerf::train
