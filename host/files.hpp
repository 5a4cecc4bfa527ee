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

// Temporary files of atomic writes in progress are removed when the process gets SIGINT or SIGTERM (the
// handler unlinks them, then lets the signal end the process as it would have). Every atomic write
// installs it where the signal still has its default action (a program's own handler is left alone). SIGKILL cannot be caught: see remove_stale_temps.
void install_temp_file_cleanup();
// Removes `path`.tmp-PID files left by processes that no longer run (a killed writer); returns how many.
// Files of a live process (another writer of the same target) are left alone. A file name "*" (DIR/*)
// means every NAME.tmp-PID in the folder. Atomic writes sweep each folder once per process this way.
int remove_stale_temps(const std::string& path);

}  // namespace stylerf::host
