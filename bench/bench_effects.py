"""What each simulation effect costs: the simulator's time with no effect, each alone, and all.

Run: ``.venv/bin/python bench/bench_effects.py [--size 240x320] [--frames 8] [--repeat 5]``.
Prints the median of ``--repeat`` runs per row and its ratio to the no-effect baseline,
measured in the same run. Rendering the scene is not timed.
"""

from __future__ import annotations

import argparse
import statistics
import time

from flexvox_core.design import design_code
from flexvox_core.simulate.effects import EFFECTS
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video

TYPICAL = {  # a realistic setting for each effect
    "misregistration": {"dx": 0.3, "dy": -0.2, "rotation": 0.05},
    "pattern_blur": {"sigma": 0.6},
    "leakage": {"alpha": 0.005},
    "sync_phase": {"offset": 0.1, "jitter": 0.02},
    "global_illumination": {"fraction": 0.02},
    "ambient": {"level": 0.01},
    "dark_current": {"rate": 50.0},
    "photon_noise": {},
    "saturation": {"full_well": 900.0},
    "read_noise": {"sigma": 3.0},
    "adc": {"bits": 12, "gain": 0.25, "black_level": 64},
    "dropped_frames": {"probability": 0.01},
}


def timed(video, code, effects, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        simulate_video(video, code, effects=effects, seed=0)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", default="240x320")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args(argv)
    H, W = map(int, args.size.split("x"))
    code = design_code((4, 4)).code
    video = render_scene("drummer", args.frames * 16, H, W)
    voxels = video.size
    base = timed(video, code, [], args.repeat)
    rows = [("none (ideal forward model)", base)]
    for name, params in TYPICAL.items():
        rows.append((name, timed(video, code, [EFFECTS[name](**params)], args.repeat)))
    everything = [EFFECTS[n](**p) for n, p in TYPICAL.items()]
    rows.append(("all twelve", timed(video, code, everything, args.repeat)))
    print(f"simulator cost per effect: drummer {H}x{W}, K=16, {args.frames} frames ({voxels / 1e6:.1f} M voxels), "
          f"median of {args.repeat}")
    print("| effects | time (ms) | x baseline | M voxels/s |\n|---|---|---|---|")
    for name, t in rows:
        print(f"| {name} | {t * 1e3:.1f} | {t / base:.1f} | {voxels / t / 1e6:.0f} |")


if __name__ == "__main__":
    main()
