// Small file helpers shared by everything that writes outputs: write to a temporary file beside the
// target, then rename, so a crash or a full disk never leaves a half-written file under the real name.
#pragma once
#include <functional>
#include <string>

namespace stylerf::host {

void write_file_atomic(const std::string& path, const std::string& bytes);
// Calls write(tmp_path) to produce the file, then renames tmp_path to path. Removes tmp on failure.
void write_atomic_with(const std::string& path, const std::function<void(const std::string& tmp_path)>& write);
std::string read_file(const std::string& path);  // throws Error naming the path when unreadable

}  // namespace stylerf::host
