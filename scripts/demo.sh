#!/usr/bin/env bash
# Set up and run the main job on built-in defaults (nothing from ../shared is needed):
# list OpenCL devices, make a content and a style image, stylize with AdaIN, train and render the density
# stage on a generated scene, then its feature stage (VGG feature grid + decoder, fast profile) and its
# style stage (SICT + DST on generated styles, compared with 2D AdaIN on a held-out style), then zero-shot
# use of it (a style image never trained on along a camera path, a 4-corner interpolation sheet, two styles
# composed by a 3D region), its consistency against per-frame AdaIN (eval table), print the GEMM summary.
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
"$S" demo-images -o "$OUT" --styles 5
echo "== 2D AdaIN with the real VGG-19 encoder and AdaIN decoder"
"$S" adain --content "$OUT/content.png" --style "$OUT/style.png" --size 256 -o "$OUT/adain.png"
"$S" adain --content "$OUT/content.png" --style "$OUT/style.png" --size 256 --alpha 0.5 -o "$OUT/adain_alpha0.5.png"
echo "== density stage on a generated scene (make-scene -> train-density -> render)"
"$S" make-scene -o "$OUT/scene" --size 64 --views 30
"$S" train-density --scene "$OUT/scene" --force --iters 200 --init-voxels 32^3 --final-voxels 64^3 \
    --upsample-at 70,140 --mask-at 70,140 --log-every 50 -o "$OUT/density.ckpt"
"$S" render --ckpt "$OUT/density.ckpt" --views test -o "$OUT/render_test"
"$S" render --ckpt "$OUT/density.ckpt" --views path --frames 24 -o "$OUT/render_path"
echo "== feature stage on the same scene (train-features -> render: decoded RGB, PCA of the features)"
"$S" train-features --density "$OUT/density.ckpt" --iters 300 --log-every 100 --force -o "$OUT/features.ckpt"
"$S" render --ckpt "$OUT/features.ckpt" --views test -o "$OUT/features_test"
"$S" render --ckpt "$OUT/features.ckpt" --views path --frames 24 -o "$OUT/features_path"
echo "== style stage on the same scene (train-style on 4 generated styles, 1 held out -> eval-style vs 2D AdaIN)"
"$S" train-style --features "$OUT/features.ckpt" --styles "$OUT/styles" --holdout-styles 1 --iters 40 --patch 64 \
    --log-every 10 --eval-every 20 --force -o "$OUT/style.ckpt"
"$S" eval-style --ckpt "$OUT/style.ckpt" --views 2 --images "$OUT/style_eval"
echo "== zero-shot: a style never trained on along a path, a 4-corner sheet, two styles split by a sphere"
# style_2 is the style train-style held out (printed in its log): never trained on.
"$S" stylize --ckpt "$OUT/style.ckpt" --style "$OUT/styles/style_2.png" --views path --frames 24 -o "$OUT/zero_shot_path"
"$S" stylize --ckpt "$OUT/style.ckpt" --views test --mix-grid \
    "$OUT/styles/style_2.png,$OUT/styles/style_0.png,$OUT/styles/style_1.png,$OUT/styles/style_3.png" -o "$OUT/zero_shot_grid"
"$S" stylize --ckpt "$OUT/style.ckpt" --region sphere:0,0,0,0.6 --style-inside "$OUT/styles/style_2.png" \
    --style-outside "$OUT/styles/style_4.png" --views path --frames 12 --no-losses -o "$OUT/zero_shot_region"
echo "== consistency (the paper's Table 1 protocol by the scene's geometry): RGB floor, per-frame AdaIN, StyleRF"
"$S" eval table --scene-ckpts "$OUT/density.ckpt,$OUT/style.ckpt" --styles "$OUT/styles/style_2.png" \
    --frames 10 --path-frames 60 -o "$OUT/consistency"
echo "== GEMM summary (quick shapes; full table: $S bench gemm)"
"$S" bench gemm --quick --repeats 2
echo "== outputs in $OUT"
ls -l "$OUT"
