#!/usr/bin/env bash
# The test suite under AddressSanitizer + UndefinedBehaviorSanitizer (a separate build in build-asan).
# Leaks inside the OpenCL driver (PoCL, LLVM) are not ours and are suppressed by library name
# (tests/asan_leaks.supp); everything in libstylerf and the tests is checked.
#   bash scripts/sanitize.sh [ctest args, e.g. -R test_io]
set -euo pipefail
cd "$(dirname "$0")/.."
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$HOME/.cache/stylerf/pocl}
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTYLERF_SANITIZE=ON > /dev/null
cmake --build build-asan -j"$(nproc)"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export LSAN_OPTIONS=suppressions=$PWD/tests/asan_leaks.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cd build-asan && ctest --output-on-failure "$@"
