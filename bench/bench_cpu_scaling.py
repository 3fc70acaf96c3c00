"""Motion-aware on the CPU at 2, 4, 8, 16 … cores: each stage's time, and what does not scale.

Each core count runs in its own process pinned to cores 0 … n − 1 (``taskset``; numba's threads set to n), on
a 1-s, 15 Hz, 640×480 clip of a scene (K = 16, 73.7 M voxels): one warm-up, then ``--repeat`` runs, the median
of each stage. Printed: seconds per stage at every core count, and each stage's speed-up from the fewest cores
to the most against the ideal (the ratio of the core counts).

Figures only, never pass/fail. Usage: ``python bench/bench_cpu_scaling.py [--cores 2,4,8,16] [--scene balls]
[--frames 15] [--repeat 1]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent("""
    import json, statistics, sys, time
    from flexvox_core.design import design_code
    from flexvox_core.forward import capture
    from flexvox_core.motion import motion_aware
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.threads import workers
    scene, frames, repeat = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    code = design_code((4, 4)).code
    f = capture(render_scene(scene, frames * 16, 480, 640, seed=0), code)
    motion_aware(f[:2], code)  # compiles numba's kernels
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = motion_aware(f, code)
        runs.append((time.perf_counter() - t0, r.stage_seconds))
    total = statistics.median(s for s, _ in runs)
    stages = {k: statistics.median(st[k] for _, st in runs) for k in runs[0][1]}
    print(json.dumps({"total": total, "stages": stages, "workers": workers()}))
""")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", default="2,4,8,16")
    ap.add_argument("--scene", default="balls")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    have = len(os.sched_getaffinity(0))
    counts = [n for n in (int(v) for v in args.cores.split(",")) if n <= have]
    if shutil.which("taskset") is None:
        sys.exit("bench_cpu_scaling: needs taskset (util-linux)")
    results = {}
    for n in counts:
        env = {**os.environ, "NUMBA_NUM_THREADS": str(n)}
        done = subprocess.run(["taskset", "-c", f"0-{n - 1}", sys.executable, "-c", CHILD, args.scene,
                               str(args.frames), str(args.repeat)], capture_output=True, text=True, env=env)
        if done.returncode:
            sys.exit(f"{n} cores failed:\n{done.stderr[-2000:]}")
        results[n] = json.loads(done.stdout.strip().splitlines()[-1])
        r = results[n]
        print(f"{n} cores ({r['workers']} worker threads): {r['total']:.2f} s", flush=True)
    stages = list(results[counts[0]]["stages"])
    voxels = args.frames * 16 * 480 * 640
    print(f"\n{args.scene}, 640x480, K = 16, {args.frames} frames; seconds (median of {args.repeat})")
    print("| stage | " + " | ".join(f"{n} cores" for n in counts) + f" | speed-up {counts[0]}→{counts[-1]} |")
    print("|---|" + "---|" * (len(counts) + 1))
    ideal = counts[-1] / counts[0]
    for k in ("total", *stages):
        vals = [results[n]["total"] if k == "total" else results[n]["stages"].get(k, 0.0) for n in counts]
        gain = vals[0] / vals[-1] if vals[-1] > 0 else float("nan")
        print(f"| {k} | " + " | ".join(f"{v:.2f}" for v in vals) + f" | {gain:.1f}x (ideal {ideal:.0f}x) |")
    print("| M voxels/s | " + " | ".join(f"{voxels / results[n]['total'] / 1e6:.1f}" for n in counts) + " | |")


if __name__ == "__main__":
    main()
