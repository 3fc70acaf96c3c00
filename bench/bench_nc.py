"""Normalized-convolution speed at 640×480, K = 16, and what plain diffusion scores on Runner/Drop.

1. ``diffuse(..., solver="nc")`` on F camera frames of a random 640×480 capture with the
   designed 4×4 code: M voxels/s, and the ratio to the naive float64
   ``scipy.ndimage.gaussian_filter`` normalized convolution (``nc_naive``, the tests' reference) timed in the
   same run, and the ratio to 74 M voxels/s (640×480 at 15 Hz with K = 16, a live VGA stream).
2. On Runner and Drop (SCI benchmark, frames 0–7) with the 2×4 code: isotropic nc, a small
   tensor × time sweep (best shown), the explicit and steady solvers, and re-binning, beside
   GAP-TV's reference figures. Skipped when the data are absent.

Figures only, never pass/fail. Usage, from the repository root (the reference is the tests'):
``python -m bench.bench_nc [F]`` (default F = 4).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bench.bench_gaptv_sci import REFERENCE, SCENES, data_dir, load
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr, ssim
from flexvox_core.reconstruct import diffuse, rebin, supported_divisions
from tests.flexvox_core.reconstruct.nc_reference import nc_naive

LIVE_VGA = 640 * 480 * 15 * 16
"""Voxels per second of a live 640×480 stream at 15 Hz with K = 16."""


def best_of(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def speed(F: int) -> None:
    import cv2

    code = design_code((4, 4)).code
    rng = np.random.default_rng(0)
    frames = rng.random((F, 480, 640), dtype=np.float32)
    voxels = F * 16 * 480 * 640
    print(f"nc speed: 640x480, K=16, F={F} ({voxels / 1e6:.1f} M voxels), cv2 threads {cv2.getNumThreads()}")
    for tensor, t in (((1, 1, 1), 0.25), ((1, 1, 1), 2.0), ((0.95, 0.05, 0.05), 4.0)):
        fast = best_of(lambda tensor=tensor, t=t: diffuse(frames, code, tensor=tensor, time=t), 3)
        naive = best_of(lambda tensor=tensor, t=t: nc_naive(frames, code, tensor=tensor, time=t), 1)
        print(f"  tensor {tensor!s:18s} time {t:4.2f}: fast {fast * 1e3:7.1f} ms"
              f" = {voxels / fast / 1e6:6.1f} M voxels/s | naive scipy {naive * 1e3:7.1f} ms"
              f" = {voxels / naive / 1e6:5.1f} M voxels/s | ratio {naive / fast:5.1f}x"
              f" | {voxels / fast / LIVE_VGA:4.2f}x a live 640x480 stream at 15 Hz, K = 16 (74 M voxels/s)")


def quality() -> None:
    root = data_dir()
    if root is None:
        print("SKIP quality: no sci_benchmark data (set FLEXVOX_DATA or provide ../shared/data)")
        return
    code = design_code((2, 4)).code
    tensors = [(1, 1, 1), (1, 1, 0.5), (1, 1, 2), (1, 1, 0.25), (1, 1, 4), (0, 0, 1), (1, 1, 0)]
    times = [0.1, 0.15, 0.25, 0.5, 1.0, 2.0]
    print("\nRunner/Drop, 2x4 code (frames 0-7): PSNR dB / SSIM / ms")
    for scene in SCENES:
        gt, _ = load(root, scene)
        frames = capture(gt, code)
        rows = []
        for tensor in tensors:
            for t in times:
                t0 = time.perf_counter()
                out = diffuse(frames, code, tensor=tensor, time=t)
                rows.append((psnr(gt, out), tensor, t, time.perf_counter() - t0, out))
        iso = [r for r in rows if r[1] == (1, 1, 1)]
        print(f"  {scene}: isotropic nc by time: "
              + ", ".join(f"n={r[2]}: {r[0]:.2f}" for r in iso))
        best = max(rows, key=lambda r: r[0])
        print(f"  {scene}: best of sweep: tensor {best[1]} time {best[2]}: {best[0]:.2f} dB,"
              f" SSIM {ssim(gt, best[4]):.3f}, {best[3] * 1e3:.0f} ms"
              f" (GAP-TV reference {REFERENCE[(scene, '2x4')]:.1f} dB)")
        for solver in ("explicit", "steady"):
            t0 = time.perf_counter()
            out = diffuse(frames, code, tensor=(1, 1, 1), time=best[2] if best[1] == (1, 1, 1) else 0.25,
                          solver=solver)
            ms = (time.perf_counter() - t0) * 1e3
            print(f"  {scene}: {solver:8s} (1,1,1): {psnr(gt, out):.2f} dB, {ms:.0f} ms")
        for d in supported_divisions(code):
            for interp in (False, True):
                out = rebin(frames, code, d, interpolate=interp)
                print(f"  {scene}: rebin {d.label} [TR {d.tr}, SR {d.sr}]{' interp' if interp else '       '}:"
                      f" {psnr(gt, out):.2f} dB")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("frames", nargs="?", type=int, default=4, metavar="F", help="camera frames timed (default 4)")
    speed(ap.parse_args().frames)
    quality()
    return 0


if __name__ == "__main__":
    sys.exit(main())
