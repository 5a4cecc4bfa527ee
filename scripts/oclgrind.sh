#!/usr/bin/env bash
# Test suites on Oclgrind, a simulated OpenCL device that reports out-of-bounds accesses, data races and
# invalid API use: a second, stricter platform than PoCL. Its LLVM cannot build restrict-qualified
# kernels, so they are built with restrict defined away (STYLERF_CL_OPTIONS=-Drestrict=).
#   bash scripts/oclgrind.sh [suite ...]      (default: a few fast kernel suites; needs a build in build/)
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v oclgrind > /dev/null; then
  SUDO=$([ "$(id -u)" = 0 ] && echo "" || echo sudo)
  $SUDO apt-get install -y oclgrind > /dev/null
fi
suites=${*:-test_reduce test_norm test_spatial test_loss test_render}
export STYLERF_CL_OPTIONS="-Drestrict=" STYLERF_TEST_DATA=${STYLERF_TEST_DATA:-$PWD/../shared/data}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$HOME/.cache/stylerf/pocl}
status=0
for s in $suites; do
  log=build/oclgrind_$s.log
  if oclgrind --data-races --uninitialized "build/$s" > "$log" 2>&1 && ! grep -qE "Invalid (read|write)|data race|Uninitialized|error" "$log"; then
    echo "$s: clean under Oclgrind"
  else
    echo "$s: FINDINGS (see $log)"; status=1
  fi
done
exit $status
