"""How near the live preview's region comes to what the recording's reconstruction shows there, at two flow scales.

For each built-in moving scene (4×4 code, K = 16) at 640×480: the last 3 frames, as the preview takes them; a centred
region of each ``--sides`` size reconstructed by motion-aware with the preview's options
(:func:`~flexvox_app.capture.live_preview.preview_options`) twice, its flow at the region's own scale
(:func:`~flexvox_core.motion.options.auto_flow_scale` of the region) and at the whole frame's (what the preview runs);
and the whole frame's reconstruction with the same options, cropped ("offline"). Printed per row: the middle frame's
PSNR against the truth of each, and of each region against the offline crop (how alike the pictures are), with the
region's CPU ms. Figures only, never pass/fail. Usage:
``python bench/bench_preview_fidelity.py [--scenes fan,balls,drummer,pan] [--sides 192,288]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexvox_app.capture.live_preview import preview_options
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.motion.options import auto_flow_scale
from flexvox_core.simulate.scenes import render_scene

H, W, FRAMES = 480, 640, 3


def _run(frames: np.ndarray, code: np.ndarray, options: dict) -> tuple[np.ndarray, float]:
    """The middle frame's K sub-frames, clipped to [0, 1], and the CPU seconds of the run."""
    K = code.shape[2]
    start = time.process_time()
    video = motion_aware(frames, code, sample_range=(0.0, 1.0), **options).video
    return np.clip(video[K:2 * K], 0.0, 1.0), time.process_time() - start


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="fan,balls,drummer,pan", help="built-in scenes, comma-separated")
    ap.add_argument("--sides", default="192,288", help="the square regions' sides in px, comma-separated")
    args = ap.parse_args(argv)
    code = design_code((4, 4)).code
    K = code.shape[2]
    preview = preview_options((H, W))
    own_scale = {k: v for k, v in preview.items() if k != "flow_scale"}
    print(f"640x480, the last {FRAMES} frames, the middle frame's PSNR (dB, the mean of its sub-frames') against the "
          f"truth; the preview's options {preview}")
    print("| scene | region | own scale | frame's scale | offline, cropped | own vs offline | frame's vs offline "
          "| CPU ms own / frame's |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        truth = render_scene(scene, (FRAMES + 2) * K, H, W).astype(np.float32)[-FRAMES * K:]
        frames = capture(truth, code)
        offline, _ = _run(frames, code, preview)
        for side in (int(s) for s in args.sides.split(",")):
            y0, x0 = (H - side) // 8 * 4, (W - side) // 8 * 4  # centred, on the code's grid
            cut = (slice(None), slice(y0, y0 + side), slice(x0, x0 + side))
            region = np.ascontiguousarray(frames[cut])
            ref = truth[K:2 * K][cut]
            _run(region, code, own_scale)  # numba's compilation out of the timings
            own, own_s = _run(region, code, own_scale)
            framed, framed_s = _run(region, code, preview)
            crop = offline[cut]
            print(f"| {scene} | {side} (own scale {auto_flow_scale(side, side):.2f}) "
                  f"| {psnr(ref, own):.2f} | {psnr(ref, framed):.2f} | {psnr(ref, crop):.2f} "
                  f"| {psnr(crop, own):.1f} | {psnr(crop, framed):.1f} "
                  f"| {own_s * 1000:.0f} / {framed_s * 1000:.0f} |", flush=True)


if __name__ == "__main__":
    main()
