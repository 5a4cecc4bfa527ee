#!/usr/bin/env bash
# The decoder step against PyTorch in one run: PyTorch-CPU (../shared/anchors/torch_step.py) against
# `stylerf bench decoder-step`, paper and fast decoders at SIZE (default 256), alternating the two
# engines so that both see the same machine state; prints each median and the ratio ours / PyTorch.
#   usage: bench/decoder_step_vs_torch.sh PYTHON_WITH_TORCH [SIZE] [STEPS]
# PyTorch is never a dependency of the project: make a throw-away environment for it, e.g.
#   python3 -m venv TORCH_ENV && TORCH_ENV/bin/pip install torch
set -euo pipefail
py=${1:?usage: $0 PYTHON_WITH_TORCH [SIZE] [STEPS]}
size=${2:-256}
steps=${3:-5}
here=$(cd "$(dirname "$0")/.." && pwd)
anchor="$here/../shared/anchors/torch_step.py"
bin="$here/build/stylerf"
[ -f "$anchor" ] || { echo "no $anchor (../shared beside the checkout)" >&2; exit 2; }
[ -x "$bin" ] || { echo "no $bin: build first (cmake -S . -B build && cmake --build build -j2)" >&2; exit 2; }
out=$(mktemp -d)
for dec in paper fast; do
  torch=$("$py" "$anchor" "$size" "$steps" 2 "$dec" 2>/dev/null | tail -1)
  "$bin" bench decoder-step --size "$size" --decoder "$dec" --repeats "$steps" --json "$out/$dec.json" > "$out/$dec.log"
  python3 - "$torch" "$out/$dec.json" "$dec" <<'PY'
import json, sys
t = json.loads(sys.argv[1]); o = json.load(open(sys.argv[2]))
print(f"{sys.argv[3]:6s} size {o['size']}: pytorch-cpu {t['median_s']:.3f} s/step (torch {t['torch']}, 2 threads), "
      f"stylerf {o['median_s']:.3f} s/step ({o['conv_algo']}, {o['gemm_engine']}): ratio {o['median_s'] / t['median_s']:.3f}")
PY
done
rm -rf "$out"
