#!/usr/bin/env bash
# Builds a fresh venv that holds only what the GPU machine's image holds (bench/image_packages.txt): Python 3.12,
# no zarr, dask, distributed, pyusb, pyserial or opencv-contrib. `make gpu-dry-run` runs bench/gpu_check.sh in it.
#   bench/image_venv.sh [VENV]      (default .gpu-venv, an ignored folder; PYTHON312 names the interpreter)
set -euo pipefail
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
    sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
    exit 0
fi
cd "$(dirname "$0")/.."
VENV="${1:-.gpu-venv}"
PY312="${PYTHON312:-/root/.pyenv/versions/3.12.1/bin/python3.12}"
"$PY312" -c 'import sys; assert sys.version_info[:2] == (3, 12), sys.version' \
    || { echo "image_venv: $PY312 is not Python 3.12 (the image's); set PYTHON312" >&2; exit 2; }
rm -rf "$VENV"
"$PY312" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
grep -v '^\s*#' bench/image_packages.txt | grep . | xargs "$VENV/bin/python" -m pip install --quiet
"$VENV/bin/python" -m pip list --format=freeze > "$VENV/image-freeze.txt"
echo "image_venv: $VENV, $("$VENV/bin/python" -V), $(wc -l < "$VENV/image-freeze.txt") packages"
