"""``flexvox demo``: the end-to-end story on the simulated rig.

This is the foundation-stage demo: it designs a 4×4 code, makes a small synthetic
high-speed scene, runs the forward model and checks that every division can be re-binned
from the capture. Simulation effects, calibration, capture and reconstruction join it as
those parts land (README, "Status").
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from app.cli.errors import EXIT_OK
from flexvox_core.codes import verify
from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume

HELP = "run the end-to-end demo on the simulated rig"


def register(sub) -> None:
    """Add the ``demo`` subcommand."""
    p = sub.add_parser("demo", help=HELP, description=__doc__.split("\n\n")[1])
    p.add_argument("--out", type=Path, default=Path("flexvox-demo"), metavar="DIR",
                   help="where the report goes (default: flexvox-demo/)")
    p.add_argument("--quick", action="store_true", help="a smaller scene")
    p.set_defaults(func=run)


def _scene(S: int, H: int, W: int, rng: np.random.Generator) -> np.ndarray:
    """A fine static texture with a bright square crossing it at 1 px per sub-frame."""
    wall = rng.random((H, W)).astype(np.float32) * 0.5 + 0.25
    video = np.repeat(wall[None], S, axis=0)
    for s in range(S):
        x0 = (4 + s) % (W - 8)
        video[s, H // 2 - 4: H // 2 + 4, x0: x0 + 8] = 0.95
    return video


def run(args) -> int:
    """Carry out ``flexvox demo``."""
    H, W, F = (32, 48, 2) if args.quick else (64, 96, 4)
    t0 = time.perf_counter()
    design = design_code((4, 4))
    print(f"1. designed a 4x4 code: {design.message}")
    print("   firing order: " + " / ".join(" ".join(map(str, row)) for row in design.order))
    video = _scene(F * design.K, H, W, np.random.default_rng(0))
    frames = capture(video, design.code)
    print(f"2. simulated {video.shape[0]} sub-frames of a {H}x{W} scene (a square crossing "
          f"a textured wall) and captured {frames.shape[0]} coded frames (ideal forward model)")
    mask = sample_mask(video.shape, design.code)
    placed = sparse_volume(frames, design.code)
    assert np.array_equal(placed[mask], video[mask])
    print(f"3. every captured value is its sampled voxel ({int(mask.sum())} samples = "
          f"{mask.mean():.2%} of the volume, 1/K)")
    check = verify(design.code)
    print(f"4. {check.message}: " + ", ".join(f"[{d.tr}, {d.sr}]" for d in check.supported))
    print(f"done in {time.perf_counter() - t0:.2f} s. Not in this demo yet: scene effects, "
          "calibration, capture, reconstruction and the HTML report (they arrive with "
          f"their issues; nothing was written to {args.out}).")
    return EXIT_OK
