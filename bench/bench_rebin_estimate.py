"""Re-binning's closed-form accuracy estimate: the compiled passes against the whole-volume numpy form they replaced.

On a capture of the built-in ``balls`` scene (4×4 code, K = 16, photon noise and read noise of σ = 3 e⁻),
:func:`flexvox_core.accuracy_rebin.rebin_error` (compiled, a voxel at a time, one camera frame held per thread) and
the numpy reference (``tests/flexvox_core/accuracy_rebin_reference.py``: every corner's blocks, weights and lags for
every voxel, about 250 bytes a voxel), alternating, after one untimed call of each. Printed per round: the wall
seconds and the peak of traced memory (``tracemalloc``: numpy's arrays) of each, their ratios, and how far the two
estimates lie apart. ``--no-reference`` times the compiled form alone (the reference needs about 19 GB on a 1-s
640×480 clip). Both fit the same variogram (SciPy's ``least_squares``, about 1.8 s whatever the size). Figures only,
never pass/fail. Usage: ``python -m bench.bench_rebin_estimate [--size HxW] [--frames F] [--rounds N]
[--no-reference]``.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from flexvox_core.accuracy import NoiseModel
from flexvox_core.accuracy_rebin import rebin_error
from flexvox_core.design import design_code
from flexvox_core.reconstruct.rebin import default_block
from flexvox_core.simulate import render_scene, simulate_video

NOISE = {"photon_noise": {}, "read_noise": {"sigma": 3}}
"""Photon noise and read noise of σ = 3 e⁻ (1000 e⁻ per unit, the simulator's default)."""


def _timed(fn, *args):
    """(result, wall seconds, peak traced MB) of ``fn(*args)``."""
    tracemalloc.start()
    start = time.perf_counter()
    out = fn(*args)
    seconds = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return out, seconds, peak


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", default="240x320", help="HxW of the capture (default 240x320)")
    ap.add_argument("--frames", type=int, default=4, help="camera frames (default 4)")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds after the untimed calls (default 2)")
    ap.add_argument("--no-reference", action="store_true", help="time the compiled form alone")
    args = ap.parse_args(argv)
    H, W = (int(v) for v in args.size.lower().split("x"))
    code = design_code((4, 4)).code
    sim = simulate_video(render_scene("balls", args.frames * 16, H, W, seed=0), code, effects=NOISE, seed=0)
    frames = np.asarray(sim.frames, np.float64)
    variance = NoiseModel.from_effects(NOISE).variance(frames)
    division = default_block(code)
    forms = {"compiled": rebin_error}
    if not args.no_reference:
        from tests.flexvox_core.accuracy_rebin_reference import rebin_error_reference

        forms["numpy reference"] = rebin_error_reference
    call = (frames, code, division, variance)
    for fn in forms.values():  # untimed: numba's compilation, first touches
        fn(*call)
    print(f"{H}x{W}, {args.frames} frames, K = 16 ({args.frames * 16 * H * W / 1e6:.1f} M voxels), division "
          f"{division.label}")
    print("| round | form | wall s | peak traced MB | estimate (MSE) |")
    print("|---|---|---|---|---|")
    rows: dict[str, list[tuple[float, float]]] = {name: [] for name in forms}
    results = {}
    for r in range(args.rounds):
        for name, fn in forms.items():
            out, seconds, peak = _timed(fn, *call)
            rows[name].append((seconds, peak))
            results[name] = out
            print(f"| {r + 1} | {name} | {seconds:.2f} | {peak:.0f} | {out.mse:.6g} |", flush=True)
    if len(forms) == 2:
        a, b = results["compiled"], results["numpy reference"]
        time_ratio = [x[0] / y[0] for x, y in zip(rows["compiled"], rows["numpy reference"], strict=True)]
        mem_ratio = [x[1] / y[1] for x, y in zip(rows["compiled"], rows["numpy reference"], strict=True)]
        print(f"compiled / reference: time {', '.join(f'{v:.2f}' for v in time_ratio)}; peak memory "
              f"{', '.join(f'{v:.3f}' for v in mem_ratio)}; MSE relative difference {abs(a.mse / b.mse - 1):.1e}; "
              f"per-frame estimates equal: {np.array_equal(a.per_frame, b.per_frame)}")


if __name__ == "__main__":
    main()
