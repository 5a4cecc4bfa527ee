#!/usr/bin/env bash
# Test suites on Oclgrind, a simulated OpenCL device that reports out-of-bounds accesses, data races and
# invalid API use: a second, stricter platform than PoCL. Runs every suite CTest runs (package_find_package
# included: its example runs on Oclgrind), each under `oclgrind --data-races --check-api` with a time
# limit; a suite is clean when it passes and Oclgrind reported nothing. One line per suite, then a summary;
# exit status 1 on any finding or timeout. Logs: $BUILD_DIR/oclgrind_<suite>.log (doctest durations in them).
#   bash scripts/oclgrind.sh [suite ...]      (default: every CTest suite of the build)
#   BUILD_DIR=build-ocl                        build directory (default build; built as usual with cmake)
#   OCLGRIND_SUITE_TIMEOUT=600                 seconds per suite (default 600)
# Under Oclgrind (21.10, LLVM 14):
# - kernels are built with restrict defined away (STYLERF_CL_OPTIONS=-Drestrict=): inlining a noalias
#   parameter leaves llvm.experimental.noalias.scope.decl calls, which its interpreter cannot run. A struct
#   return is such a parameter too (clang's sret pointer): the grid helpers, whose structs stay in memory
#   after optimisation, fill out-parameters instead (kernels/grid.cl; other struct returns are optimised
#   away before the interpreter sees them). -cl-opt-disable does not help: always_inline still inlines.
# - STYLERF_TEST_SMALL=1: the heavy suites run the same cases and checks at smaller sizes (tests/testing.hpp,
#   small_run()), since the simulator runs kernels ~1000x slower than PoCL. Cases that cannot shrink without
#   losing their meaning are skipped below, each printed with its reason.
# - the device reports 1 GiB of global memory (--global-mem-size) rather than its default 128 MiB.
# - --uninitialized is not used: its plugin crashes (SIGSEGV in Uninitialized::instructionExecuted) on
#   reduce.cl's sum_partials, and it does not see clEnqueueFillBuffer's writes, so every kernel reading a
#   Tensor::zeros / full (relu and maxpool backward in test_spatial, ...) gets false "uninitialized" reports.
# Known gaps (last runs, 2-core CPU): 25 suites clean. test_adain and test_vgg were clean in every case that
# finished within a 300 s limit (one case each was cut; both likely fit the 600 s default). Not yet finished
# under the new sizes (each clean until its limit): test_feature_targets, test_style_model, test_stylize,
# test_hardening, test_lpips, test_train_features, test_eval_cli, test_stylize_cli, and test_train_density
# with its final skips: measure them, then shrink or skip what is still too slow. Later runs at a 900 s limit
# (two suites at a time): test_stylize clean in its first 7 cases (region masks 403 s, supersampling 166 s,
# style encoder 329 s), cut in the 8th; test_feature_targets clean in 4 (the targets cache 832 s), cut in
# the 5th; test_lpips skips its two official-value cases (printed).
set -uo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
TIMEOUT=${OCLGRIND_SUITE_TIMEOUT:-600}
if ! command -v oclgrind > /dev/null; then
  SUDO=$([ "$(id -u)" = 0 ] && echo "" || echo sudo)
  $SUDO apt-get install -y oclgrind > /dev/null
fi
if [ $# -gt 0 ]; then
  suites="$*"
else
  suites=$(cd "$BUILD_DIR" && ctest -N | sed -n 's/^ *Test *#[0-9]*: //p')
fi
[ -n "$suites" ] || { echo "no CTest suites found in $BUILD_DIR (build it first)"; exit 1; }
export STYLERF_CL_OPTIONS="-Drestrict=" STYLERF_TEST_SMALL=1
export STYLERF_TEST_DATA=${STYLERF_TEST_DATA:-$PWD/../shared/data}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$HOME/.cache/stylerf/pocl}
OCLGRIND=(oclgrind --data-races --check-api --global-mem-size 1073741824)

# Doctest cases left out under Oclgrind, each with its reason (printed). Keep this list short: shrink a
# case under STYLERF_TEST_SMALL instead where its meaning survives that.
# (doctest filters: comma-separated, wildcards; a name with a comma is matched by its start and a *.)
declare -A EXCLUDE=(
  [test_lpips]="lpips: the official values*,lpips alex: the official values*"
  [test_train_density]="refit_schedule*,time-budgeted run*,train-density smoke*,checkpoint: round trip*,checkpoint: --resume*,checkpoint: missing*"
)
declare -A EXCLUDE_WHY=(
  [test_lpips]="six fixed 256x256 pairs of ../shared/reference/lpips through VGG-16 and AlexNet (hours simulated); the same kernels run in the other cases, against double-precision references"
  [test_train_density]="refit_schedule trains 154 steps to fire its events (over 300 s simulated even at 128 rays) and the trained-model cases 150; the time-budgeted case checks wall-clock step rates; the training kernels still run in the 10-step NaN-guard cases"
)
# API errors a suite provokes on purpose (--check-api reports them too): a regex over the report's block.
declare -A EXPECTED_API_ERROR=(
  [test_runtime]="Kernel 'no_such_kernel' not found"  # the error message for a missing kernel is under test
)

# Number of Oclgrind reports in log $1, less the API errors matching regex $2 (blocks end at a blank line).
count_findings() {
  awk -v allow="$2" '
    function flush() { if (block != "" && !(allow != "" && block ~ allow)) n++; block = "" }
    /Invalid (read|write)|data race|Uninitiali[sz]ed|OpenCL runtime error|OCLGRIND FATAL|divergence/ { flush(); block = $0; next }
    block != "" && /^[[:space:]]*$/ { flush(); next }
    block != "" { block = block "\n" $0 }
    /corrupted|Aborted|Segmentation/ { n++ }
    END { flush(); print n + 0 }' "$1"
}

status=0
summary=()
for s in $suites; do
  log=$BUILD_DIR/oclgrind_$s.log
  if [ "$s" = package_find_package ]; then
    cmd=(bash tests/package_test.sh "$BUILD_DIR" "$PWD")  # installs, builds examples/embed, runs it
  else
    cmd=("$BUILD_DIR/$s" --duration=true)  # per-case seconds in the log, for choosing what to shrink
    if [ -n "${EXCLUDE[$s]:-}" ]; then
      cmd+=("--test-case-exclude=${EXCLUDE[$s]}")
      echo "$s: skipping under Oclgrind: ${EXCLUDE[$s]} (${EXCLUDE_WHY[$s]})"
    fi
  fi
  start=$(date +%s)
  timeout "$TIMEOUT" "${OCLGRIND[@]}" "${cmd[@]}" > "$log" 2>&1
  rc=$?
  secs=$(($(date +%s) - start))
  # Oclgrind's reports: invalid accesses, races, uninitialised values, API errors, fatal errors.
  findings=$(count_findings "$log" "${EXPECTED_API_ERROR[$s]:-}")
  if [ $rc = 124 ]; then
    line="$s: TIMEOUT after ${TIMEOUT}s (see $log)"; status=1
  elif [ $rc != 0 ] || [ "$findings" != 0 ]; then
    line="$s: FINDINGS (exit $rc, $findings Oclgrind reports; see $log) in ${secs}s"; status=1
  else
    line="$s: clean in ${secs}s"
  fi
  [ -n "${EXCLUDE[$s]:-}" ] && line="$line; skipped: ${EXCLUDE[$s]}"
  echo "$line"
  summary+=("$line")
done
echo "---- Oclgrind summary ($BUILD_DIR, limit ${TIMEOUT}s a suite) ----"
printf '%s\n' "${summary[@]}"
exit $status
