"""Motion-aware's long-reach stage alone, on the inputs a real run gives it: the compiled gather that reads the frames
against the remap gather on the sample volume it replaced (``--ab long-reach-remap`` of
``bench/bench_motion_throughput.py``), alternating in one process.

One ``motion_aware`` call on a built-in scene (640×480, the 4×4 code, K = 16) records the long reach's inputs
(flow, guide, slow voxels); then each version runs on copies of them, N rounds after a warm-up, and the wall
seconds and the process's CPU seconds of each run are printed (CPU seconds count the work whatever else the
machine runs), with the reads made, the CPU time per read, and the largest difference between the two results.

Figures only, never pass/fail. Usage, in the repository root: ``python -m bench.bench_long_reach [SCENE] [--frames F]
[--rounds N]``
(default: balls, F = 5, N = 3).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from bench.bench_motion_throughput import _long_reach_on_sample_planes
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.motion import motion_aware, stages
from flexvox_core.simulate.scenes import render_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default="balls")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    code = design_code((4, 4)).code
    frames = capture(render_scene(args.scene, args.frames * 16, 480, 640), code)
    kept = stages.CpuStages.long_reach
    saved: dict = {}

    def record(self, flow, video, slow):
        # The slow voxels made whole (held a bit per voxel): the stage reads an array as well.
        saved.update(engine=self, flow=flow, video=video.copy(), slow=stages.band(slow, 0, self.window.S).copy())
        return kept(self, flow, video, slow)

    stages.CpuStages.long_reach = record
    try:
        motion_aware(frames, code)
    finally:
        stages.CpuStages.long_reach = kept
    engine, flow, video, slow = saved["engine"], saved["flow"], saved["video"], saved["slow"]
    plan = engine.window.long_reach_plan
    reads = int(np.count_nonzero(slow)) * (2 * plan.reach + 1)
    print(f"{args.scene}, 640x480, {args.frames} frames: {np.count_nonzero(slow) / 1e6:.2f} M slow voxels of "
          f"{slow.size / 1e6:.1f} M, reach {plan.reach}: {reads / 1e6:.0f} M trajectory reads (and those of their "
          f"neighbours for the blur)")
    runs: dict[str, list[tuple[float, float]]] = {"frames (kept)": [], "remap (before)": []}
    results = {}
    for round_ in range(args.rounds + 1):  # the first: warm-up
        for name in runs:
            out = video.copy()
            w0, c0 = time.perf_counter(), time.process_time()
            if name == "frames (kept)":
                kept(engine, flow, out, slow)
            else:
                with _long_reach_on_sample_planes():
                    stages.CpuStages.long_reach(engine, flow, out, slow)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            if round_:
                runs[name].append((wall, cpu))
            results[name] = out
    print(f"load {os.getloadavg()[0]:.1f} (1-min average at the end)")
    print("| long reach | wall s, every run | CPU s, every run | CPU s median | CPU ns per read |")
    print("|---|---|---|---|---|")
    for name, rr in runs.items():
        cpu = statistics.median(c for _, c in rr)
        print(f"| {name} | {', '.join(f'{w:.2f}' for w, _ in rr)} | {', '.join(f'{c:.2f}' for _, c in rr)} "
              f"| {cpu:.2f} | {cpu / reads * 1e9:.1f} |")
    diff = np.abs(results["frames (kept)"] - results["remap (before)"])
    print(f"|kept − before|: max {diff.max():.2e}, mean at the slow voxels {diff[slow].mean():.2e}")


if __name__ == "__main__":
    main()
