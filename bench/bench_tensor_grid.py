"""How good can a constant tensor be? Every axis-aligned tensor and time on a fine grid.

Only ``time · c`` enters the diffusion (Gaussian σᵢ = sqrt(2·n·cᵢ)), so with cx = cy the whole
family of constant tensors and times is the plane of (σs, σt): spatial and temporal standard
deviations in pixels and sub-frames. This script scores a fine grid of that plane on the
captures of ``flexvox bench`` (built-in scenes at K = 16 and K = 8, 96×128, 6 frames; SCI
Runner/Drop when the data is present) and prints:

* the five-scene score (PSNR of the mean squared error, as ``flexvox bench``) of every grid
  point at K = 16, the best grid point per group, the paper's high-SR tensor (0.05, 0.05, 1) at
  its best time of the bench's sweep and flexvox's default (0.15, 0.15, 1), n = 1.5;
* the per-scene oracle: each scene with its own best grid point (what a perfect per-clip
  selector could reach);
* with ``--cv``, a per-clip selector by cross-validation: a random 15 % of the samples held
  out, every grid point scored by how well the rest predict them, the best one applied to the
  whole capture.

Figures only, never pass/fail. Usage: ``python bench/bench_tensor_grid.py [--cv]``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.ndimage import gaussian_filter1d

from flexvox_app.accuracy_bench import TIMES_FULL, cases
from flexvox_core.forward import sample_mask, sparse_volume
from flexvox_core.reconstruct import diffuse
from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, TRUNCATE

SIGMA_S = (0.0, 0.25, 0.35, 0.5, 0.6, 0.7, 0.85, 1.0, 1.4, 2.0)
SIGMA_T = (0.0, 0.7, 1.0, 1.4, 2.0, 2.4, 2.8, 3.4, 4.0, 5.7, 8.0, 16.0)
HIGH_SR = (0.05, 0.05, 1.0)
HOLD_OUT = 0.15


def tensor_time(ss: float, st: float) -> tuple[tuple[float, float, float], float]:
    """The (tensor, time) with standard deviations (ss, ss, st); the largest entry 1."""
    m = max(ss, st)
    return (ss * ss / (m * m), ss * ss / (m * m), st * st / (m * m)), m * m / 2.0


def grid() -> list[tuple[float, float]]:
    return [(ss, st) for st in SIGMA_T for ss in SIGMA_S if max(ss, st) > 0]


def mse(case, tensor, n) -> float:
    video = diffuse(case.frames, case.code, tensor=tensor, time=n)
    return float(np.mean((case.truth.astype(np.float64) - video) ** 2))


def db(m: float) -> float:
    return 10.0 * math.log10(1.0 / max(m, 1e-20))


def cv_select(case, seed: int = 0) -> tuple[float, float]:
    """The grid point whose normalized convolution best predicts 15 % held-out samples."""
    vals = sparse_volume(case.frames, case.code).astype(np.float32)
    mask = sample_mask(vals.shape, case.code)
    held = mask & (np.random.default_rng(seed).random(mask.shape) < HOLD_OUT)
    train = (mask & ~held).astype(np.float32)
    target = vals[held]

    def blur(v, s, axes):
        for a in axes if s > 0 else ():
            v = gaussian_filter1d(v, s, axis=a, mode="reflect", truncate=TRUNCATE)
        return v

    best, best_err = None, math.inf
    for st in SIGMA_T:
        num_t, den_t = blur(vals * train, st, (0,)), blur(train, st, (0,))
        for ss in SIGMA_S:
            if max(ss, st) == 0:
                continue
            num, den = blur(num_t, ss, (1, 2))[held], blur(den_t, ss, (1, 2))[held]
            ok = den > 1e-6
            pred = np.where(ok, num / np.where(ok, den, 1.0), target.mean())
            err = float(np.mean((pred - target) ** 2))
            if err < best_err:
                best, best_err = (ss, st), err
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cv", action="store_true", help="also run the cross-validation per-clip selector")
    args = ap.parse_args()
    t0 = time.perf_counter()
    all_cases = cases(quick=False)
    points = grid()
    scores = {(c.name, p): mse(c, *tensor_time(*p)) for c in all_cases for p in points}
    fixed = {(c.name, "default"): mse(c, DEFAULT_TENSOR, DEFAULT_TIME) for c in all_cases}
    for n in TIMES_FULL:
        fixed.update({(c.name, f"high SR n={n:g}"): mse(c, HIGH_SR, n) for c in all_cases})
    groups = {"built-in K=16": [c for c in all_cases if c.K == 16],
              "built-in K=8": [c for c in all_cases if c.K == 8 and "SCI" not in c.name]}
    groups.update({c.name: [c] for c in all_cases if "SCI" in c.name})

    def group_db(table, group, key):
        return db(np.mean([table[(c.name, key)] for c in groups[group]]))

    k16 = groups["built-in K=16"]
    print("five-scene PSNR (dB) at K = 16 of every (σs px, σt sub-frames); '-' has no blur")
    print("σt \\ σs " + "".join(f"{ss:>7g}" for ss in SIGMA_S))
    for st in SIGMA_T:
        cells = [f"{db(np.mean([scores[(c.name, (ss, st))] for c in k16])):7.2f}" if max(ss, st) > 0 else "      -"
                 for ss in SIGMA_S]
        print(f"{st:>7g} " + "".join(cells))
    print()
    print(f"{'group':<18}{'best grid point':>28}{'high SR, best n':>20}{'default':>10}{'per-scene oracle':>19}"
          + (f"{'CV selector':>14}" if args.cv else ""))
    for group, members in groups.items():
        best = max(points, key=lambda p: group_db(scores, group, p))
        sr_n = max(TIMES_FULL, key=lambda n: group_db(fixed, group, f"high SR n={n:g}"))
        oracle = db(np.mean([min(scores[(c.name, p)] for p in points) for c in members]))
        best_txt = f"σ=({best[0]:g}, {best[1]:g}) {group_db(scores, group, best):.2f}"
        sr_txt = f"n={sr_n:g} " + format(group_db(fixed, group, f"high SR n={sr_n:g}"), ".2f")
        line = f"{group:<18}{best_txt:>28}{sr_txt:>20}{group_db(fixed, group, 'default'):>10.2f}{oracle:>19.2f}"
        if args.cv:
            picks = {c.name: cv_select(c) for c in members}
            line += f"{db(np.mean([scores[(c.name, picks[c.name])] for c in members])):>14.2f}"
            line += "  picks " + ", ".join(f"{name.split(' ')[0]} ({p[0]:g}, {p[1]:g})" for name, p in picks.items())
        print(line)
    print(f"\n{len(points)} grid points × {len(all_cases)} captures in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
