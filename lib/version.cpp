#include "lib/version.hpp"

// STYLERF_VERSION comes from CMakeLists.txt (this file's compile definitions); git_commit.inc is rewritten by
// cmake/git_commit.cmake on every build, and only when the commit changed.
#include "git_commit.inc"

#ifndef STYLERF_VERSION
#error "STYLERF_VERSION must be defined by the build (CMakeLists.txt)"
#endif

namespace stylerf {

const char* version() { return STYLERF_VERSION; }
const char* git_commit() { return STYLERF_GIT_COMMIT; }

}  // namespace stylerf
