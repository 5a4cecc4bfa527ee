#!/usr/bin/env bash
# The device check: the test suite, the benches and a short lego density run on one OpenCL
# device, in at most 8 minutes, into ONE JSON ($OUT/device_check.json) and one log ($OUT/device_check.log),
# with a table at the end and a projection of the paper's schedule (density 30k, features 25k, style 25k
# steps) from the measured step times.
#
#   bash scripts/device_check.sh --bundle .devcarry --device gpu --out $OUT     # on a GPU machine
#   bash scripts/device_check.sh --build build --device cpu --out $OUT         # on a CPU (implies --quick)
#
# Options:
#   --bundle DIR   what scripts/device_bundle.sh made: unpacked into a temporary folder, its libraries on
#                  LD_LIBRARY_PATH, the paths the tests were built at recreated by symlinks, NVIDIA's OpenCL library
#                  registered as an ICD when one is found
#   --build DIR    a local build (the CPU case); the scene from ../shared/data/scenes/blender/lego
#   --device D     gpu (default) | cpu: passed to every command (and STYLERF_DEVICE for the tests)
#   --out DIR      where the JSON and the log go (default out/device_check)
#   --quick        smaller sizes (patch and decoder steps at 64x64, one repeat, field --quick, the density
#                  run 1 minute at 1/4 resolution); the default with --device cpu
#   --full         the GPU sizes even with --device cpu
#   --parts LIST   comma list of devices,patch,decoder,field,ops,gemm,tune,density,tests (default all but tune)
#   --jobs N       ctest -j (default 4 on a GPU, 2 on a CPU)
#   --total S      seconds for all the parts together (default 450: 8 minutes less the unpacking)
#   --baseline F   a stylerf binary built from an earlier commit (same libraries; relative to the bundle when
#                  not found as given): the patch and decoder parts run with it too, as NAME_baseline, right
#                  after each, so that a change is measured against its baseline on the same warm machine
#   --profile      the stage-3 and stage-2 paper patch steps again under STYLERF_PROFILE=1: the top kernels
#                  and CLBlast calls by time go to the log
# Each part runs under `timeout` with its own budget, capped by what is left of --total; a part that fails
# or runs out of time is recorded as such and the rest still run.
set -uo pipefail

REPO=$(cd "$(dirname "$0")/.." && pwd -P)
BUNDLE="" BUILD="" DEVICE=gpu OUT="" QUICK="" PARTS="devices,patch,decoder,field,ops,gemm,density,tests" JOBS="" TOTAL=450
BASELINE="" PROFILE=""
usage() { sed -n 2,32p "$0" | sed 's/^# \{0,1\}//'; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --bundle) BUNDLE=$2; shift 2 ;;
    --build) BUILD=$2; shift 2 ;;
    --device) DEVICE=$2; shift 2 ;;
    --out) OUT=$2; shift 2 ;;
    --quick) QUICK=1; shift ;;
    --full) QUICK=0; shift ;;
    --parts) PARTS=$2; shift 2 ;;
    --jobs) JOBS=$2; shift 2 ;;
    --total) TOTAL=$2; shift 2 ;;
    --baseline) BASELINE=$2; shift 2 ;;
    --profile) PROFILE=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "device_check: unknown argument $1" >&2; usage >&2; exit 2 ;;
  esac
done
[[ -n "$BUNDLE" || -n "$BUILD" ]] || BUILD=$REPO/build
[[ -n "$BUNDLE" && -n "$BUILD" ]] && { echo "device_check: --bundle or --build, not both" >&2; exit 2; }
[[ -z "$QUICK" ]] && { [[ "$DEVICE" == cpu ]] && QUICK=1 || QUICK=0; }
[[ -z "$JOBS" ]] && { [[ "$DEVICE" == cpu ]] && JOBS=2 || JOBS=4; }
OUT=${OUT:-$REPO/out/device_check}
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd -P)
LOG=$OUT/device_check.log
: > "$LOG"
WORK=$(mktemp -d /tmp/device_check.XXXXXX)
mkdir -p "$WORK/logs" "$WORK/json"
export POCL_CACHE_DIR=${POCL_CACHE_DIR:-$WORK/pocl_cache}
T0=$(date +%s)
DEADLINE=$(( T0 + TOTAL ))

