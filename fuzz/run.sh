#!/usr/bin/env bash
# Builds the libFuzzer harnesses (clang) and runs each for RUNS executions (default 1,000,000) from the
# committed seeds in fuzz/corpus/<harness>/, with ASan + UBSan, leak detection, a 10 s per-input hang
# limit and a 2 GB memory limit. New inputs found go to a scratch corpus, not into the repository. A crash
# leaves crash-*/leak-*/timeout-* under build-fuzz/findings/<harness>/: copy it to
# tests/data/fuzz_regressions/<harness>/ so test_fuzz_regressions replays it for good.
#   bash fuzz/run.sh [RUNS] [harness ...]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-1000000}
shift || true
harnesses=${*:-npy safetensors checkpoint image scene_json colmap_bin nerfstudio_json}
CXX=clang++ cmake -S fuzz -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo > /dev/null
cmake --build build-fuzz -j"$(nproc)" > /dev/null
for h in $harnesses; do
  scratch=build-fuzz/corpus/$h findings=build-fuzz/findings/$h
  mkdir -p "$scratch" "$findings"
  start=$(date +%s)
  ./build-fuzz/fuzz_"$h" -runs="$runs" -timeout=10 -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
      -artifact_prefix="$findings/" "$scratch" "fuzz/corpus/$h" > "build-fuzz/$h.log" 2>&1 || {
    echo "fuzz_$h: FINDING (see build-fuzz/$h.log and $findings)"; tail -30 "build-fuzz/$h.log"; exit 1; }
  echo "fuzz_$h: $(grep -o 'stat::number_of_executed_units: *[0-9]*' "build-fuzz/$h.log" | grep -o '[0-9]*$') runs," \
       "no crash, leak or hang, $(( $(date +%s) - start )) s"
done
