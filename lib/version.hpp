// Which stylerf this is: the release version (project(VERSION) in CMakeLists.txt, its one source) and the git
// commit it was built from, for `stylerf --version`, run reports and the Python module.
#pragma once

namespace stylerf {

// "MAJOR.MINOR.PATCH".
const char* version();
// The short hash of the commit the library was built from, read at build time; "unknown" when the source
// was not a git checkout (a source archive, an sdist).
const char* git_commit();

}  // namespace stylerf
