"""Kernels under numba-cuda's simulator: the ones that never synchronise their block run their threads in turn
(:mod:`flexvox_core.gpu.cudasim`), with the same results as on the simulator's threads."""

import importlib
import math
import threading

import numpy as np
import pytest

from flexvox_core.gpu import launch as L
from flexvox_core.gpu.cudasim import needs_threads, sequential_blocks

pytestmark = pytest.mark.skipif(not L._sim(), reason="the simulator's execution only (FLEXVOX_TEST_GPU=1 is set)")


def _all_kernels():
    from flexvox_core.motion.gpu import KERNEL_PACKAGES

    modules = L.modules_of(KERNEL_PACKAGES)
    for name in modules:
        importlib.import_module(name)
    return {n: k for n, k in L.REGISTRY.items() if k.py_func.__module__ in modules}


def test_only_the_kernels_that_synchronise_their_block_take_threads():
    """DIS's search shares its block's memory and waits at its barriers; every other kernel runs sequentially."""
    kernels = _all_kernels()
    assert len(kernels) >= 40
    assert {n for n, k in kernels.items() if needs_threads(k.py_func)} == {"flexvox_core.gpu.dis._search"}


def _plain_device(x):
    return x + 1


def _syncing_device(x):
    cuda.syncthreads()  # noqa: F821 - never called: read by needs_threads only
    return x


def test_a_barrier_inside_a_called_device_function_counts():
    from numba import cuda as numba_cuda

    plain, syncing = numba_cuda.jit(device=True)(_plain_device), numba_cuda.jit(device=True)(_syncing_device)
    scope = {"plain": plain, "syncing": syncing}
    exec("def calls_plain(a):\n    a[0] = plain(a[0])\n"
         "def calls_syncing(a):\n    a[0] = syncing(a[0])\n", scope)
    assert not needs_threads(scope["calls_plain"])
    assert needs_threads(scope["calls_syncing"])


def _both_ways(dispatcher, count, *arrays_and_scalars):
    """The kernel's outputs (every array argument, copied back) on the simulator's threads, then in turn."""
    from numba import cuda

    runs = []
    for sequential in (False, True):
        args = [cuda.to_device(a.copy()) if isinstance(a, np.ndarray) else a for a in arrays_and_scalars]
        grid = math.ceil(count / L.SIM_BLOCK)
        if sequential:
            with sequential_blocks():
                dispatcher[grid, L.SIM_BLOCK](*args)
        else:
            dispatcher[grid, L.SIM_BLOCK](*args)
        runs.append([a.copy_to_host() for a in args if hasattr(a, "copy_to_host")])
    return runs


def test_in_turn_is_bit_for_bit_the_threads_result(rng):
    """A blur pass (device functions from two modules) and the normalized convolution's last step (an atomic
    counter, a NaN where no sample reaches) give the same bits both ways."""
    from flexvox_core.gpu.diffusion import _finish
    from flexvox_core.gpu.filters import _blur_pass, gaussian_taps

    planes = rng.random((2, 5, 7)).astype(np.float32)
    # Zeros, not np.empty: the pass leaves the second output alone, and uninitialised memory may hold a NaN.
    threads, turn = _both_ways(_blur_pass, planes.size, planes, planes, np.zeros_like(planes), np.zeros_like(planes),
                               gaussian_taps(1.0), np.int32(2), np.uint8(1), np.uint8(0))
    assert all(np.array_equal(a, b) for a, b in zip(threads, turn, strict=True))
    assert not np.array_equal(turn[2], planes)  # it did blur

    S, H, W = 8, 3, 4
    num, den = rng.random((S, H, W)).astype(np.float32), rng.random((S, H, W)).astype(np.float32)
    den[0, 0, :3] = 0  # three voxels with no weight: NaN, counted
    frames = rng.random((2, H, W)).astype(np.float32)
    order = rng.integers(0, 4, (H, W)).astype(np.int32)
    threads, turn = _both_ways(_finish, S * H * W, num, den, frames, order, np.ones(2, np.uint8), np.float32(1e-6),
                               np.float32(0), np.float32(1), np.uint8(1), np.empty((S, H, W), np.float32),
                               np.zeros(1, np.int32))
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(threads, turn, strict=True))
    assert turn[-1][0] == 3


def test_an_error_in_a_kernel_leaves_the_simulator_and_the_thread_as_they_were():
    """An index past an array's end raises out of the launch; afterwards the simulator runs blocks on threads
    again, the launching thread carries no simulated index, and the device functions are the simulator's."""
    from numba import cuda
    from numba.cuda.simulator import kernel as simkernel

    from flexvox_core.gpu import filters

    threaded = simkernel.BlockManager
    wrapped = filters.reflected
    planes = cuda.to_device(np.zeros((1, 2, 2), np.float32))
    with pytest.raises(IndexError):
        L.launch(filters._blur_pass, 64, planes, planes, cuda.to_device(np.zeros((1, 1, 1), np.float32)), planes,
                 cuda.to_device(np.array([0.25, 0.5, 0.25], np.float32)), np.int32(2), np.uint8(1), np.uint8(0))
    assert simkernel.BlockManager is threaded
    assert not hasattr(threading.current_thread(), "threadIdx")
    assert filters.reflected is wrapped and getattr(filters.reflected, "_device", False)


