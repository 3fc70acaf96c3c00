"""Per-item work on the cores: :func:`flexvox_core.threads.for_each` against a thread pool made per call with a
future per item (``ThreadPoolExecutor.map``, the form it replaced), in one process, alternating.

1. The cost per item of a small item (a 64×64 float32 product by OpenCV): wall and CPU µs.
2. With ``--motion``: a warm ``motion_aware`` call on the 1-s 640×480 balls clip (K = 16), every module's
   ``for_each`` swapped for the other form: wall and CPU s, medians of ``--rounds`` alternating calls.

Figures only, never pass/fail. Usage, from the repository root: ``python -m bench.bench_for_each [--motion]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from flexvox_core import threads


def pool_per_call(fn, count: int) -> None:
    """The form :func:`~flexvox_core.threads.for_each` replaced: a pool per call, a future per item."""
    n = threads.workers()
    if n == 1 or count < 2:
        for i in range(count):
            fn(i)
        return
    saved = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ThreadPoolExecutor(max_workers=n) as pool:
            list(pool.map(fn, range(count)))
    finally:
        cv2.setNumThreads(saved)


FORMS = {"kept": threads.for_each, "pool per call": pool_per_call}


def use(form) -> None:
    """Every loaded flexvox module's ``for_each`` (imported by name) set to ``form``."""
    for name, module in list(sys.modules.items()):
        if name.startswith("flexvox_core") and callable(getattr(module, "for_each", None)):
            module.for_each = form


def per_item(rounds: int) -> None:
    a = np.random.default_rng(0).random((240, 64, 64), np.float32)
    out = np.empty_like(a)

    def fn(i: int) -> None:
        cv2.multiply(a[i], 2.0, dst=out[i])

    got: dict[str, list[tuple[float, float]]] = {k: [] for k in FORMS}
    for _ in range(rounds):
        for name, form in FORMS.items():
            t0, c0 = time.perf_counter(), time.process_time()
            for _ in range(50):
                form(fn, len(a))
            n = 50 * len(a)
            got[name].append(((time.perf_counter() - t0) / n * 1e6, (time.process_time() - c0) / n * 1e6))
    print(f"workers {threads.workers()}; a 64x64 product per item, 240 items a call, 50 calls, {rounds} rounds")
    for name, rows in got.items():
        print(f"  {name:>14}: {statistics.median(r[0] for r in rows):6.1f} us wall, "
              f"{statistics.median(r[1] for r in rows):6.1f} us CPU per item")


def motion(rounds: int) -> None:
    from flexvox_core.design import design_code
    from flexvox_core.forward import capture
    from flexvox_core.motion import motion_aware
    from flexvox_core.simulate import render_scene

    code = design_code((4, 4)).code
    frames = capture(render_scene("balls", 240, 480, 640), code)
    motion_aware(frames, code)  # compiled and warm
    got: dict[str, list[tuple[float, float]]] = {k: [] for k in FORMS}
    for _ in range(rounds):
        for name, form in FORMS.items():
            use(form)
            t0, c0 = time.perf_counter(), time.process_time()
            motion_aware(frames, code)
            got[name].append((time.perf_counter() - t0, time.process_time() - c0))
    use(threads.for_each)
    print(f"warm motion_aware, balls 640x480, 240 sub-frames, K = 16; medians of {rounds} alternating calls")
    base = statistics.median(r[0] for r in got["pool per call"])
    for name, rows in got.items():
        wall = statistics.median(r[0] for r in rows)
        print(f"  {name:>14}: {wall:5.2f} s wall ({wall / base:.2f}x), "
              f"{statistics.median(r[1] for r in rows):5.2f} s CPU")


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    p.add_argument("--motion", action="store_true", help="also a warm motion_aware call with each form")
    args = p.parse_args(argv)
    per_item(args.rounds)
    if args.motion:
        motion(args.rounds)


if __name__ == "__main__":
    main()
