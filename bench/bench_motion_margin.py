"""Motion-aware against the best fixed-tensor diffusion on the moving built-in scenes, with or without noise.

Motion-aware's accuracy goal: on the built-in moving scenes at K = 16 (fan, balls and drummer; pan is
reported too; 96×128, 6 frames, 4×4 code), motion-aware PSNR at least 2 dB above the best fixed-tensor
diffusion — every tensor family and time of ``flexvox bench``, the one with the best pooled score chosen
after the fact — with and without noise effects. Two ways of pooling scenes are printed: the mean of the
scenes' PSNR (each scene's PSNR the mean over its sub-frames, as the SCI literature reports), and the PSNR
of the mean squared error over the scenes (what ``flexvox bench`` tables). Per scene, against that scene's
own best fixed tensor and time. ``--noise`` adds photon noise and read noise (σ = 3 e⁻) at ``--electrons``
e⁻ per unit of intensity; ``--seed`` renders the scenes (and draws the noise) with another seed;
``--no-noise-aware`` turns motion-aware's noise-aware smoothing off (an A/B of it). Figures only, never
pass/fail. Usage:
``python bench/bench_motion_margin.py [--noise] [--electrons E] [--seed S] [--refine n] [--no-noise-aware]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from flexvox_app.accuracy_bench import TENSORS, TIMES_FULL
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.reconstruct import diffuse
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video

SCENES = ("fan", "balls", "drummer", "pan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", action="store_true", help="photon noise and read noise (sigma 3 e-)")
    ap.add_argument("--electrons", type=float, default=1000.0, help="e- per unit of intensity (default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--refine", type=float, default=None, metavar="n",
                    help="motion-aware's refinement time (default: its own, (K/16)²)")
    ap.add_argument("--no-noise-aware", action="store_true",
                    help="motion-aware without its noise-aware smoothing (noise_aware=False)")
    args = ap.parse_args()
    code = design_code((4, 4)).code
    effects = parse_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}}) if args.noise else None
    ours, fixed = {}, {}  # scene -> (PSNR, MSE); (tensor, n) -> scene -> (PSNR, MSE)
    print(f"K = 16, 96x128, 6 frames, seed {args.seed}, "
          + (f"photon + read noise, {args.electrons:g} e-/unit" if args.noise else "no noise")
          + (f", motion-aware refine {args.refine:g}" if args.refine is not None else "")
          + (", motion-aware noise-blind" if args.no_noise_aware else ""))
    print("| scene | motion-aware dB | its own best fixed tensor and time | dB | margin |")
    print("|---|---|---|---|---|")
    for scene in SCENES:
        truth = render_scene(scene, 6 * 16, 96, 128, seed=args.seed)
        if effects is None:
            frames = capture(truth, code)
        else:
            res = simulate_video(truth, code, effects=effects, seed=args.seed, electrons_per_unit=args.electrons)
            frames = np.asarray(res.frames, np.float32)
        kw = {} if args.refine is None else {"refine_time": args.refine}
        if args.no_noise_aware:
            kw["noise_aware"] = False
        ours[scene] = _score(truth, motion_aware(frames, code, **kw).video)
        for name, tensor in TENSORS.items():
            for n in TIMES_FULL:
                fixed.setdefault((name, n), {})[scene] = _score(truth, diffuse(frames, code, tensor=tensor, time=n))
        own = max(fixed, key=lambda k: fixed[k][scene][0])
        print(f"| {scene} | {ours[scene][0]:.2f} | {own[0]} n = {own[1]:g} | {fixed[own][scene][0]:.2f} | "
              f"{ours[scene][0] - fixed[own][scene][0]:+.2f} |", flush=True)
    for label, scenes in (("fan, balls, drummer", SCENES[:3]), ("all four", SCENES)):
        for pooling, pool in (("mean of PSNR", _mean_psnr), ("PSNR of mean MSE", _pooled_mse)):
            best = max(fixed, key=lambda k: pool([fixed[k][s] for s in scenes]))
            a, b = pool([ours[s] for s in scenes]), pool([fixed[best][s] for s in scenes])
            print(f"{label}, {pooling}: motion-aware {a:.2f} dB; best fixed {best[0]} n = {best[1]:g}: "
                  f"{b:.2f} dB; margin {a - b:+.3f} dB ({(a - b) / 2.0:.2f}x the +2.0 dB aimed for)")


def _score(truth: np.ndarray, video: np.ndarray) -> tuple[float, float]:
    """(mean PSNR over sub-frames, mean squared error) of a reconstruction clipped to [0, 1]."""
    video = np.clip(video, 0, 1)
    return float(psnr(truth, video)), float(np.mean((truth.astype(np.float64) - video) ** 2))


def _mean_psnr(scores) -> float:
    return float(np.mean([p for p, _ in scores]))


def _pooled_mse(scores) -> float:
    return float(10 * np.log10(1 / np.mean([m for _, m in scores])))


if __name__ == "__main__":
    main()
