"""Reconstruction across dropped frames: PSNR next to and inside a gap of 1, 2 and 5 frames.

For each built-in moving scene (96×128, K = 16, 12 camera frames) and each method, frames 5.. are
dropped (zero rows, as a recording keeps them) and the capture is reconstructed with them marked
missing (``flexvox_core.gaps``). Printed per run: PSNR of the frame just before the gap, of the gap's
sub-frames, and of the frame just after it; beside them, measured in the same run, the same frames
reconstructed from the capture without drops (``clean``), and the frame before the gap when the zero
row is taken for samples (``naive``: what reconstructing a recording with dropped frames used to mean
if the refusal were lifted). A gap longer than a method's reach is refused: "refused".

Figures only, never pass/fail. Usage: ``python bench/bench_gaps.py [SCENES] [--methods M,...]``
(default: balls,drummer; diffusion,motion-aware,rebin,gap-tv).
"""

from __future__ import annotations

import argparse

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.gaps import GapTooLongError
from flexvox_core.methods import Method, run
from flexvox_core.metrics import psnr
from flexvox_core.simulate.scenes import render_scene

F, K, FIRST = 12, 16, 5


def _p(truth, video, frames) -> float:
    sl = slice(frames[0] * K, frames[-1] * K + K)
    return float(psnr(truth[sl], video[sl]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="?", default="balls,drummer")
    ap.add_argument("--methods", default="diffusion,motion-aware,rebin,gap-tv")
    args = ap.parse_args()
    code = design_code((4, 4)).code
    print(f"96x128, K = {K}, {F} frames, gap from frame {FIRST}; PSNR dB of the frame before the gap / the gap / "
          "the frame after")
    print("| scene | method | gap | before | gap frames | after | clean: before / gap / after | naive before |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        truth = render_scene(scene, F * K, 96, 128)
        frames = capture(truth, code)
        for name in args.methods.split(","):
            method = Method(name)
            clean = run(frames, code, method).video
            for n in (1, 2, 5):
                gap = list(range(FIRST, FIRST + n))
                before, after = [FIRST - 1], [FIRST + n]
                missing = np.zeros(F, bool)
                missing[gap] = True
                dropped = frames.copy()
                dropped[missing] = 0
                ref = (f"{_p(truth, clean, before):.2f} / {_p(truth, clean, gap):.2f} / "
                       f"{_p(truth, clean, after):.2f}")
                naive = _p(truth, run(dropped, code, method).video, before)
                try:
                    video = run(dropped, code, method, missing=missing).video
                except GapTooLongError:
                    print(f"| {scene} | {name} | {n} | refused | | | {ref} | {naive:.2f} |", flush=True)
                    continue
                assert np.isfinite(video).all()
                print(f"| {scene} | {name} | {n} | {_p(truth, video, before):.2f} | {_p(truth, video, gap):.2f} "
                      f"| {_p(truth, video, after):.2f} | {ref} | {naive:.2f} |", flush=True)


if __name__ == "__main__":
    main()