say() { echo "$*" | tee -a "$LOG"; }
note() { echo "$1=$2" >> "$WORK/meta.env"; }   # facts for the JSON
: > "$WORK/meta.env"
: > "$WORK/parts.tsv"
say "device_check: $(date -u +%Y-%m-%dT%H:%M:%SZ) on $(uname -n); device $DEVICE; quick $QUICK; work $WORK"

# --- where the binaries, libraries and scene are -------------------------------------------------------------
SCENE="" ICD="" COMMIT="" CARRIED_WEIGHTS=""
if [[ -n "$BUNDLE" ]]; then
  BUNDLE=$(cd "$BUNDLE" && pwd -P) || { say "device_check: no bundle at $BUNDLE"; exit 2; }
  [[ -f "$BUNDLE/bundle.env" ]] || { say "device_check: $BUNDLE/bundle.env is missing: not a device_bundle.sh folder"; exit 2; }
  # shellcheck disable=SC1091
  source "$BUNDLE/bundle.env"
  COMMIT=$GIT_COMMIT
  U=$WORK/bundle
  mkdir -p "$U/build"
  tar -C "$U/build" -xJf "$BUNDLE/build.tar.xz" || { say "device_check: cannot unpack build.tar.xz"; exit 2; }
  tar -C "$U" -xJf "$BUNDLE/libs.tar.xz" || say "device_check: cannot unpack libs.tar.xz"
  [[ -f "$BUNDLE/tools.tar.xz" ]] && tar -C "$U" -xJf "$BUNDLE/tools.tar.xz"
  [[ -f "$BUNDLE/lego.tar" ]] && tar -C "$U" -xf "$BUNDLE/lego.tar" && SCENE=$U/lego
  # The carried weights (VGG-19 to conv4_1, AdaIN's decoder), where the machine has none of its own.
  if [[ -f "$BUNDLE/weights.tar" && ! -f "${STYLERF_WEIGHTS:-$HOME/.cache/stylerf/weights}/vgg_normalised.safetensors" ]]; then
    tar -C "$U" -xf "$BUNDLE/weights.tar" && export STYLERF_WEIGHTS=$U/weights && CARRIED_WEIGHTS=1
  fi
  BUILD=$U/build
  export LD_LIBRARY_PATH=$U/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
  [[ -d "$U/tools/bin" ]] && export PATH=$U/tools/bin:$PATH
  say "bundle: $BUNDLE (commit $GIT_COMMIT, made $MADE on $MADE_ON), unpacked in $(( $(date +%s) - T0 )) s"
  # The tests have the source and build paths of the machine that built them compiled in (STYLERF_CLI,
  # STYLERF_TEST_FIXTURES) and CTestTestfile.cmake names them: point those paths here by symlinks where they
  # are free, and rewrite the test file to the unpacked build.
  if [[ -L "$SRC_ORIG" || ! -e "$SRC_ORIG" ]]; then   # a symlink: ours, from an earlier run
    mkdir -p "$(dirname "$SRC_ORIG")" && ln -sfn "$REPO" "$SRC_ORIG" && say "paths: $SRC_ORIG -> $REPO (symlink)"
  else
    say "paths: $SRC_ORIG exists here; left alone"
  fi
  if [[ -L "$BUILD_ORIG" || ! -e "$BUILD_ORIG" ]]; then
    mkdir -p "$(dirname "$BUILD_ORIG")" && ln -sfn "$BUILD" "$BUILD_ORIG" && say "paths: $BUILD_ORIG -> $BUILD (symlink)"
  else
    say "paths: $BUILD_ORIG exists here; left alone"
    cmp -s "$BUILD_ORIG/stylerf" "$U/build/stylerf" ||
      say "paths: WARNING $BUILD_ORIG/stylerf is not the bundle's: the tests that run the CLI run that one"
  fi
  sed -i "s|$BUILD_ORIG|$BUILD|g; s|$SRC_ORIG|$REPO|g" "$BUILD/CTestTestfile.cmake"
  # NVIDIA's OpenCL driver, registered with the carried ICD loader by a vendors folder of our own.
  if [[ "$DEVICE" != cpu ]]; then
    for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib \
             /usr/local/cuda/compat /usr/local/cuda/lib64; do
      for f in "$d"/libnvidia-opencl.so.1 "$d"/libnvidia-opencl.so.*; do
        [[ -f "$f" ]] && { ICD=$f; break 2; }
      done
    done
    if [[ -z "$ICD" ]]; then
      ICD=$(ldconfig -p 2>/dev/null | awk '/libnvidia-opencl\.so/ {print $NF; exit}')
    fi
    if [[ -z "$ICD" ]]; then
      ICD=$(timeout 40 find / \( -path /proc -o -path /sys -o -path /dev -o -path "$WORK" \) -prune -o \
            -name 'libnvidia-opencl.so*' -print 2>/dev/null | sort | head -1)
    fi
    if [[ -n "$ICD" ]]; then
      mkdir -p "$WORK/vendors"
      echo "$ICD" > "$WORK/vendors/nvidia.icd"
      export OCL_ICD_VENDORS=$WORK/vendors
      export LD_LIBRARY_PATH=$LD_LIBRARY_PATH:$(dirname "$ICD")
      say "OpenCL ICD: $ICD (OCL_ICD_VENDORS=$OCL_ICD_VENDORS)"
    else
      say "OpenCL ICD: no libnvidia-opencl.so* found; /etc/OpenCL/vendors: $(ls /etc/OpenCL/vendors 2>/dev/null | tr '\n' ' ')"
    fi
  fi
