"""Streaming motion-aware against the offline run over the whole clip: PSNR per scene, time per frame.

For each built-in moving scene (fan, balls, drummer, pan; 4×4 code, K = 16): the offline
``motion_aware`` over the whole clip, and :class:`~flexvox_core.motion.streaming.StreamingMotionAware`
fed one camera frame at a time (one frame behind), both with the samples' range [0, 1]. Printed: each
one's PSNR (mean over sub-frames) and the difference (the goal: within 0.3 dB), the seconds per
camera frame of both (the stream's median over its frames; the offline run's total over the frames),
and the stream's flow pairs found again against computed. ``--noise`` adds photon noise and read noise
(σ = 3 e⁻, 1000 e⁻ per unit). Figures only, never pass/fail. Usage:
``python bench/bench_streaming.py [--size HxW] [--frames F] [--noise] [--back B]``
(default 96x128, 8 frames; ``--size 480x640`` for the VGA figures).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.motion.streaming import BACK, StreamingMotionAware
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video

SCENES = ("fan", "balls", "drummer", "pan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="96x128", help="HxW (default 96x128)")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--noise", action="store_true", help="photon noise and read noise (sigma 3 e-)")
    ap.add_argument("--back", type=int, default=BACK, help=f"frames of context before each frame (default {BACK})")
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.lower().split("x"))
    code = design_code((4, 4)).code
    K = code.shape[2]
    effects = parse_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}}) if args.noise else None
    print(f"{H}x{W}, K = 16, {args.frames} frames, {'photon + read noise' if args.noise else 'no noise'}, "
          f"stream: {args.back} frame(s) back, 1 ahead")
    print("| scene | offline dB | stream dB | difference | offline s/frame | stream s/frame (median) "
          "| ratio | flow pairs found / computed |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        truth = render_scene(scene, args.frames * K, H, W)
        if effects is None:
            frames = capture(truth, code)
        else:
            res = simulate_video(truth, code, effects=effects, seed=0, electrons_per_unit=1000.0)
            frames = np.clip(np.asarray(res.frames, np.float32), 0, 1)
        t0 = time.perf_counter()
        offline = motion_aware(frames, code, sample_range=(0, 1)).video
        t_off = (time.perf_counter() - t0) / args.frames
        stream = StreamingMotionAware(code, back=args.back)
        out = []
        for frame in frames:
            out += stream.push(frame)
        out += stream.finish()
        video = np.concatenate([o.video for o in out])
        t_st = float(np.median([o.seconds for o in out]))
        p_off, p_st = psnr(truth, offline), psnr(truth, video)
        print(f"| {scene} | {p_off:.2f} | {p_st:.2f} | {p_st - p_off:+.2f} | {t_off:.2f} | {t_st:.2f} "
              f"| {t_st / t_off:.2f}x | {stream.memo.hits} / {stream.memo.misses} |", flush=True)


if __name__ == "__main__":
    main()
