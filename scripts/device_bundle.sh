#!/usr/bin/env bash
# Packs what scripts/device_check.sh needs on a GPU machine that has no build tools, no -dev packages and no
# network: the built stylerf binary and the CTest executables (with CTestTestfile.cmake and the source and
# build paths they were built at), the shared libraries such a machine lacks (the ICD loader, CLBlast,
# OpenEXR, Boost, OpenBLAS), CLBlast's tuners, the pretrained VGG-19 up to conv4_1 and AdaIN's decoder (all
# of the 80 MB VGG-19 file does not fit; the layouts of both files too, for stand-ins where they are not
# carried) and a lego subset for a full-resolution density run.
#
#   bash scripts/device_bundle.sh BUILD_DIR DEST        e.g. bash scripts/device_bundle.sh build .devcarry
#
# DEST is made afresh (list it in .git/info/exclude so that it travels as a carried path). The machine gets
# the repository and the carried paths in 64 MiB all told: this script refuses (exit 1) a bundle over
# 56 MiB. Environment: DC_TRAIN_VIEWS (default 30) and DC_TEST_VIEWS (default 3) lego views; DC_SCENE (default
# ../shared/data/scenes/blender/lego beside the source tree).
set -euo pipefail

if [[ $# -ne 2 || "$1" == -h || "$1" == --help ]]; then
  sed -n 2,15p "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
BUILD=$(cd "$1" && pwd -P)
DEST_ARG=$2
REPO=$(cd "$(dirname "$0")/.." && pwd -P)
LIMIT_MIB=56
TRAIN_VIEWS=${DC_TRAIN_VIEWS:-30}
TEST_VIEWS=${DC_TEST_VIEWS:-3}

die() { echo "device_bundle: $*" >&2; exit 1; }
[[ -x "$BUILD/stylerf" ]] || die "$BUILD/stylerf is missing: build first"
[[ -f "$BUILD/CTestTestfile.cmake" ]] || die "$BUILD/CTestTestfile.cmake is missing (configure with tests)"
command -v xz >/dev/null || die "xz is needed"

# The source and build paths the binaries were built at: CTestTestfile.cmake names them, and the tests have
# them compiled in (STYLERF_CLI, STYLERF_TEST_FIXTURES).
SRC_ORIG=$(sed -n 's/^# Source directory: //p' "$BUILD/CTestTestfile.cmake" | head -1)
BUILD_ORIG=$(sed -n 's/^# Build directory: //p' "$BUILD/CTestTestfile.cmake" | head -1)
[[ -n "$SRC_ORIG" && -n "$BUILD_ORIG" ]] || die "cannot read the source and build paths from $BUILD/CTestTestfile.cmake"

SCENE=${DC_SCENE:-}
if [[ -z "$SCENE" ]]; then
  for c in "$SRC_ORIG/../shared/data/scenes/blender/lego" "$REPO/../shared/data/scenes/blender/lego"; do
    [[ -f "$c/transforms_train.json" ]] && { SCENE=$c; break; }
  done
fi
[[ -n "$SCENE" && -f "$SCENE/transforms_train.json" ]] || die "no lego scene found (set DC_SCENE)"

rm -rf "$DEST_ARG"
mkdir -p "$DEST_ARG"
DEST=$(cd "$DEST_ARG" && pwd -P)
STAGE=$(mktemp -d /tmp/device_bundle.XXXXXX)
trap 'rm -rf "$STAGE"' EXIT

# 1. Binaries: stylerf and every executable an add_test names inside the build folder, plus the test file.
mapfile -t TESTS < <(grep -o '^add_test([^)]*' "$BUILD/CTestTestfile.cmake" | grep -o "\"$BUILD_ORIG/[^\"]*\"" |
                     tr -d '"' | sed "s|^$BUILD_ORIG/||" | sort -u)
BINS=(stylerf)
for t in "${TESTS[@]}"; do [[ -x "$BUILD/$t" ]] && BINS+=("$t"); done
echo "binaries: stylerf and $(( ${#BINS[@]} - 1 )) tests"
tar -C "$BUILD" -cf - CTestTestfile.cmake "${BINS[@]}" | nice -n 10 xz -T1 -9 > "$DEST/build.tar.xz"

# 2. Shared libraries the GPU image lacks (not libc, libm, libstdc++, libgcc_s, libz: its own are newer).
WANT='^(libOpenCL\.so|libclblast|libOpenEXR|libImath|libIex|libIlmThread|libboost_program_options|libopenblas|libgfortran|libquadmath)'
mkdir -p "$STAGE/lib"
for b in "${BINS[@]}"; do ldd "$BUILD/$b"; done | awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' | sort -u |
  while read -r name path; do
    if [[ "$name" =~ $WANT ]]; then cp -L "$path" "$STAGE/lib/$name"; fi
  done
echo "libraries: $(ls "$STAGE/lib" | tr '\n' ' ')"
tar -C "$STAGE" -cf - lib | nice -n 10 xz -T1 -9 > "$DEST/libs.tar.xz"

# 3. CLBlast's tuners that `stylerf tune` runs (from clblast-utils), if installed here.
mkdir -p "$STAGE/tools/bin"
for t in $(grep -o '"clblast_tuner_[a-z_]*"' "$REPO/examples/stylerf/cmd_tune.cpp" | tr -d '"' | sort -u); do
  p=$(command -v "$t" || true)
  [[ -n "$p" ]] && cp -L "$p" "$STAGE/tools/bin/"
done
if [[ -n "$(ls "$STAGE/tools/bin")" ]]; then
  tar -C "$STAGE" -cf - tools | nice -n 10 xz -T1 -9 > "$DEST/tools.tar.xz"
  echo "tuners: $(ls "$STAGE/tools/bin" | tr '\n' ' ')"
else
  echo "tuners: none installed here (clblast-utils); stylerf tune would run its own kernel's search only"
fi

# 4. The real weights the code reads, as far as they fit: AdaIN's VGG-19 up to conv4_1 (StyleRF reads no deeper
#    layer: 14 MB of its 80) and AdaIN's decoder (14 MB). With them the tests that need the pretrained weights
#    run on the device too (the LPIPS networks, 69 MB, still do not fit: those tests are counted apart). Also
#    both files' layouts (safetensors headers): the check writes stand-ins of the same names and shapes
#    where no weights are carried, for timing only.
WDIR=${STYLERF_WEIGHTS:-$HOME/.cache/stylerf/weights}
python3 - "$WDIR" "$STAGE/weights" "$DEST/weights_layout.json" <<'PYEOF'
import hashlib, json, os, struct, sys
wdir, out, layout_out = sys.argv[1], sys.argv[2], sys.argv[3]
layouts = {}
# AdaIN's vgg_normalised indices: the input 1x1 conv (0) and the convs up to conv4_1 (29).
keep = {"vgg_normalised.safetensors": lambda k: int(k.split(".")[0]) <= 29, "adain_decoder.safetensors": lambda k: True}
manifest = {"note": "carried by device_bundle.sh: vgg_normalised trimmed to conv4_1", "files": {}}
for name, wanted in keep.items():
    p = os.path.join(wdir, name)
    if not os.path.exists(p):
        print("weights: %s absent here, not carried" % p)
        continue
    with open(p, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        layouts[name] = header
        base = 8 + n
        tensors = sorted(((k, v) for k, v in header.items() if k != "__metadata__" and wanted(k)),
                         key=lambda kv: kv[1]["data_offsets"][0])
        hdr = {"__metadata__": header["__metadata__"]} if "__metadata__" in header else {}
        blobs, off = [], 0
        for k, v in tensors:
            a, b = v["data_offsets"]
            f.seek(base + a)
            data = f.read(b - a)
            hdr[k] = dict(v, data_offsets=[off, off + len(data)])
            blobs.append(data)
            off += len(data)
    h = json.dumps(hdr).encode()
    h += b" " * (-len(h) % 8)
    os.makedirs(out, exist_ok=True)
    body = struct.pack("<Q", len(h)) + h + b"".join(blobs)
    with open(os.path.join(out, name), "wb") as f:
        f.write(body)
    manifest["files"][name] = {"sha256": hashlib.sha256(body).hexdigest()}
    print("weights: %s, %d of %d tensors, %.1f MB" % (name, len(tensors), len(header) - ("__metadata__" in header), len(body) / 1e6))
if manifest["files"]:
    json.dump(manifest, open(os.path.join(out, "manifest.json"), "w"), indent=1)
json.dump(layouts, open(layout_out, "w"))
print("weights layouts: %s" % ", ".join(sorted(layouts)) if layouts else "weights layouts: none")
PYEOF
[[ -d "$STAGE/weights" ]] && tar -C "$STAGE" -cf "$DEST/weights.tar" weights   # floats: compression gains little

# 5. A lego subset: TRAIN_VIEWS of the train views and TEST_VIEWS of the test views, evenly spread.
python3 - "$SCENE" "$STAGE/lego" "$TRAIN_VIEWS" "$TEST_VIEWS" <<'EOF'
import json, os, shutil, sys
src, dst, ntrain, ntest = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
for split, n in (("train", ntrain), ("test", ntest)):
    j = json.load(open(os.path.join(src, "transforms_%s.json" % split)))
    frames = j["frames"]
    n = min(n, len(frames))
    keep = [frames[(i * len(frames)) // n] for i in range(n)]
    for f in keep:
        rel = f["file_path"]
        rel = rel if rel.endswith(".png") else rel + ".png"
        os.makedirs(os.path.dirname(os.path.join(dst, rel)), exist_ok=True)
        shutil.copyfile(os.path.join(src, rel), os.path.join(dst, rel))
    j["frames"] = keep
    json.dump(j, open(os.path.join(dst, "transforms_%s.json" % split), "w"), indent=1)
    print("lego subset: %d of %d %s views" % (n, len(frames), split))
EOF
"$BUILD/stylerf" scene-info --scene "$STAGE/lego" > "$STAGE/scene_info.txt" 2>&1 ||
  { cat "$STAGE/scene_info.txt"; die "stylerf scene-info does not load the lego subset"; }
head -3 "$STAGE/scene_info.txt" | sed 's/^/  /'
tar -C "$STAGE" -cf "$DEST/lego.tar" lego   # PNGs: compression gains nothing

# 6. Where it came from.
{
  echo "SRC_ORIG=$SRC_ORIG"
  echo "BUILD_ORIG=$BUILD_ORIG"
  echo "GIT_COMMIT=$(git -C "$REPO" rev-parse HEAD 2>/dev/null || echo unknown)"
  echo "GIT_DIRTY=$(git -C "$REPO" status --porcelain 2>/dev/null | grep -vc '^??' || true)"
  echo "MADE=$(date -u +%Y-%m-%dT%H:%M:%SZ)"
  echo "MADE_ON=$(uname -n)"
} > "$DEST/bundle.env"

BYTES=$(du -sb "$DEST" | cut -f1)
REPO_BYTES=$(git -C "$REPO" ls-files -z 2>/dev/null | (cd "$REPO" && xargs -0 du -cb 2>/dev/null) | tail -1 | cut -f1)
ls -l "$DEST" | tail -n +2 | awk '{printf "  %-20s %6.2f MiB\n", $9, $5 / 1048576}'
awk -v b="$BYTES" -v r="${REPO_BYTES:-0}" 'BEGIN {
  printf "bundle %s: %.2f MiB; with the repository'"'"'s tracked files (%.2f MiB): %.2f MiB of the 64 MiB carried\n",
         "'"$DEST_ARG"'", b / 1048576, r / 1048576, (b + r) / 1048576 }'
if (( BYTES > LIMIT_MIB * 1048576 )); then
  die "the bundle is over $LIMIT_MIB MiB: refused (fewer views: DC_TRAIN_VIEWS)"
fi
