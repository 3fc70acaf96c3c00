"""The local choice's bias on single-frame captures of still subjects: the gather alone, and with each candidate.

A sample's leave-one-out estimate leaves its pixel without its own sample. Where a pixel is still and
sampled once within the trajectory gather's reach (one camera frame of a still subject), the gather
leans on exactly that sample at the pixel's other voxels, so leave-one-out overestimates the gather's
error and the local choice blends in too much of the candidate (docs/reconstruction.md, "The local
choice"). This prints, for still single-frame captures at K = 8 (2×4 code) and K = 16 (4×4), the PSNR
(mean over sub-frames) of motion-aware with ``local_choice=False`` (the gather alone), with isotropic nc
as the candidate (oriented nc given a guide without edges: the same kernel) and with oriented nc (the
default). Captures: a still bright square turned by 0.5 rad, 64×48, on a flat ground and on a ground with
a slow vertical ripple; the built-in ``static`` scene's first sub-frame, 128×96; and, when the SCI
benchmark data is present (``$FLEXVOX_DATA/sci_benchmark``), the first sub-frame of Runner and of Drop
held still. Figures only, never pass/fail. Usage: ``python bench/bench_choice_bias.py [--quick]`` (about a
minute; ``--quick``: K = 8 and the plain square only, a few seconds). The isotropic candidate replaces
``flexvox_core.motion.stages.OrientedNc``, the name the CPU stages call (the run is on the CPU).
"""

from __future__ import annotations

import argparse

import numpy as np

import flexvox_core.motion.stages as stages
from flexvox_app.accuracy_bench import sci_data_dir
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.reconstruct.oriented_nc import OrientedNc
from flexvox_core.simulate.scenes import render_scene

ORIENTED = stages.OrientedNc
"""The candidate the CPU stages call, read at import: a renamed or moved name fails here, under ``--help`` too."""


def square(S: int, H: int, W: int, *, ripple: bool) -> np.ndarray:
    """A still square (0.75 on 0.25), 28×20 px turned by 0.5 rad, optionally on a slow vertical ripple."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    u = (x - W / 2) * np.cos(0.5) + (y - H / 2) * np.sin(0.5)
    v = -(x - W / 2) * np.sin(0.5) + (y - H / 2) * np.cos(0.5)
    img = 0.25 + 0.5 * ((np.abs(u) < 14) & (np.abs(v) < 10)) + (0.1 * np.sin(y / 9.0) if ripple else 0.0)
    return np.broadcast_to(img, (S, H, W)).astype(np.float32).copy()


def clips(K: int, quick: bool = False) -> dict[str, np.ndarray]:
    if quick:
        return {"square": square(K, 48, 64, ripple=False)}
    out = {"square on a ripple": square(K, 48, 64, ripple=True), "square": square(K, 48, 64, ripple=False),
           "static (built-in)": np.repeat(render_scene("static", 1, 96, 128, seed=0), K, axis=0)}
    folder = sci_data_dir()
    if folder is not None:
        from flexvox_core.simulate.sources import load_video

        for name in ("runner", "drop"):
            out[f"{name} (SCI) held still"] = np.repeat(load_video(folder / f"{name}40_cacti.mat")[:1], K, axis=0)
    return out


class Isotropic(OrientedNc):
    """The local choice's candidate before oriented nc: the same kernel with a guide without edges."""

    def __init__(self, frames, code, guide, **kw) -> None:
        super().__init__(frames, code, np.zeros_like(guide), **kw)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="K = 8 and the plain square only (a few seconds)")
    args = ap.parse_args()
    print("| K | still subject, one frame | gather alone dB | isotropic candidate dB | oriented (default) dB |")
    print("|---|---|---|---|---|")
    oriented = ORIENTED
    for tile in ((2, 4),) if args.quick else ((2, 4), (4, 4)):
        code = design_code(tile).code
        K = code.shape[2]
        for name, truth in clips(K, args.quick).items():
            frames = capture(truth, code)
            alone = psnr(truth, motion_aware(frames, code, local_choice=False, device="cpu").video)
            default = psnr(truth, motion_aware(frames, code, device="cpu").video)
            stages.OrientedNc = Isotropic  # type: ignore[misc]
            try:
                iso = psnr(truth, motion_aware(frames, code, device="cpu").video)
            finally:
                stages.OrientedNc = oriented  # type: ignore[misc]
            print(f"| {K} | {name} | {alone:.2f} | {iso:.2f} | {default:.2f} |", flush=True)


if __name__ == "__main__":
    main()
