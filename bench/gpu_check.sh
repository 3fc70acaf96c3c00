#!/usr/bin/env bash
# The whole GPU check in one command, for the lent machine with an NVIDIA GPU and no network (its image's python3
# 3.12; bench/image_packages.txt lists what that image holds), in stages, each with a header, a time limit and its
# wall time; all of them within GPU_CHECK_BUDGET seconds (default 450),
# so one device call of 8 minutes (timeout_s 500) with the machine's start leaves ~5 minutes of the 15 for a rerun
# of the stages that need it (GPU_CHECK_ONLY=... GPU_CHECK_BUDGET=270):
#   versions  Python, numpy, numba, numba-cuda, OpenCV, the GPU, the cores
#   tests     the GPU path's tests on the card (FLEXVOX_TEST_GPU=1: the simulator's tests and those marked gpu)
#   engine    bench/bench_gpu.py: per stage, M voxels/s, memory against the estimate, PSNR and time against the CPU,
#             the same bits on every repeat
#   rows      bench/gpu_rows.py: PSNR GPU against CPU on every motion-aware row of flexvox bench and the SCI clips
#             (when $FLEXVOX_DATA holds them), the same bits on a rerun of each row
#   preview   bench/bench_live_preview.py --device cuda: the live preview on the GPU against the CPU's, a soak
#   scaling   bench/bench_cpu_scaling.py: motion-aware's stages at 2, 4, 8, 16 cores (taskset)
# What the image lacks travels as wheels in .whl/ (ignored): `bench/gpu_check.sh --download` (on a machine with the
# package index) fetches the CARRIED wheels below and builds flexvox's own wheel; the check installs them with
# `pip --no-index --no-deps --target $GPU_CHECK_SITE` and puts that folder on PYTHONPATH. The device call carries
# .whl and .gpu-data: `bench/gpu_check.sh` as its command, timeout_s 500.
# Logs go to $OUT (or bench/results/gpu_check); the last lines of each are printed. The SCI clips are read from
# $FLEXVOX_DATA (default .gpu-data, an ignored folder: copy ../shared/data/sci_benchmark there to include them).
# GPU_CHECK_SMALL=1: tiny sizes under numba-cuda's simulator; `make gpu-dry-run` runs it so in a venv holding only
# the image's packages plus the carried wheels (bench/gpu_dry_run.sh), with what the image lacks blocked.
# GPU_CHECK_ONLY=tests,engine: those stages alone. GPU_CHECK_SOAK: the preview's soak in seconds (default 30;
# a 5-minute soak needs a call of its own: GPU_CHECK_ONLY=preview GPU_CHECK_SOAK=300).
set -uo pipefail
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
    sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'
    exit 0
fi
cd "$(dirname "$0")/.."
# Carried over the image (the image's numpy 2.5 breaks its numba-cuda), with flexvox's own wheel (built by
# --download: flexvox_app and flexvox_calibration install under names that are not their folders'). Nothing else:
# the check's path imports no zarr, dask, distributed, pyusb, pyserial or cv2.optflow (tests/test_gpu_check.py).
CARRIED=(numpy==2.4.6)
ABSENT=zarr,numcodecs,dask,distributed,usb,serial,PySide6,pyqtgraph,napari,harvesters,genicam,ome_zarr_models
if [[ "${1:-}" == "--download" ]]; then
    PY="${PYTHON:-python3}"
    mkdir -p .whl
    rm -f .whl/flexvox-*.whl
    "$PY" -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
        --platform manylinux2014_x86_64 -d .whl "${CARRIED[@]}" || exit 1
    "$PY" -m pip wheel --quiet --no-deps -w .whl . > "${TMPDIR:-/tmp}/gpu_check_wheel.log" 2>&1 \
        || { cat "${TMPDIR:-/tmp}/gpu_check_wheel.log"; exit 1; }
    ls -l .whl
    exit 0
