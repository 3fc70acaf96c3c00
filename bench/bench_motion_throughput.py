"""Motion-aware throughput: a 1-s, 15 Hz, 640×480 clip with the 4×4 code (K = 16, 73.7 M voxels).

For each moving built-in scene: the end-to-end time of ``motion_aware`` with its defaults, the
split between its steps (high-TR reconstruction, flow, motion-compensated diffusion), M voxels/s,
PSNR; and, as the baseline timed in the same run, the fixed-tensor normalized convolution
(``diffuse`` with the paper's high-SR tensor, n = 4) with its time, PSNR and the ratio.
It prints the M voxels/s and their ratio to 5 and to 15 M voxels/s (15 s and 5 s for the clip; docs/benchmarks.md).

Figures only, never pass/fail. Usage:
``python bench/bench_motion_throughput.py [SCENES] [--frames F] [--flow-scale S] [--slow-reach R] [--refine n]
[--no-local-choice]``
(default: balls,drummer; F = 15; S: automatic, a third at 640×480; R: motion_aware's default).
"""

from __future__ import annotations

import argparse
import time

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.reconstruct import diffuse
from flexvox_core.simulate.scenes import render_scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="?", default="balls,drummer")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--flow-scale", type=float, default=None, help="default: auto (shorter side 160 px)")
    ap.add_argument("--refine", type=float, default=None,
                    help="refinement time (default: motion_aware's, (K/16)²; 0: none, as before it was the default)")
    ap.add_argument("--no-local-choice", action="store_true",
                    help="the trajectory gather alone, without blending in isotropic nc (motion_aware's local_choice)")
    ap.add_argument("--slow-reach", type=float, default=None,
                    help="slow voxels' reach in sampling periods (default: motion_aware's, 0.75; 0: short gather)")
    args = ap.parse_args()
    code = design_code((4, 4)).code
    scale = args.flow_scale or 'auto'
    reach = "default" if args.slow_reach is None else args.slow_reach
    print(f"640x480, K = 16, {args.frames} frames ({args.frames * 16} sub-frames), flow scale {scale}, "
          f"slow reach {reach}{', no local choice' if args.no_local_choice else ''}")
    print("| scene | motion-aware s | high-TR / flow / diffusion s | M voxels/s (÷ 5, ÷ 15) | PSNR dB "
          "| fixed nc s | fixed PSNR dB | time ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        truth = render_scene(scene, args.frames * 16, 480, 640)
        frames = capture(truth, code)
        t0 = time.perf_counter()
        fixed = diffuse(frames, code, tensor=(0.05, 0.05, 1.0), time=4.0)
        t_fixed = time.perf_counter() - t0
        t0 = time.perf_counter()
        extra = {} if args.slow_reach is None else {"slow_reach": args.slow_reach}
        if args.refine is not None:
            extra["refine_time"] = args.refine
        if args.no_local_choice:
            extra["local_choice"] = False
        result = motion_aware(frames, code, flow_scale=args.flow_scale, **extra)
        t_ma = time.perf_counter() - t0
        sec = result.seconds
        rate = truth.size / t_ma / 1e6  # M voxels/s
        print(f"| {scene} | {t_ma:.1f} | {sec['high_tr']:.1f} / {sec['flow']:.1f} / {sec['diffusion']:.1f} "
              f"| {rate:.2f} ({rate / 5:.2f}, {rate / 15:.2f}) | {psnr(truth, result.video):.2f} | {t_fixed:.2f} "
              f"| {psnr(truth, fixed):.2f} | {t_ma / t_fixed:.0f}x |", flush=True)


if __name__ == "__main__":
    main()
