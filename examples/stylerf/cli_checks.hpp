// Checks every command runs on its options before any work: numbers in range (NaN never means "the
// default"), and an output checkpoint that can be written and is not overwritten by accident. Each error
// names the option.
#pragma once
#include <string>

namespace stylerf::cli {

// lo <= v <= hi, and finite; `option` is the flag as the user typed it ("--lr-grid").
void check_range(const std::string& option, double v, double lo, double hi);
void check_int_range(const std::string& option, long long v, long long lo, long long hi);

// The checkpoint at `out` before training starts: required, not a folder, its folder exists (or can be
// made) and is writable (a probe file is created and removed); an existing file needs --resume (continue
// it) or --force (overwrite it); --resume needs an existing file. Also removes temporary files a killed
// earlier writer left beside it.
void check_checkpoint_output(const std::string& out, bool resume, bool force);

// The flag that sets a library config field (host::SettingError::field()): "--" and the field with '-' for
// '_' ("lr_decoder" -> "--lr-decoder"), except where the flag has its own name ("lr_decay_ratio" ->
// "--lr-decay").
std::string flag_for_field(const std::string& field);

}  // namespace stylerf::cli
