#!/usr/bin/env bash
# Installs what stylerf needs on a fresh Debian machine, fetches the pretrained weights and builds.
# Idempotent: packages already present are not reinstalled, weights already verified are kept.
#   BUILD_DIR   build directory (default: build)
#   JOBS        parallel build jobs (default: number of cores)
set -euo pipefail
cd "$(dirname "$0")/.."

# libcpp-httplib-dev: `stylerf view`'s HTTP server; chromium, chromium-driver, python3-selenium: its browser test;
# libopenmpi-dev, openmpi-bin: several ranks under mpirun (optional at build time; the suite tests them).
PACKAGES=(build-essential cmake pkg-config python3 python3-pip
          ocl-icd-opencl-dev opencl-c-headers opencl-clhpp-headers pocl-opencl-icd clinfo
          libclblast-dev clblast-utils libopenexr-dev libboost-program-options-dev doctest-dev
          nlohmann-json3-dev libstb-dev libopenblas-dev ffmpeg colmap
          pybind11-dev python3-dev python3-numpy python3-pytest
          libcpp-httplib-dev chromium chromium-driver python3-selenium libopenmpi-dev openmpi-bin)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "== installing: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "== system packages present"
fi

echo "== weights (AdaIN's VGG-19 encoder and decoder, LPIPS VGG-16 and AlexNet)"
bash scripts/fetch_weights.sh

BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}
echo "== building in $BUILD_DIR with $JOBS jobs"
mkdir -p "$BUILD_DIR"
# The Python module and its pytest suite use Debian's interpreter, the one apt's numpy and pytest serve
# (python3 on PATH may be another, e.g. pyenv's).
PY_ARGS=()
[ -x /usr/bin/python3 ] && PY_ARGS=(-DPython_EXECUTABLE=/usr/bin/python3)
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release "${PY_ARGS[@]}" > "$BUILD_DIR/cmake-configure.log" 2>&1 || { cat "$BUILD_DIR/cmake-configure.log"; exit 1; }
cmake --build "$BUILD_DIR" -j "$JOBS"
