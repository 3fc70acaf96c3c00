"""The refinement alone, the kept code against a variant of ``bench_motion_throughput.py`` (``--variant``, default
``refine-halo-bands``: the code before the steps were carried from band to band), on the refinement's own inputs.

One ``motion_aware`` call on a built-in scene's clip (default balls, 640×480, 15 frames: the 1-s clip) keeps the
refinement's inputs (the video before it, the flow, the samples' mask, the slow voxels); then the refinement alone
runs on copies of them, the kept code and the variant in turn, N rounds after a warm-up of each: each run's CPU
seconds (``time.process_time``: every thread of the process) and wall seconds, their medians, the peak of the
memory traced by ``tracemalloc`` in one more call of each, and the largest difference between their videos.

With ``--kernel``, the step's kernel alone instead (``vardiff_kernel.vardiff_step``, one numba thread, the
refinement's tensor): 12 sub-frames of synthetic HxW planes, every voxel moving at up to 0.5 px, every one read by
Catmull-Rom, then every one bilinearly; the kept kernel and the variant's in turn, nanoseconds a voxel (CPU), and
whether their bits agree.

Figures only, never pass/fail. Usage:
``python bench/bench_refinement.py [SCENE] [--frames F] [--size HxW] [--rounds N] [--variant VARIANT] [--kernel]``
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
    ap.add_argument("--kernel", action="store_true", help="the step's kernel alone, on synthetic planes")
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.split("x"))
    if args.kernel:
        kernel_alone(H, W, args.rounds, args.variant)
        return
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


def kernel_alone(H: int, W: int, rounds: int, variant: str) -> None:
    import numba

    from flexvox_core.motion import vardiff_kernel as vk
    from flexvox_core.motion.options import REFINE_C

    numba.set_num_threads(1)
    rng = np.random.default_rng(0)
    S = 12
    init = rng.uniform(0, 1, (S, H, W)).astype(np.float32)
    mask = np.zeros(init.shape, bool)
    flow = rng.uniform(-0.5, 0.5, (S, H, W, 2)).astype(np.float32)
    print(f"\nthe refinement's kernel alone, one thread, {S}x{H}x{W} synthetic planes, {rounds} rounds alternating; "
          f"ns a voxel (CPU), medians")
    print("| reads | kept | " + variant + " | the same bits |")
    print("|---|---|---|---|")
    for name, every in (("all bicubic", True), ("all bilinear", False)):
        sharp = np.full(init.shape, every)
        times: dict[str, list[float]] = {"kept": [], variant: []}
        outs = {}
        for r in range(rounds + 1):  # round 0: the warm-up (and the compilation)
            for v in times:
                out = np.empty_like(init)
                with contextlib.nullcontext() if v == "kept" else VARIANTS[v]():
                    c = time.process_time()
                    vk.vardiff_step(init, out, flow, mask, True, *REFINE_C, 0.4, sharp, True, 0, S, 1e-6)
                    if r:
                        times[v].append((time.process_time() - c) / init.size * 1e9)
                outs[v] = out
        same = np.array_equal(outs["kept"].view(np.uint32), outs[variant].view(np.uint32))
        print(f"| {name} | {statistics.median(times['kept']):.1f} | {statistics.median(times[variant]):.1f} | {same} |")
    print(f"load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