else
  BUILD=$(cd "$BUILD" && pwd -P) || { say "device_check: no build at $BUILD"; exit 2; }
  COMMIT=$(git -C "$REPO" rev-parse HEAD 2>/dev/null || echo unknown)
  for c in "$REPO/../shared/data/scenes/blender/lego"; do
    [[ -f "$c/transforms_train.json" ]] && { SCENE=$c; break; }
  done
fi
SCENE=${DC_SCENE:-$SCENE}
STYLERF=$BUILD/stylerf
[[ -x "$STYLERF" ]] || { say "device_check: $STYLERF is missing"; exit 2; }
export STYLERF_DEVICE=$DEVICE
note mode "$([[ -n "$BUNDLE" ]] && echo bundle || echo build)"
note commit "$COMMIT"
note icd "$ICD"
note scene "$SCENE"
note build "$BUILD"
note started "$(date -u +%Y-%m-%dT%H:%M:%SZ)"
{ echo "=== ldd $STYLERF (LD_LIBRARY_PATH=${LD_LIBRARY_PATH:-})"; ldd "$STYLERF"; } >> "$LOG" 2>&1
if ldd "$STYLERF" | grep -q 'not found'; then
  say "ldd: missing libraries: $(ldd "$STYLERF" | grep 'not found' | awk '{print $1}' | tr '\n' ' ')"
fi

# --- weights: the benches time stand-ins of the real shapes where the real files are absent -----------------
REAL_W=${STYLERF_WEIGHTS:-$HOME/.cache/stylerf/weights}
BENCH_W=$REAL_W
if [[ -n "${CARRIED_WEIGHTS:-}" ]]; then
  note weights carried
  say "weights: $REAL_W (carried: the real VGG-19 to conv4_1 and AdaIN's decoder; no LPIPS networks)"
elif [[ -f "$REAL_W/vgg_normalised.safetensors" ]]; then
  note weights real
  say "weights: $REAL_W (real)"
elif [[ -n "$BUNDLE" && -s "$BUNDLE/weights_layout.json" ]]; then
  BENCH_W=$WORK/standin_weights
  python3 - "$BUNDLE/weights_layout.json" "$BENCH_W" <<'EOF'
