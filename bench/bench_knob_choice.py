"""A knob chosen by the estimate (:func:`flexvox_core.choice.choose`): what it picks against what the truth would
pick, and what choosing costs.

On the built-in moving scenes (4×4 designed code, K = 16, 64×96, 4 frames), clean and with photon and read noise
(1000 e⁻ per unit, 3 e⁻ read noise), diffusion's time n is chosen over :data:`~flexvox_core.choice.TIMES` from
the capture alone. Then, with the ground truth (read only after the choice), every candidate's true PSNR: per
run the chosen n, its estimate and truth, the truly best n and its truth, the loss (best truth − chosen truth),
and the seconds of the choice against one reconstruction at the chosen n (warm). Last, the totals: runs whose
choice is the truly best, within 1 dB of it, and the cost's range.

Figures only, never pass/fail. Usage: ``python bench/bench_knob_choice.py [--quick] [--size HxW] [--frames F]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexvox_core.accuracy import NoiseModel
from flexvox_core.choice import TIMES, choose
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method, run
from flexvox_core.metrics import psnr
from flexvox_core.simulate import render_scene, simulate_video

NOISE = {"photon_noise": {}, "read_noise": {"sigma": 3.0}}


def cases(quick: bool, size: tuple[int, int] | None = None, frames: int = 4):
    """(name, truth, frames, code, noise model) of every run."""
    H, W, F = (48, 64, frames) if quick else (64, 96, frames)
    if size is not None:
        H, W = size
    code = design_code((4, 4)).code
    out = []
    for scene in ("balls", "fan") if quick else ("balls", "fan", "drummer", "pan"):
        truth = render_scene(scene, F * 16, H, W, seed=0)
        out.append((f"{scene} clean", truth, capture(truth, code), code, NoiseModel()))
        sim = simulate_video(truth, code, effects=NOISE, seed=1)
        out.append((f"{scene} noisy", truth, sim.frames, code, NoiseModel.from_effects(NOISE)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two scenes, smaller frames")
    ap.add_argument("--size", help="HxW of the frames (default 64x96; 48x64 with --quick)")
    ap.add_argument("--frames", type=int, default=4, help="camera frames (default 4)")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.lower().split("x")) if args.size else None
    runs = cases(args.quick, size, args.frames)
    _, _, frames0, code0, _ = runs[0]
    run(frames0, code0, Method("diffusion"), chunk_frames=None)  # compile once: no run below pays for it
    print(f"candidates: n = {', '.join(f'{t:g}' for t in TIMES)} (diffusion nc, default tensor)")
    print(f"{'case':14s} {'chosen':>6s} {'estimate':>8s} {'truth':>6s} {'best n':>6s} {'best':>6s} {'loss':>5s} "
          f"{'choose s':>8s} {'1 run s':>7s} {'ratio':>5s}")
    exact = within = 0
    ratios = []
    for name, truth, frames, code, noise in runs:
        t0 = time.perf_counter()
        choice = choose(frames, code, Method("diffusion"), "time", noise=noise, chunk_frames=None, keep_video=False)
        t_choose = time.perf_counter() - t0
        t0 = time.perf_counter()
        run(frames, code, choice.method, chunk_frames=None)
        t_one = time.perf_counter() - t0
        true = {t: float(psnr(truth, run(frames, code, Method("diffusion", time=t), chunk_frames=None).video))
                for t in TIMES}  # the truth, only now
        best = max(true, key=lambda t: true[t])
        loss = true[best] - true[choice.value]
        exact += best == choice.value
        within += loss <= 1.0
        ratios.append(t_choose / t_one)
        print(f"{name:14s} {choice.value:6g} {choice.estimate.psnr:8.2f} {true[choice.value]:6.2f} {best:6g} "
              f"{true[best]:6.2f} {loss:5.2f} {t_choose:8.2f} {t_one:7.3f} {t_choose / t_one:5.1f}")
        print(f"{'':14s} truths: " + ", ".join(f"n={t:g} {true[t]:.2f}" for t in TIMES)
              + "; estimates: " + ", ".join(f"{c.estimate.psnr:.2f}" if c.estimate else "none"
                                            for c in choice.candidates))
    n = len(runs)
    print(f"\nchosen = truly best on {exact} of {n} runs; within 1 dB of it on {within} of {n}")
    print(f"choosing over {len(TIMES)} candidates cost {min(ratios):.1f}-{max(ratios):.1f}x one reconstruction "
          f"(median {float(np.median(ratios)):.1f}x)")


if __name__ == "__main__":
    main()
