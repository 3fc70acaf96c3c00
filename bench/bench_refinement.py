"""The refinement alone, the kept code against a variant of ``bench_motion_throughput.py`` (``--variant``, default
``refine-halo-bands``: the code before the steps were carried from band to band), on the refinement's own inputs.

One ``motion_aware`` call on a built-in scene's clip (default balls, 640×480, 15 frames: the 1-s clip) keeps the
refinement's inputs (the video before it, the flow, the samples' mask, the slow voxels); then the refinement alone
runs on copies of them, the kept code and the variant in turn, N rounds after a warm-up of each: each run's CPU
seconds (``time.process_time``: every thread of the process) and wall seconds, their medians, the peak of the
memory traced by ``tracemalloc`` in one more call of each, and the largest difference between their videos.

Figures only, never pass/fail. Usage:
``python bench/bench_refinement.py [SCENE] [--frames F] [--size HxW] [--rounds N] [--variant VARIANT]``
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.bench_motion_throughput import VARIANTS  # noqa: E402
from flexvox_core.design import design_code  # noqa: E402
from flexvox_core.forward import capture  # noqa: E402
from flexvox_core.motion import motion_aware, stages  # noqa: E402
from flexvox_core.simulate.scenes import render_scene  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", nargs="?", default="balls")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--size", default="480x640", help="HxW")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--variant", default="refine-halo-bands", choices=[v for v in VARIANTS if v != "kept"])
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.split("x"))
    code = design_code((4, 4)).code
    frames = capture(render_scene(args.scene, args.frames * 16, H, W), code)
    got: dict = {}
    kept_stage = stages.CpuStages.refinement

    def keep(self, video, flow, slow):
        got.update(engine=self, video=video.copy(), flow=flow, slow=slow)
        kept_stage(self, video, flow, slow)

    stages.CpuStages.refinement = keep  # type: ignore[method-assign]
    try:
        motion_aware(frames, code)
    finally:
        stages.CpuStages.refinement = kept_stage  # type: ignore[method-assign]
    video = got["video"].copy()

    def run(variant: str) -> tuple[float, float]:
        np.copyto(video, got["video"])
        ctx = contextlib.nullcontext() if variant == "kept" else VARIANTS[variant]()
        with ctx:
            t, c = time.perf_counter(), time.process_time()
            stages.CpuStages.refinement(got["engine"], video, got["flow"], got["slow"])
            return time.process_time() - c, time.perf_counter() - t

    variants = ["kept", args.variant]
    rows: dict[str, list[tuple[float, float]]] = {v: [] for v in variants}
    outs, peaks = {}, {}
    for r in range(args.rounds + 1):  # round 0: the warm-up
        for v in variants:
            figures = run(v)
            if r:
                rows[v].append(figures)
    for v in variants:
        tracemalloc.start()
        run(v)
        peaks[v] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        outs[v] = video.copy()
    print(f"\nthe refinement, {args.scene} {H}x{W}, {args.frames} frames, {args.rounds} rounds alternating, load "
          f"{os.getloadavg()[0]:.1f}; medians")
    print("| variant | CPU s | wall s | CPU s, every run | traced peak MB |")
    print("|---|---|---|---|---|")
    for v in variants:
        cpu, wall = (statistics.median(x[i] for x in rows[v]) for i in (0, 1))
        print(f"| {v} | {cpu:.2f} | {wall:.2f} | {', '.join(f'{x[0]:.2f}' for x in rows[v])} | {peaks[v]:.0f} |")
    print(f"largest |difference| of the videos: {float(np.abs(outs['kept'] - outs[args.variant]).max()):.2g}")


if __name__ == "__main__":
    main()
