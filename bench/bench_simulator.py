"""Motion-aware's GPU engine under numba-cuda's simulator: the simulator's threads against runs in turn.

One tiny window (``--frames`` frames of ``--size`` pixels at K = 4, noise 0.01) runs through the whole GPU engine
twice per round under the simulator: once with every kernel on the simulator's Python threads
(``FLEXVOX_SIM_THREADS=1``, as numba-cuda ships it), once with the kernels that never synchronise their block run
one simulated thread after another (:mod:`flexvox_core.gpu.cudasim`, the default). Printed: each run's seconds,
the median of each way, their ratio, and whether the two videos are the same bits (they must be).

Figures only, never pass/fail. Usage (the simulator is chosen here; no GPU is needed)::

    python bench/bench_simulator.py [--rounds 2] [--frames 2] [--size 8x8]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

os.environ["NUMBA_ENABLE_CUDASIM"] = "1"  # before numba's cuda module is first imported, which reads it once

import numpy as np  # noqa: E402


def _size(text: str) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--size must be HxW in pixels, such as 8x8; got {text!r}") from None
    if h < 4 or w < 4:
        raise argparse.ArgumentTypeError(f"--size must be at least 4x4; got {text!r}")
    return h, w


def one_run(frames: np.ndarray, code: np.ndarray, threads: bool) -> tuple[float, np.ndarray]:
    """(seconds, video) of one window through the GPU engine under the simulator, on threads or in turn."""
    from flexvox_core.gpu.cudasim import needs_threads
    from flexvox_core.motion.options import MotionOptions, check_sample_range
    from flexvox_core.motion.pipeline import run_window

    os.environ["FLEXVOX_SIM_THREADS"] = "1" if threads else "0"
    needs_threads.cache_clear()
    start = time.perf_counter()
    run = run_window(frames, code, MotionOptions(), check_sample_range(frames, None, None), device="cuda")
    seconds = time.perf_counter() - start
    if run.device != "cuda":
        raise RuntimeError(f"the window ran on {run.device}: {run.device_note}")
    return seconds, run.video


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=2, help="rounds of both ways, alternating (default 2)")
    parser.add_argument("--frames", type=int, default=2, help="captured frames in the window (default 2)")
    parser.add_argument("--size", type=_size, default=(8, 8), help="HxW pixels (default 8x8)")
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.frames < 2:
        parser.error(f"--rounds must be >= 1 and --frames >= 2; got {args.rounds} and {args.frames}")
    from flexvox_core import capture, code_from_order
    from flexvox_core.simulate.scenes import render_scene

    h, w = args.size
    code = code_from_order([[0, 2], [3, 1]])
    truth = render_scene("balls", args.frames * 4, h, w, seed=0)
    frames = np.clip(capture(truth, code) + np.random.default_rng(0).normal(0, 0.01, (args.frames, h, w)), 0, 1)
    frames = np.asarray(frames, np.float32)
    print(f"one window: {args.frames} frames of {h}x{w} at K = 4 through the GPU engine under numba-cuda's simulator")
    times: dict[bool, list[float]] = {True: [], False: []}
    videos: dict[bool, np.ndarray] = {}
    for r in range(args.rounds):
        for threads in ((True, False) if r % 2 == 0 else (False, True)):
            seconds, video = one_run(frames, code, threads)
            times[threads].append(seconds)
            videos[threads] = video
            print(f"  round {r + 1}, {'threads' if threads else 'in turn'}: {seconds:.1f} s", flush=True)
    on_threads, in_turn = statistics.median(times[True]), statistics.median(times[False])
    print(f"median: on the simulator's threads {on_threads:.1f} s, in turn {in_turn:.1f} s "
          f"({on_threads / in_turn:.1f}x)")
    print(f"the same bits both ways: {np.array_equal(videos[True], videos[False])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
