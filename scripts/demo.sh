#!/usr/bin/env bash
# The main job, on built-in data only (nothing from ../shared, no network once set up): set up and build,
# list OpenCL devices, show 2D AdaIN on a generated picture, then StyleRF end to end with one command,
# `stylerf run`, on a generated scene (four textured objects, 48 views of 128 px) and 32 generated styles
# (4 of them held out, never trained on): density, features and style stages, the held-out styles against
# 2D AdaIN, zero-shot videos of 2 of them, the 5x5 style-interpolation sheet and the consistency table, gathered in
# out/demo/index.html and out/demo/summary.json.
# It exits non-zero when its own result is degenerate (`stylerf run --check`): held-out style loss above
# 1.5x 2D AdaIN's, mix-sheet corners closer than 0.01, or short-range RMSE above 0.8x per-frame AdaIN's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
BUILD_DIR=${BUILD_DIR:-build}
S="$BUILD_DIR/stylerf"
OUT=${OUT:-out/demo}
mkdir -p "$OUT"
start=$(date +%s)
echo "== devices"
"$S" devices
echo "== generated pictures: a ray-traced content image and 32 styles, each its own palette and texture"
"$S" demo-images -o "$OUT" --num-styles 32 --size 256
echo "== 2D AdaIN with the real VGG-19 encoder and AdaIN decoder"
"$S" adain --content "$OUT/content.png" --style "$OUT/styles/style_3.png" --size 256 -o "$OUT/adain.png"
echo "== a generated scene: 48 views of four textured objects, with known depth"
"$S" make-scene -o "$OUT/scene" --size 128 --num-views 48
echo "== StyleRF in one command (iterations sized for under 6 minutes in all on a 2-core CPU; a real scene: --minutes 90)"
"$S" run --scene "$OUT/scene" --styles "$OUT/styles" --holdout-styles 4 --stage-iters 700,280,90 --max-videos 2 \
    --frames 36 --eval-views 3 --table-frames 10 --check -o "$OUT"
echo "== one test view, then the same view in three held-out styles (each inset at the corner): $OUT/strip.png"
# Cut from the truth | ours | AdaIN sheets the held-out evaluation wrote for its first view.
mapfile -t sheets < <(ls "$OUT"/style_eval/*.png | sort | head -3)
inputs=(); for s in "${sheets[@]}"; do inputs+=(-i "$s"); done
for s in "${sheets[@]}"; do inputs+=(-i "$OUT/styles/$(basename "$s")"); done
graph="[0:v]crop=iw/3:ih:0:0,scale=iw*2:ih*2:flags=lanczos,pad=iw+8:ih:0:0:white[c];"
for i in 0 1 2; do
  graph+="[$i:v]crop=iw/3:ih:iw/3:0,scale=iw*2:ih*2:flags=lanczos[o$i];"
  graph+="[$((i + 3)):v]scale=80:80,pad=84:84:2:2:white[s$i];"
  graph+="[o$i][s$i]overlay=W-w:H-h,pad=iw+8:ih:0:0:white[p$i];"
done
graph+="[c][p0][p1][p2]hstack=inputs=4,crop=iw-8:ih:0:0"
ffmpeg -loglevel error -y "${inputs[@]}" -filter_complex "$graph" -frames:v 1 "$OUT/strip.png"
echo "== done in $(( $(date +%s) - start )) s after the build; open $OUT/index.html"
echo "   or see it live, restyled by any picture you drop on the page: $S view --ckpt $OUT/style.ckpt --open"
