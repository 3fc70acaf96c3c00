#!/usr/bin/env bash
# The dry run of bench/gpu_check.sh against the GPU machine's image, on a machine without a GPU (`make gpu-dry-run`):
#   1. bench/image_venv.sh builds .gpu-venv (Python 3.12 with bench/image_packages.txt alone) when it is missing or
#      older than that list;
#   2. `bench/gpu_check.sh --download` fills .whl/ with the carried wheels and flexvox's own; their sizes, the SCI
#      clips' (.gpu-data, copied from $GPU_CHECK_SCI, default ../shared/data/sci_benchmark, when that exists) and the working tree's are added up against
#      the device's 64 MiB transfer limit;
#   3. bench/gpu_check.sh in that venv with GPU_CHECK_SMALL=1 (tiny sizes, numba-cuda's simulator), the carried
#      wheels installed as on the card, the packages the image lacks blocked, and each stage's kernel launches and
#      bytes counted (bench/gpu_dry/sitecustomize.py);
#   4. bench/gpu_dry_counts.py prints those counts per stage.
# Exit status: the check's (non-zero when a stage failed or ran out of time). Logs in $OUT (bench/results/gpu_dry).
set -euo pipefail
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
    sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'
    exit 0
fi
cd "$(dirname "$0")/.."
t0=$SECONDS
VENV="${GPU_IMAGE_VENV:-.gpu-venv}"
OUT="${OUT:-bench/results/gpu_dry}"
if [[ ! -f "$VENV/.built" || bench/image_packages.txt -nt "$VENV/.built" || bench/image_venv.sh -nt "$VENV/.built" ]]
then
    bench/image_venv.sh "$VENV"
    touch "$VENV/.built"
fi
echo "== the image's venv: $("$VENV/bin/python" -V), $(wc -l < "$VENV/image-freeze.txt") packages ($((SECONDS - t0)) s)"
PYTHON="$VENV/bin/python" bench/gpu_check.sh --download
SCI="${GPU_CHECK_SCI:-../shared/data/sci_benchmark}"
if [[ ! -d .gpu-data/sci_benchmark && -d "$SCI" ]]; then
    mkdir -p .gpu-data
    cp -r "$SCI" .gpu-data/
fi
echo "== what travels to the card (limit 64 MiB):"
tree=$(git ls-files -co --exclude-standard -z | du -cb --files0-from=- 2>/dev/null | tail -1 | cut -f1)
travels=(.whl/*.whl)
[[ -d .gpu-data ]] && travels+=(.gpu-data)
carried=$(du -cb "${travels[@]}" | tail -1 | cut -f1)
du -bs "${travels[@]}" | awk '{printf "   %6.2f MiB  %s\n", $1 / 1048576, $2}'
awk -v t="$tree" -v c="$carried" 'BEGIN { printf "   %6.2f MiB  the working tree\n   %6.2f MiB  in all\n", \
    t / 1048576, (t + c) / 1048576; exit (t + c > 64 * 1048576) }' || { echo "OVER the 64 MiB limit"; exit 1; }
rm -rf "$OUT"
mkdir -p "$OUT"
rc=0
OUT="$OUT" PYTHON="$VENV/bin/python" GPU_CHECK_SMALL=1 GPU_CHECK_WHEELS=1 GPU_CHECK_SITE="$PWD/$OUT/site" \
    GPU_CHECK_COUNTS="$PWD/$OUT/counts" bench/gpu_check.sh || rc=$?
"$VENV/bin/python" bench/gpu_dry_counts.py "$OUT"
echo "== gpu-dry-run: exit $rc in $((SECONDS - t0)) s"
exit "$rc"