# Same names, dtypes and shapes as the real files; He-scaled pseudo-random values (a repeated block):
# the step times do not depend on the values, the losses do (they are meaningless here).
import array, json, math, os, random, struct, sys
layouts, out = json.load(open(sys.argv[1])), sys.argv[2]
os.makedirs(out, exist_ok=True)
rng = random.Random(42)
base = [rng.gauss(0.0, 1.0) for _ in range(1 << 16)]
for name, header in layouts.items():
    meta = header.get("__metadata__", {})
    tensors = sorted(((k, v) for k, v in header.items() if k != "__metadata__"), key=lambda kv: kv[1]["data_offsets"][0])
    hdr = {"__metadata__": dict(meta, standin="pseudo-random, timing only")} if meta else {}
    blobs, off = [], 0
    for k, v in tensors:
        n = math.prod(v["shape"]) if v["shape"] else 1
        fan_in = math.prod(v["shape"][1:]) if len(v["shape"]) > 1 else 0
        scale = math.sqrt(2.0 / fan_in) if fan_in else 0.01
        block = array.array("f", (x * scale for x in base)).tobytes()
        data = (block * (n // len(base) + 1))[: 4 * n]
        hdr[k] = {"dtype": "F32", "shape": v["shape"], "data_offsets": [off, off + len(data)]}
        blobs.append(data)
        off += len(data)
    h = json.dumps(hdr).encode()
    h += b" " * (-len(h) % 8)
    with open(os.path.join(out, name), "wb") as f:
        f.write(struct.pack("<Q", len(h)) + h)
        for b in blobs:
            f.write(b)
    print("stand-in %s: %.1f MB" % (name, (8 + len(h) + off) / 1e6))
EOF
  note weights standin
  say "weights: $REAL_W absent; the benches time stand-ins of the real shapes ($BENCH_W); the tests that need the real ones are counted apart"
else
  note weights absent
  say "weights: $REAL_W absent and no layouts to make stand-ins: the benches that load VGG will fail"
fi

# --- sizes ----------------------------------------------------------------------------------------------------
if [[ "$QUICK" == 1 ]]; then
  SIZE=64 REPEATS=1 FIELD_ARGS="--quick --repeats 1" DENSITY_MIN=1 DENSITY_ARGS="--downsample 4"
else
  SIZE=256 REPEATS=3 FIELD_ARGS="" DENSITY_MIN=2 DENSITY_ARGS=""
fi
note size "$SIZE"
note quick "$QUICK"
note density_minutes "$DENSITY_MIN"
note density_args "$DENSITY_ARGS"
note jobs "$JOBS"

want() { [[ ",$PARTS," == *",$1,"* ]]; }

# run_part NAME BUDGET_S CMD...: its output to the log; its status, exit code, seconds and budget to parts.tsv.
run_part() {
  local name=$1 budget=$2; shift 2
  local left=$(( DEADLINE - $(date +%s) ))
  if (( left < 5 )); then
    printf '%s\tskipped\t-\t0\t0\t%s\n' "$name" "$*" >> "$WORK/parts.tsv"
    say "$(printf '%-22s skipped (no time left of --total %s s)' "$name" "$TOTAL")"
    return
  fi
  local t=$(( budget < left ? budget : left ))
  {
    echo
    echo "=== $name (timeout ${t} s): $*"
  } >> "$LOG"
  local s e rc st
  s=$(date +%s.%N)
  timeout -k 10 "$t" "$@" > "$WORK/logs/$name.log" 2>&1 < /dev/null
  rc=$?
  e=$(date +%s.%N)
  cat "$WORK/logs/$name.log" >> "$LOG"
  if (( rc == 0 )); then st=ok; elif (( rc == 124 || rc == 137 )); then st=timeout; else st=failed; fi
  local secs
  secs=$(awk -v s="$s" -v e="$e" 'BEGIN {printf "%.1f", e - s}')
  echo "=== $name: $st (exit $rc) in $secs s" >> "$LOG"
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$st" "$rc" "$secs" "$t" "$*" >> "$WORK/parts.tsv"
  say "$(printf '%-22s %-8s %7s s  (budget %s s)' "$name" "$st" "$secs" "$t")"
  [[ "$st" == ok ]] || tail -n 5 "$WORK/logs/$name.log" | sed 's/^/    | /'
}

bench() {  # bench NAME BUDGET ARGS...: stylerf bench with --json, the weights the benches use, the device
  local name=$1 budget=$2; shift 2
  run_part "$name" "$budget" env STYLERF_WEIGHTS="$BENCH_W" "$STYLERF" bench "$@" --device "$DEVICE" \
    --json "$WORK/json/$name.json"
  if [[ -n "$BASELINE_BIN" ]]; then
    run_part "${name}_baseline" "$budget" env STYLERF_WEIGHTS="$BENCH_W" "$BASELINE_BIN" bench "$@" \
      --device "$DEVICE" --json "$WORK/json/${name}_baseline.json"
  fi
}
BASELINE_BIN=""
if [[ -n "$BASELINE" ]]; then
  for c in "$BASELINE" "${BUNDLE:+$BUNDLE/$BASELINE}"; do
    [[ -n "$c" && -f "$c" ]] && { BASELINE_BIN=$WORK/stylerf_baseline; cp "$c" "$BASELINE_BIN"; chmod +x "$BASELINE_BIN"; break; }
  done
  [[ -n "$BASELINE_BIN" ]] && say "baseline: $BASELINE" || say "baseline: $BASELINE not found; no baseline runs"
  note baseline "$BASELINE"
fi

# --- the parts, the most wanted first; the tests last, with what is left ----------------------------------------
if want devices; then
  run_part devices 30 "$STYLERF" devices
  # No device of the kind asked for: every part would fail the same way; spend no more device time.
  if [[ "$(tail -n 1 "$WORK/parts.tsv" | cut -f2)" != ok && -z "${DC_GO_ON:-}" ]]; then
    say "device_check: stylerf devices failed for --device $DEVICE: the other parts are skipped (DC_GO_ON=1 runs them)"
    PARTS=devices
  fi
fi
if want patch; then
  bench patch_s2_fast 30 patch --stage 2 --profile fast --size "$SIZE" --repeats "$REPEATS"
  bench patch_s2_paper 60 patch --stage 2 --profile paper --size "$SIZE" --repeats "$REPEATS"
  bench patch_s3_fast 30 patch --stage 3 --profile fast --size "$SIZE" --repeats "$REPEATS"
  bench patch_s3_paper 40 patch --stage 3 --profile paper --size "$SIZE" --repeats "$REPEATS"
  if [[ -n "$PROFILE" ]]; then
    run_part patch_s3_paper_profile 40 env STYLERF_PROFILE=1 STYLERF_WEIGHTS="$BENCH_W" "$STYLERF" bench patch \
      --stage 3 --profile paper --size "$SIZE" --repeats 1 --device "$DEVICE"
    run_part patch_s2_paper_profile 60 env STYLERF_PROFILE=1 STYLERF_WEIGHTS="$BENCH_W" "$STYLERF" bench patch \
      --stage 2 --profile paper --size "$SIZE" --repeats 1 --device "$DEVICE"
  fi
fi
if want decoder; then
  bench decoder_paper 25 decoder-step --decoder paper --size "$SIZE" --repeats "$REPEATS"
  bench decoder_fast 20 decoder-step --decoder fast --size "$SIZE" --repeats "$REPEATS"
fi
# shellcheck disable=SC2086
if want field; then bench field 60 field $FIELD_ARGS; fi
# The reductions and the channel attention on each path (per-item, work-group), and the device's default.
# shellcheck disable=SC2086
if want ops; then bench ops_norm 40 ops --parts norm,style $([[ "$QUICK" == 1 ]] && echo --quick) --repeats "$REPEATS"; fi
if want gemm; then bench gemm 40 gemm --quick --repeats "$REPEATS"; fi
# Tuning (only when asked: --parts ...,tune): stylerf tune --quick into the user tuning file, copied to $OUT,
# then the GEMMs and the patch steps again with it.
if want tune; then
  run_part tune 170 "$STYLERF" tune --quick --device "$DEVICE"
  TUNED=${STYLERF_CACHE_DIR:-$HOME/.cache/stylerf}/clblast-tuning.json
  [[ -f "$TUNED" ]] && cp "$TUNED" "$OUT/clblast-tuning.json"
  bench gemm_tuned 40 gemm --quick --repeats "$REPEATS"
  bench patch_s3_paper_tuned 40 patch --stage 3 --profile paper --size "$SIZE" --repeats "$REPEATS"
  bench patch_s2_paper_tuned 60 patch --stage 2 --profile paper --size "$SIZE" --repeats "$REPEATS"
fi
if want density; then
  if [[ -n "$SCENE" && -f "$SCENE/transforms_train.json" ]]; then
    # shellcheck disable=SC2086
    run_part density $(( DENSITY_MIN * 60 + 45 )) "$STYLERF" train-density --scene "$SCENE" \
      -o "$WORK/density.ckpt" --force --minutes "$DENSITY_MIN" --eval-views 2 --log-every 200 \
      --ckpt-every 1000000 --device "$DEVICE" $DENSITY_ARGS
  else
    printf 'density\tskipped\t-\t0\t0\tno lego scene\n' >> "$WORK/parts.tsv"
    say "density                skipped (no lego scene: --bundle or ../shared/data/scenes/blender/lego)"
  fi
fi
if want tests; then
  EXCL=${DC_TESTS_EXCLUDE:-package}
  LEFT=$(( DEADLINE - $(date +%s) ))
  if command -v ctest > /dev/null && [[ -z "${DC_NO_CTEST:-}" ]]; then
    note test_runner ctest
    run_part tests $(( LEFT > 30 ? LEFT : 30 )) bash -c 'cd "$1" && ctest -E "$2" -j "$3" --output-on-failure' _ \
      "$BUILD" "$EXCL" "$JOBS"
  else
    # No CTest on this machine: the same tests from CTestTestfile.cmake (command, ENVIRONMENT), N at a time,
    # reported in CTest's words so that one parser reads both.
    note test_runner python
    cat > "$WORK/run_tests.py" <<'EOF'
import concurrent.futures as cf, os, re, shlex, subprocess, sys, time
build, exclude, jobs = sys.argv[1], re.compile(sys.argv[2]), int(sys.argv[3])
text = open(os.path.join(build, "CTestTestfile.cmake")).read()
tests, env = [], {}
for m in re.finditer(r'add_test\(\[=\[(.*?)\]=\]\s+(.*?)\)\n', text):
    tests.append((m.group(1), [a.strip('"') for a in re.findall(r'"[^"]*"', m.group(2))]))
for m in re.finditer(r'set_tests_properties\(\[=\[(.*?)\]=\] PROPERTIES\s+ENVIRONMENT "([^"]*)"', text):
    env[m.group(1)] = dict(kv.split("=", 1) for kv in m.group(2).split(";") if "=" in kv)
tests = [t for t in tests if not exclude.search(t[0])]
n, done, failed = len(tests), [0], []
def run(i, name, cmd):
    t = time.time()
    p = subprocess.run(cmd, cwd=build, env=dict(os.environ, **env.get(name, {})), stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    return i, name, p.returncode, time.time() - t, p.stdout.decode(errors="replace")
print("Test project %s (python runner: no ctest here)" % build, flush=True)
with cf.ThreadPoolExecutor(jobs) as ex:
    for i, name, rc, s, out in (f.result() for f in cf.as_completed([ex.submit(run, i + 1, *t) for i, t in enumerate(tests)])):
        done[0] += 1
        st = "   Passed" if rc == 0 else ("***Exception: rc %d" % rc if rc < 0 else "***Failed")
        print("%d/%d Test #%d: %s %s %s %.2f sec" % (done[0], n, i, name, "." * max(3, 40 - len(name)), st, s), flush=True)
        if rc:
            failed.append(name)
            print(out, flush=True)
print("\n%d%% tests passed, %d tests failed out of %d" % (round(100 * (n - len(failed)) / max(n, 1)), len(failed), n))
sys.exit(1 if failed else 0)
EOF
    run_part tests $(( LEFT > 30 ? LEFT : 30 )) python3 "$WORK/run_tests.py" "$BUILD" "$EXCL" "$JOBS"
  fi
fi
note finished "$(date -u +%Y-%m-%dT%H:%M:%SZ)"
note total_seconds "$(( $(date +%s) - T0 ))"

# --- one JSON and the table ---------------------------------------------------------------------------------
python3 - "$WORK" "$OUT/device_check.json" <<'EOF' 2>&1 | tee -a "$LOG"
import json, os, re, sys
work, out = sys.argv[1], sys.argv[2]
meta = dict(l.rstrip("\n").split("=", 1) for l in open(os.path.join(work, "meta.env")) if "=" in l)
def log(name):
    p = os.path.join(work, "logs", name + ".log")
    return open(p, errors="replace").read() if os.path.exists(p) else ""
parts = {}
for line in open(os.path.join(work, "parts.tsv")):
    name, status, rc, secs, budget, cmd = line.rstrip("\n").split("\t", 5)
    p = {"status": status, "exit": None if rc == "-" else int(rc), "seconds": float(secs), "budget_s": int(budget),
         "command": cmd}
    jp = os.path.join(work, "json", name + ".json")
    if os.path.exists(jp):
        try:
            p["json"] = json.load(open(jp))
        except ValueError as e:
            p["json_error"] = str(e)
    parts[name] = p

def num(x):
    return None if x is None else float(x)

# Key numbers per part.
for name, p in parts.items():
    j = p.get("json")
    if name.startswith("patch_") and j:
        p["step_s"] = j.get("step_seconds")
        p["parts_s"] = {q["part"]: q["seconds"] for q in j.get("parts", [])}
        p["samples"] = j.get("samples")
    elif name.startswith("decoder_") and j:
        p["step_s"] = j.get("median_s")
    elif name == "field" and j:
        p["rows_ms"] = {r["name"]: r["ms"] for r in j.get("rows", [])}
        p["rows_gb_s"] = {r["name"]: r.get("gb_s") for r in j.get("rows", [])}
    elif name.startswith("gemm") and j:
        p["auto_engine"] = j.get("auto_engine")
        p["results_agree"] = j.get("results_agree")
        p["best_gflops"] = {s["name"]: max(s["gflops"].items(), key=lambda kv: kv[1]) for s in j.get("shapes", [])}
device = None
if "devices" in parts:
    text = log("devices")
    parts["devices"]["output"] = text
    m = re.search(r"^chosen: \[\d+\]\s*(.*?)\s*(\(pick with|$)", text, re.M)
    device = m.group(1).strip() if m else None
for name in ("patch_s2_fast", "decoder_paper", "field", "gemm"):
    if device is None and parts.get(name, {}).get("json", {}).get("device"):
        device = parts[name]["json"]["device"]
if "density" in parts:
    text, p = log("density"), parts["density"]
    m = re.search(r"trained (\d+) iterations in ([\d.]+) s", text)
    if m:
        p["iterations"], p["train_seconds"] = int(m.group(1)), float(m.group(2))
        p["s_per_it"] = p["train_seconds"] / max(p["iterations"], 1)
    its = re.findall(r"^it (\d+)/\d+ .*?psnr ([\d.]+).*? ([\d.]+) s/it", text, re.M)
    if its:
        p["train_psnr_last"] = float(its[-1][1])
        p["s_per_it_last_window"] = float(its[-1][2])
    m = re.search(r"test PSNR ([\d.]+) dB over (\d+)", text)
    if m:
        p["test_psnr"], p["test_views"] = float(m.group(1)), int(m.group(2))
    p["args"] = meta.get("density_args") or "full resolution"
if "tests" in parts:
    text, p = log("tests"), parts["tests"]
    lines = text.splitlines()
    res = {}
    pat = re.compile(r"Test\s+#\d+:\s+(\S+)\s+\.+\s*(\**)(.+?)\s+([\d.]+)\s+sec")
    cur = None
    outs = {}
    for l in lines:
        m = pat.search(l)
        if m:
            res[m.group(1)] = (m.group(3).strip(), float(m.group(4)))
            cur = m.group(1) if m.group(3).strip() != "Passed" else None
            continue
        if re.match(r"^\s*(Start\s+\d+:|\d+/\d+ Test)", l) or l.startswith("The following tests"):
            cur = None
        if cur:
            outs.setdefault(cur, []).append(l)
    passed = sorted(k for k, v in res.items() if v[0] == "Passed")
    bad = sorted(k for k, v in res.items() if v[0] != "Passed")
    weights = [k for k in bad if re.search(r"fetch_weights|weights missing|pretrained weights", "\n".join(outs.get(k, [])))]
    # Tools the GPU image lacks (COLMAP, pytest): counted apart too, by the message that names them.
    tools = [k for k in bad if k not in weights and
             re.search(r"colmap is not installed|No module named pytest", "\n".join(outs.get(k, [])))]
    m = re.search(r"tests failed out of (\d+)", text)
    p.update({"passed": len(passed), "failed": len(bad) - len(weights) - len(tools),
              "failed_needing_weights": len(weights), "failed_needing_tools": len(tools),
              "reported_total": int(m.group(1)) if m else None, "finished": len(res),
              "failed_names": [k for k in bad if k not in weights and k not in tools], "weights_names": weights,
              "tools_names": tools,
              "results": {k: {"result": v[0], "seconds": v[1]} for k, v in sorted(res.items())}})
    # pass: every test ran, and the only failures are those that need the pretrained weights or a tool absent here.
    p["verdict"] = "pass" if (p["failed"] == 0 and p["reported_total"] is not None and
                              p["finished"] == p["reported_total"]) else "fail"

# The paper's schedule from the measured steps.
def step(name, key="step_s"):
    p = parts.get(name, {})
    return p.get(key) if p.get("status") == "ok" else None
proj = {"note": "hours = steps x measured seconds a step; density from the lego run's mean s/it (its grid grows "
                "within the run), features and style from bench patch's paper-profile step at %sx%s"
                % (meta.get("size"), meta.get("size"))}
stages = [("density", 30000, step("density", "s_per_it")), ("features", 25000, step("patch_s2_paper")),
          ("style", 25000, step("patch_s3_paper"))]
total = 0.0
for st, n, s in stages:
    proj[st] = {"steps": n, "s_per_step": s, "hours": None if s is None else n * s / 3600}
    total = None if (total is None or s is None) else total + n * s / 3600
proj["total_hours"] = total
if meta.get("quick") == "1":
    proj["caveat"] = "--quick sizes (patch %s px, density at reduced resolution): not the paper's" % meta.get("size")

result = {"schema": 1, "device": device, "device_arg": os.environ.get("STYLERF_DEVICE"),
          "date": meta.get("started"), "finished": meta.get("finished"), "git_commit": meta.get("commit"),
          "total_seconds": int(meta.get("total_seconds", 0)), "mode": meta.get("mode"), "quick": meta.get("quick") == "1",
          "size": int(meta.get("size", 0)), "weights": meta.get("weights"), "opencl_icd": meta.get("icd") or None,
          "scene": meta.get("scene"), "test_runner": meta.get("test_runner"), "jobs": int(meta.get("jobs", 0)),
          "parts": parts, "projection": proj}
json.dump(result, open(out, "w"), indent=1, sort_keys=False)

# The table.
def f(x, fmt="%.3f"):
    return "-" if x is None else fmt % x
print("\n== device check: %s" % (device or "device unknown"))
print("   commit %s, %s, %s mode, weights %s, %d s in all" % ((meta.get("commit") or "?")[:10], result["date"],
      result["mode"], result["weights"], result["total_seconds"]))
print("%-16s %-8s %8s  %s" % ("part", "status", "seconds", "key numbers"))
for name, p in parts.items():
    k = ""
    if name.startswith(("patch_", "decoder_")):
        k = "step %s s" % f(p.get("step_s"))
        if p.get("parts_s"):
            top = sorted(p["parts_s"].items(), key=lambda kv: -kv[1])[:2]
            k += " (" + ", ".join("%s %.3f" % kv for kv in top) + ")"
    elif name == "field" and p.get("rows_ms"):
        k = ", ".join("%s %.1f ms" % (r, ms) for r, ms in p["rows_ms"].items() if "bwd" in r and ("app" in r or "density" in r))
    elif name.startswith("gemm") and p.get("best_gflops"):
        k = "auto %s; agree %s; " % (p.get("auto_engine"), p.get("results_agree")) + ", ".join(
            "%s %s %.0f" % (s, e, g) for s, (e, g) in list(p["best_gflops"].items())[:2]) + " GFLOP/s"
    elif name == "density":
        k = "%s it, %s s/it (last %s), test PSNR %s dB" % (p.get("iterations", "-"), f(p.get("s_per_it"), "%.4f"),
            f(p.get("s_per_it_last_window"), "%.4f"), f(p.get("test_psnr"), "%.2f"))
    elif name == "tests":
        k = "%s: %s passed, %s failed, %s need the weights, %s a tool (of %s finished)" % (p.get("verdict"),
            p.get("passed"), p.get("failed"), p.get("failed_needing_weights"), p.get("failed_needing_tools"),
            p.get("finished"))
        if p.get("failed_names"):
            k += ": " + " ".join(p["failed_names"])
    elif name == "devices":
        k = device or ""
    print("%-16s %-8s %8.1f  %s" % (name, p["status"], p["seconds"], k))
print("projection of the paper's schedule (%s):" % ("quick sizes" if result["quick"] else "%d px steps" % result["size"]))
for st, n, _ in stages:
    q = proj[st]
    print("  %-9s %6d steps x %s s = %s h" % (st, n, f(q["s_per_step"], "%.4f"), f(q["hours"], "%.2f")))
print("  total     %s h" % f(proj["total_hours"], "%.2f"))
print("wrote %s" % out)
EOF
[[ -s "$OUT/device_check.json" ]] || say "device_check: the JSON was not written"
[[ -n "${DC_KEEP:-}" ]] || rm -rf "$WORK"