fi
OUT="${OUT:-bench/results/gpu_check}"
mkdir -p "$OUT"
PY="${PYTHON:-python3}"
SMALL="${GPU_CHECK_SMALL:-0}"
SITE="${GPU_CHECK_SITE:-/tmp/site}"
export PYTHONPATH="$PWD"
if compgen -G ".whl/*.whl" > /dev/null && [[ "$SMALL" != "1" || "${GPU_CHECK_WHEELS:-0}" == "1" ]]; then
    rm -rf "$SITE"
    "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" .whl/*.whl \
        || exit 1
    # The tree's own packages first (flexvox_core, rig_drivers: always this tree's), then the carried wheels.
    export PYTHONPATH="$PWD:$SITE"
    "$PY" - "$SITE" <<'EOF' || exit 1
import filecmp, pathlib, sys
site = pathlib.Path(sys.argv[1])
for installed, folder in (("flexvox_app", "app"), ("flexvox_calibration", "calibration")):
    for f in pathlib.Path(folder).rglob("*.py"):
        if not filecmp.cmp(f, site / installed / f.relative_to(folder), shallow=False):
            sys.exit(f"gpu_check: the carried flexvox wheel is older than {f}: rebuild it (bench/gpu_check.sh --download)")
EOF
fi
export FLEXVOX_DATA="${FLEXVOX_DATA:-$PWD/.gpu-data}" PYTHONUNBUFFERED=1
if [[ "$SMALL" == "1" ]]; then
    export NUMBA_ENABLE_CUDASIM=1 GPU_CHECK_ABSENT="$ABSENT" PYTHONPATH="$PWD/bench/gpu_dry:$PYTHONPATH"
    TESTS=(tests/flexvox_core/gpu/test_nc.py)
    BENCH=(--scenes balls --frames 2 --repeat 1 --size 8x8 --no-rows)
    ROWS=(--crop 8x8 --frames 2 --cases 0 --sci 1 --rows 1)
    PREVIEW=(--seconds 3 --sizes 8x8 --strategies stream --device cuda --soak "${GPU_CHECK_SOAK:-3}")
    SCALING=(--cores 1,2 --frames 1)
else
    export FLEXVOX_TEST_GPU=1
    TESTS=(tests/flexvox_core/gpu)
    BENCH=(--scenes balls,drummer --no-rows)
    ROWS=()
    PREVIEW=(--seconds 6 --sizes 640x480,1280x1024 --strategies stream --device cuda --soak "${GPU_CHECK_SOAK:-30}")
    SCALING=(--cores 2,4,8,16 --frames 8)
fi
# Under the simulator every stage is slower: its limits times SLOW, and a budget to match.
SLOW=1
[[ "$SMALL" == "1" ]] && SLOW=5
BUDGET="${GPU_CHECK_BUDGET:-$((450 * SLOW))}"
ONLY=",${GPU_CHECK_ONLY:-versions,tests,engine,rows,preview,scaling},"
step() {  # name, limit (s), command...: runs it into $OUT/name.log within its limit and what is left of the budget
    local name=$1 limit=$2 t0=$SECONDS rc; shift 2
    [[ "$ONLY" == *",$name,"* ]] || return 0
    limit=$((limit * SLOW))
    local left=$((BUDGET - SECONDS))
    ((left < limit)) && limit=$left
    if ((limit < 5)); then
        echo "== $name: skipped, the budget of $BUDGET s is spent"
        return 0
    fi
    echo "== $name (limit $limit s, at $SECONDS s of $BUDGET)"
    GPU_CHECK_STAGE=$name timeout -k 5 "$limit" "$@" > "$OUT/$name.log" 2>&1
    rc=$?
    local note=""
    ((rc == 124 || rc == 137)) && note=" (STOPPED at its limit)"
    echo "   $name: exit $rc$note, $((SECONDS - t0)) s"
    echo "$name $rc $((SECONDS - t0))" >> "$OUT/stages.txt"
}
: > "$OUT/stages.txt"
versions() {
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || echo "no nvidia-smi"
    "$PY" -c "import sys, numpy, numba, cv2; print('Python', sys.version.split()[0], 'numpy', numpy.__version__, \
'numba', numba.__version__, 'opencv', cv2.__version__, 'optflow', hasattr(cv2, 'optflow'))"
    "$PY" -c "import numba_cuda; print('numba-cuda', numba_cuda.__version__)" 2>&1 | tail -1
    "$PY" -c "import flexvox_app, flexvox_core; print('flexvox from', flexvox_app.__file__, flexvox_core.__file__)"
    echo "cores $(nproc)"
}
export PY
export -f versions
step versions 30 bash -c versions
cat "$OUT/versions.log"
# The project's warning filters name pydantic's (a napari plugin's); without pydantic, warnings are errors alone.
FILTERS=()
"$PY" -c "import pydantic" 2>/dev/null || FILTERS=(-o filterwarnings=error)
# No plugin loads by itself (the image's and a venv's differ, and a venv's napari or Qt plugin imports what the
# dry run blocks); each test's own limit where pytest-timeout is there (the image has it).
export PYTEST_DISABLE_PLUGIN_AUTOLOAD=1
"$PY" -c "import pytest_timeout" 2>/dev/null && FILTERS+=(-p pytest_timeout --timeout 120)
step tests 120 "$PY" -m pytest -q -p no:cacheprovider -o addopts="" "${FILTERS[@]}" "${TESTS[@]}"
[[ -f "$OUT/tests.log" ]] && { grep -E "^(FAILED|ERROR)" "$OUT/tests.log" | head -8; tail -2 "$OUT/tests.log"; }
step engine 110 "$PY" bench/bench_gpu.py "${BENCH[@]}"
if [[ -f "$OUT/engine.log" ]] && ! grep -q "^| scene | GPU ms" "$OUT/engine.log"; then
    tail -5 "$OUT/engine.log"  # the GPU's DIS failed: the rest with OpenCV's DIS on the host
    step engine_cpu_pairs 60 "$PY" bench/bench_gpu.py "${BENCH[@]}" --pairs cpu --repeat 2
    [[ -f "$OUT/engine_cpu_pairs.log" ]] && tail -30 "$OUT/engine_cpu_pairs.log"
fi
[[ -f "$OUT/engine.log" ]] && tail -32 "$OUT/engine.log"
step rows 75 "$PY" bench/gpu_rows.py "${ROWS[@]}"
[[ -f "$OUT/rows.log" ]] && { head -1 "$OUT/rows.log"; grep -E "^[0-9]+ rows|NO \||\| cpu \(" "$OUT/rows.log" | tail -8; }
step preview 100 "$PY" bench/bench_live_preview.py "${PREVIEW[@]}"
[[ -f "$OUT/preview.log" ]] && tail -20 "$OUT/preview.log"
step scaling 90 "$PY" bench/bench_cpu_scaling.py "${SCALING[@]}"
[[ -f "$OUT/scaling.log" ]] && tail -18 "$OUT/scaling.log"
echo "== done in $SECONDS s (budget $BUDGET s); each stage's exit status and seconds in $OUT/stages.txt"
! grep -vq " 0 [0-9]*$" "$OUT/stages.txt"
