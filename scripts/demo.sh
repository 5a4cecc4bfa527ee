#!/usr/bin/env bash
# Set up and run the main job on built-in defaults (nothing from ../shared is needed):
# list OpenCL devices, make a content and a style image, stylize with AdaIN, print the GEMM summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
S="$BUILD_DIR/stylerf"
OUT=${OUT:-out/demo}
mkdir -p "$OUT"
echo "== devices"
"$S" devices
echo "== demo images (procedural content and style, made by stylerf)"
"$S" demo-images -o "$OUT"
echo "== 2D AdaIN with the real VGG-19 encoder and AdaIN decoder"
"$S" adain --content "$OUT/content.png" --style "$OUT/style.png" --size 256 -o "$OUT/adain.png"
"$S" adain --content "$OUT/content.png" --style "$OUT/style.png" --size 256 --alpha 0.5 -o "$OUT/adain_alpha0.5.png"
echo "== GEMM summary (quick shapes; full table: $S bench gemm)"
"$S" bench gemm --quick --repeats 2
echo "== outputs in $OUT"
ls -l "$OUT"