def test_every_kernel_on_threads_when_asked(monkeypatch):
    from flexvox_core.gpu.filters import _blur_pass

    needs_threads.cache_clear()
    monkeypatch.setenv("FLEXVOX_SIM_THREADS", "1")
    try:
        assert needs_threads(_blur_pass.py_func)
    finally:
        needs_threads.cache_clear()


def test_a_barrier_run_in_turn_fails_loudly():
    """A kernel with a barrier misjudged as free of one does not pass silently: its barrier raises."""
    from numba import cuda

    scope = {"cuda": cuda}
    exec("def waits(a):\n    a[cuda.grid(1)] = 1\n    cuda.syncthreads()\n", scope)
    waits = cuda.jit(scope["waits"])
    assert needs_threads(scope["waits"])
    out = cuda.to_device(np.zeros(4, np.float32))
    waits[1, 4](out)  # on the simulator's threads: fine
    with pytest.raises(AttributeError, match="syncthreads"), sequential_blocks():
        waits[1, 4](out)


@pytest.mark.slow_sim  # a whole GPU run on the simulator's threads: about a minute
def test_a_whole_window_in_turn_is_bit_for_bit_the_simulators_threads(tmp_path):
    """Motion-aware's whole GPU engine on a tiny noisy window with a dropped frame: the video run in turn equals,
    bit for bit, the one run on the simulator's threads (``FLEXVOX_SIM_THREADS=1``, in a fresh process)."""
    import os
    import subprocess
    import sys
    import textwrap
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    script = textwrap.dedent("""
        import sys
        import numpy as np
        from flexvox_core.motion.options import MotionOptions, check_sample_range
        from flexvox_core.motion.pipeline import run_window
        from tests.flexvox_core.gpu.tiny import CODE, tiny_capture

        _, frames = tiny_capture("balls", 3, 8, 8, noise=0.01)
        missing = np.array([False, True, False])
        frames[1] = 0
        run = run_window(frames, CODE, MotionOptions(), check_sample_range(frames, missing, None), missing=missing,
                         device="cuda")
        assert run.device == "cuda", run.device_note
        np.save(sys.argv[1], run.video)
    """)
    videos = {}
    for threads in ("1", "0"):
        env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1", FLEXVOX_SIM_THREADS=threads,
                   PYTHONPATH=os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
        out = tmp_path / f"threads-{threads}.npy"
        done = subprocess.run([sys.executable, "-c", script, str(out)], cwd=root, env=env, capture_output=True,
                              text=True, timeout=900)
        assert done.returncode == 0, done.stderr[-3000:]
        videos[threads] = np.load(out)
    assert videos["1"].shape == (12, 8, 8) and np.isfinite(videos["1"]).all()
    assert np.array_equal(videos["1"], videos["0"])


def test_launches_from_several_threads_take_turns(rng):
    """Two threads launching in turn-run kernels and one launching a kernel with a barrier, at once: every launch
    completes with its result, and numba's block manager is its own afterwards."""
    from numba import cuda
    from numba.cuda.simulator import kernel as simkernel

    from flexvox_core.gpu import cudasim
    from flexvox_core.gpu.filters import _blur_pass

    threaded = simkernel.BlockManager
    scope = {"cuda": cuda}
    exec("def waits(a):\n    a[cuda.grid(1)] += 1\n    cuda.syncthreads()\n", scope)
    waits = cuda.jit(scope["waits"])
    planes = rng.random((1, 4, 5)).astype(np.float32)
    taps = np.array([0.25, 0.5, 0.25], np.float32)
    scratch = np.empty_like(planes)
    expected = _both_ways(_blur_pass, planes.size, planes, planes, scratch, scratch, taps, np.int32(2), np.uint8(1),
                          np.uint8(0))[0][2]
    errors, results = [], []

    def blur_many():
        try:
            for _ in range(15):
                src, dst = cuda.to_device(planes), cuda.to_device(np.empty_like(planes))
                L.launch(_blur_pass, planes.size, src, src, dst, dst, cuda.to_device(taps), np.int32(2), np.uint8(1),
                         np.uint8(0))
                results.append(np.array_equal(dst.copy_to_host(), expected))
        except Exception as exc:  # noqa: BLE001 - collected and asserted below
            errors.append(exc)

    def wait_many():
        try:
            for _ in range(5):
                out = cuda.to_device(np.zeros(8, np.float32))
                cudasim.run(waits, 1, 8, (out,))
                results.append(bool((out.copy_to_host() == 1).all()))
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    workers = [threading.Thread(target=f) for f in (blur_many, blur_many, wait_many)]
    for t in workers:
        t.start()
    for t in workers:
        t.join(timeout=300)
    assert errors == [] and len(results) == 35 and all(results)
    assert simkernel.BlockManager is threaded
