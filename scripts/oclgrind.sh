#!/usr/bin/env bash
# Test suites on Oclgrind, a simulated OpenCL device that reports out-of-bounds accesses, data races and
# invalid API use: a second, stricter platform than PoCL. Runs every suite CTest runs (package_find_package
# included: its example runs on Oclgrind; cli_doc too, though it runs no kernels), each under
# `oclgrind --data-races --check-api` with a time limit; a suite is clean when it passes and Oclgrind
# reported nothing. One line per suite, then a summary; exit status 1 on any finding or timeout.
# Logs: $BUILD_DIR/oclgrind_<suite>.log (doctest durations in them).
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
# - the device keeps Oclgrind's default 128 MiB of global memory (the suites fit at these sizes, and a
#   smaller device makes the race detector's shadow memory smaller); 3x3 convs that a test does not pin run
#   as im2col (STYLERF_CONV_ALGO): Winograd's transforms are many more launches, each slow to simulate,
#   and test_conv covers Winograd's kernels.
# - --uninitialized is not used: its plugin crashes (SIGSEGV in Uninitialized::instructionExecuted) on
#   reduce.cl's sum_partials, and it does not see clEnqueueFillBuffer's writes, so every kernel reading a
#   Tensor::zeros / full (relu and maxpool backward in test_spatial, ...) gets false "uninitialized" reports.
# Where it stands (runs of 2026-11-25 on commit 0c8fe5b's build, 2-core CPU): all 36 CTest suites clean, no
# Oclgrind report in any. 25 suites take 0-62 s each; test_stylize 206 s, test_eval_cli 239 s, test_stylize_cli
# 50 s, test_style_model 394 s, test_train_density 586 s and test_train_features 599 s (those two beside a
# training run); test_vgg, test_adain, test_feature_targets, test_hardening and test_lpips clean to the end on
# 2026-11-24 at these sizes. 14 heavy end-to-end cases are skipped (EXCLUDE below, each printed with its
# reason). Shrink rather than skip where a case can keep its meaning.
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
# The command-line suites' stylerf children run on the simulator too (they inherit its LD_PRELOAD): their
# captured output, reports included, is passed on to the suite's log (tests/cli_runner.hpp).
export STYLERF_TEST_FORWARD_CLI_OUTPUT=1
export STYLERF_CONV_ALGO=${STYLERF_CONV_ALGO:-im2col}  # convs a test does not pin (see the header)
export STYLERF_TEST_DATA=${STYLERF_TEST_DATA:-$PWD/../shared/data}
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$HOME/.cache/stylerf/pocl}
OCLGRIND=(oclgrind --data-races --check-api)  # 128 MiB of global memory, its default (see the header)

