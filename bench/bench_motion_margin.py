"""Motion-aware against the best fixed-tensor diffusion on the moving built-in scenes, with or without noise.

The motion-aware issue's accuracy target: on the moving built-in scenes at K = 16 (fan, balls,
drummer, pan; 96×128, 6 frames, 4×4 code), motion-aware PSNR at least 1.5 dB above the best
fixed-tensor diffusion — every tensor family and time of ``flexvox bench``, the one with the best
mean chosen after the fact — with and without noise effects. ``--noise`` adds photon noise and
read noise (σ = 3 e⁻) at ``--electrons`` e⁻ per unit of intensity; ``--seed`` renders the scenes
(and draws the noise) with another seed. Figures only, never pass/fail. Usage:
``python bench/bench_motion_margin.py [--noise] [--electrons E] [--seed S]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from app.accuracy_bench import TENSORS, TIMES_FULL
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
    args = ap.parse_args()
    code = design_code((4, 4)).code
    effects = parse_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}}) if args.noise else None
    ours, fixed = [], {}
    print(f"K = 16, 96x128, 6 frames, seed {args.seed}, "
          + (f"photon + read noise, {args.electrons:g} e-/unit" if args.noise else "no noise"))
    print("| scene | motion-aware dB | best fixed here dB |")
    print("|---|---|---|")
    for scene in SCENES:
        truth = render_scene(scene, 6 * 16, 96, 128, seed=args.seed)
        if effects is None:
            frames = capture(truth, code)
        else:
            res = simulate_video(truth, code, effects=effects, seed=args.seed, electrons_per_unit=args.electrons)
            frames = np.asarray(res.frames, np.float32)
        ours.append(psnr(truth, np.clip(motion_aware(frames, code).video, 0, 1)).mean)
        for name, tensor in TENSORS.items():
            for n in TIMES_FULL:
                video = np.clip(diffuse(frames, code, tensor=tensor, time=n), 0, 1)
                fixed.setdefault((name, n), []).append(psnr(truth, video).mean)
        print(f"| {scene} | {ours[-1]:.2f} | {max(v[-1] for v in fixed.values()):.2f} |", flush=True)
    best = max(fixed, key=lambda k: np.mean(fixed[k]))
    print(f"mean: motion-aware {np.mean(ours):.2f} dB; best fixed tensor {best[0]} n = {best[1]:g}: "
          f"{np.mean(fixed[best]):.2f} dB; margin {np.mean(ours) - np.mean(fixed[best]):+.2f} dB (target +1.5)")


if __name__ == "__main__":
    main()
