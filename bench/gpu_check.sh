#!/usr/bin/env bash
# The whole GPU check in one command, for a machine with an NVIDIA GPU and no network:
#   1. installs what it lacks from wheels downloaded beforehand into .whl/ (never committed):
#        bench/gpu_check.sh --download        (on a machine with the package index; Python 3.12 wheels)
#   2. runs the GPU path's tests on the card (FLEXVOX_TEST_GPU=1: the simulator's tests and those marked gpu),
#   3. the engine's benchmark (bench/bench_gpu.py: per stage, M voxels/s, memory, PSNR against the CPU),
#   4. the live preview on the GPU against the CPU's, with a soak (bench/bench_live_preview.py),
#   5. the CPU's scaling with its cores (bench/bench_cpu_scaling.py).
# Logs go to $OUT (or bench/results/gpu_check); the last lines of each are printed. The SCI clips are read from
# $FLEXVOX_DATA (default .gpu-data, an ignored folder: copy ../shared/data/sci_benchmark there to include them).
# GPU_CHECK_SMALL=1: tiny sizes under numba-cuda's simulator, with this machine's packages, to try the script on a
# machine without a GPU (PYTHON=.venv/bin/python OUT=/tmp/check GPU_CHECK_SMALL=1 bench/gpu_check.sh).
set -uo pipefail
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
    sed -n '2,/^set -uo/p' "$0" | sed '$d; s/^# \{0,1\}//'
    exit 0
fi
cd "$(dirname "$0")/.."
WHEELS=(numpy==2.4.6 zarr==3.1.6 numcodecs==0.16.6 donfig==0.8.1.post1 google-crc32c==1.9.0)
if [[ "${1:-}" == "--download" ]]; then
    mkdir -p .whl
    exec python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
        --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
        --platform manylinux2014_x86_64 -d .whl "${WHEELS[@]}"
fi
OUT="${OUT:-bench/results/gpu_check}"
mkdir -p "$OUT"
PY="${PYTHON:-python3}"
if compgen -G ".whl/*.whl" > /dev/null && [[ "${GPU_CHECK_SMALL:-0}" != "1" ]]; then
    "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl \
        || exit 1
    export PYTHONPATH="/tmp/site:$PWD"
else
    export PYTHONPATH="$PWD"
fi
export FLEXVOX_DATA="${FLEXVOX_DATA:-$PWD/.gpu-data}" PYTHONUNBUFFERED=1
if [[ "${GPU_CHECK_SMALL:-0}" == "1" ]]; then
    export NUMBA_ENABLE_CUDASIM=1
    TESTS=(tests/flexvox_core/gpu/test_nc.py)
    BENCH=(--scenes balls --frames 2 --repeat 1 --size 16x12 --no-rows)
    PREVIEW=(--seconds 5 --sizes 16x12 --strategies nc --device cuda)
    SCALING=(--cores 1,2 --frames 2)
else
    export FLEXVOX_TEST_GPU=1
    TESTS=(tests/flexvox_core/gpu)
    BENCH=()
    PREVIEW=(--seconds 10 --sizes 640x480,1280x1024 --strategies stream --device cuda --soak 40)
    SCALING=(--cores 2,4,8,16)
fi
step() {  # name, timeout (s), command...: runs it into $OUT/name.log, prints its tail
    local name=$1 limit=$2; shift 2
    echo "== $name ($(date +%T))"
    timeout "$limit" "$@" > "$OUT/$name.log" 2>&1
    echo "   exit $? after $SECONDS s in all"
}
{
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null || echo "no nvidia-smi"
    "$PY" -c "import sys, numpy, numba, cv2; print(sys.version.split()[0], 'numpy', numpy.__version__, 'numba', \
numba.__version__, 'opencv', cv2.__version__)"
    "$PY" -c "import numba_cuda; print('numba-cuda', numba_cuda.__version__)" 2>&1 | tail -1
    nproc
} > "$OUT/versions.log" 2>&1
cat "$OUT/versions.log"
# The project's warning filters name pydantic's (a napari plugin's); without pydantic, warnings are errors alone.
FILTERS=()
"$PY" -c "import pydantic" 2>/dev/null || FILTERS=(-o filterwarnings=error)
step tests 200 "$PY" -m pytest -q -p no:cacheprovider -o addopts="" "${FILTERS[@]}" "${TESTS[@]}"
grep -E "^(FAILED|ERROR)" "$OUT/tests.log" | head -8; tail -2 "$OUT/tests.log"
if ! step engine 180 "$PY" bench/bench_gpu.py "${BENCH[@]}"; then :; fi
if ! grep -q "^| scene | GPU ms" "$OUT/engine.log"; then  # the GPU's DIS failed: the rest with OpenCV's DIS on the host
    tail -5 "$OUT/engine.log"
    step engine_cpu_pairs 90 "$PY" bench/bench_gpu.py "${BENCH[@]}" --pairs cpu --no-rows --repeat 2
    tail -30 "$OUT/engine_cpu_pairs.log"
fi
tail -42 "$OUT/engine.log"
step preview 120 "$PY" bench/bench_live_preview.py "${PREVIEW[@]}"
tail -20 "$OUT/preview.log"
step scaling 100 "$PY" bench/bench_cpu_scaling.py "${SCALING[@]}"
tail -18 "$OUT/scaling.log"