# Doctest cases left out under Oclgrind, each with its reason (printed). Keep this list short: shrink a
# case under STYLERF_TEST_SMALL instead where its meaning survives that.
# (doctest filters: comma-separated, wildcards; a name with a comma is matched by its start and a *.)
declare -A EXCLUDE=(  # [suite]="filters|reason"
  [test_eval_cli]="eval consistency*,eval table*|eval consistency's four runs (LPIPS through VGG-16 and AlexNet, per-frame AdaIN, StyleRF frames) and the paper's table over two scenes, three methods and two styles: each over 10 min simulated even at 8 frames of 32x32; their library calls run in test_consistency, test_lpips, test_adain and test_stylize, and this suite's lpips, bench and refusal cases still run the command line"
  [test_lpips]="lpips: the official values*,lpips alex: the official values*,lpips: masked distance,lpips alex: masked distance|six fixed 256x256 pairs of ../shared/reference/lpips through VGG-16 and AlexNet (hours simulated); the masked cases need their 96x48 images (noise 32 px from the mask; smaller ones fail their bounds) and ~12 distances each (over 10 min simulated), and apply the mask on the host: the same kernels run in the other cases, against double-precision references"
  [test_style_model]="style training moves*,the 2D warm start*|~300 kernels a rendered step while the trainer holds ~100-170 MiB of device memory (decoder, its Adam state, VGG): ~0.4 s a launch under the race detector, over 1000 s a case; SICT, DST, the style losses, VGG and decoder backward and Adam run in this suite's other cases, test_sict_dst, test_loss, test_vgg and test_module_adam"
  [test_stylize]="style encoder: hard images*|encodes style images at the fixed 256x256 (style::kStyleImageSize) five times (~10 GB of race-detector shadow, over 10 min); VGG runs in test_vgg and test_feature_targets, DST's style branch in test_style_model"
  [test_run_cli]="run: the whole pipeline*|stylerf run end to end three times: three stages, eval style, videos, a mix sheet and a consistency table through VGG-16 LPIPS (hours simulated); each step's kernels run in the suites of its own command, and this suite's refusal case still runs the command line"
  [test_stylize_cli]="stylize: a path*|five stylize runs whose per-view losses put each style through VGG at the fixed 256x256 and decode ~40 views (a 5x5 mix sheet among them): hours simulated; their kernels run in test_stylize, test_style_model, test_adain and test_vgg"
  [test_train_density]="refit_schedule*,time-budgeted run*|refit_schedule trains its own model 151 steps for an event to fire (the suite's shared 150-step model already takes ~340 s simulated), and the time-budgeted case checks wall-clock step rates; the same training kernels run in the smoke, checkpoint and NaN-guard cases"
  [test_train_features]="feature stage (fast profile)*,feature stage (paper profile)*|the two training runs: 120 fast-profile steps of up to ~250 kernels with ~100 MiB of decoder, Adam state and VGG on the device (~0.3 s a launch under the race detector; even the 30 steps that pass its bounds at larger learning rates take ~30 min), and 6 paper-profile steps over full-resolution 256-channel features (~7 GB of race-detector shadow, over 15 min); the trainer's kernels (feature grid, targets, TV, decoder and VGG backward) run in this suite's other cases, test_grid, test_feature_targets and test_vgg"
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
  elif [ "$s" = cli_doc ]; then
    cmd=(bash tests/cli_doc_test.sh "$BUILD_DIR" "$PWD")  # docs/cli.md against --help (no kernels run)
  elif [[ "$s" == *_work_group ]]; then
    cmd=(env STYLERF_REDUCTION=work-group "$BUILD_DIR/${s%_work_group}" --duration=true)  # CMakeLists.txt
  else
    cmd=("$BUILD_DIR/$s" --duration=true)  # per-case seconds in the log, for choosing what to shrink
    if [ -n "${EXCLUDE[$s]:-}" ]; then
      skipped=${EXCLUDE[$s]%%|*}
      cmd+=("--test-case-exclude=$skipped")
      echo "$s: skipping under Oclgrind: $skipped (${EXCLUDE[$s]#*|})"
    fi
  fi
  # A fresh TMPDIR a suite, removed after it: the suites' scratch folders (tests/small_scene.cpp and the
  # like) are left behind by runs that the limit cuts short. (timeout kills the whole process group: the
  # command-line suites' stylerf children too.)
  tmp=$(mktemp -d "${TMPDIR:-/tmp}/stylerf_oclgrind_$s.XXXXXX")
  start=$(date +%s)
  TMPDIR=$tmp timeout "$TIMEOUT" "${OCLGRIND[@]}" "${cmd[@]}" > "$log" 2>&1
  rc=$?
  secs=$(($(date +%s) - start))
  rm -rf "$tmp"
  # Oclgrind's reports: invalid accesses, races, uninitialised values, API errors, fatal errors.
  findings=$(count_findings "$log" "${EXPECTED_API_ERROR[$s]:-}")
  if [ $rc = 124 ]; then
    line="$s: TIMEOUT after ${TIMEOUT}s (see $log)"; status=1
  elif [ $rc != 0 ] || [ "$findings" != 0 ]; then
    line="$s: FINDINGS (exit $rc, $findings Oclgrind reports; see $log) in ${secs}s"; status=1
  else
    line="$s: clean in ${secs}s"
  fi
  [ -n "${EXCLUDE[$s]:-}" ] && line="$line; skipped: ${EXCLUDE[$s]%%|*}"
  echo "$line"
  summary+=("$line")
done
echo "---- Oclgrind summary ($BUILD_DIR, limit ${TIMEOUT}s a suite) ----"
printf '%s\n' "${summary[@]}"
exit $status
