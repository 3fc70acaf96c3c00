"""The LightCrafter 4500's diamond pixels against the shutter: what ignoring the stagger costs.

The DLP4500 DMD takes 912 × 1140 input pixels on rows staggered by half a pixel every other row,
at half the column pitch (:mod:`rig_drivers.pixel_layout`). This benchmark projects a 4×4 code's
shutter patterns through a rig whose homography is known exactly (no calibration error), with
the projector's 912 columns over 95 % of the camera's width, and measures, for camera pixels
inside the projected frame:

* **slot accuracy**: the share of camera pixels whose brightest slot is their own code slot;
* **own-slot light**: the mean share of a pixel's light that arrives in its own slot (the rest
  is crosstalk from neighbouring mirrors);
* **addressable**: the share of camera pixels that hold at least one mirror centre.

for a square DMD (the reference), for the diamond DMD with patterns that ignore the stagger, and
for the diamond DMD with patterns built in mirror coordinates (``layout="diamond"``), at a
640×480 and a 1280×1024 camera. Nothing passes or fails.

    .venv/bin/python bench/bench_pixel_layout.py [--supersample 4] [--calibrate]

``--calibrate`` also runs the whole calibration (co-location, homography, shutter check, sync) on the
simulated rig at the real ratio (the 912×1140 DMD, a 640×480 camera) for a square DMD, a diamond DMD
calibrated as if square, and a diamond DMD calibrated with its layout, and prints the homography
error against the rig's hidden truth, the RMS residual, and the shutter's slot accuracy and crosstalk
(minutes).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexvox_calibration.shutter import make_shutter_patterns  # noqa: E402
from flexvox_core.design import design_code  # noqa: E402
from flexvox_core.forward import tiled_code  # noqa: E402
from rig_drivers.simulated_rig import warp_patterns  # noqa: E402

DMD = (1140, 912)  # rows x columns of the LightCrafter 4500's input


def rig_homography(camera_size) -> np.ndarray:
    """Mirror coordinates → camera: 912 columns over 95 % of the width, rows at half the pitch, centred,
    with a slight rotation so that nothing falls on exact pixel boundaries."""
    H, W = camera_size
    sx = 0.95 * W / DMD[1]
    a = np.deg2rad(0.7)
    lin = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ np.diag([sx, sx / 2])
    centre_proj = np.array([(DMD[1] - 1) / 2, (DMD[0] - 1) / 2])
    t = np.array([(W - 1) / 2, (H - 1) / 2]) - lin @ centre_proj
    return np.array([[*lin[0], t[0]], [*lin[1], t[1]], [0, 0, 1.0]])


def measure(camera_size, model: str, rig: str, supersample: int) -> dict:
    code = design_code((4, 4)).code
    h = rig_homography(camera_size)
    shutter = make_shutter_patterns(code, h, camera_size, DMD, layout=model)
    light = warp_patterns(shutter.patterns, h, camera_size, layout=rig, supersample=supersample)
    own = np.argmax(tiled_code(code, *camera_size), axis=0)
    total = light.sum(axis=0)
    inner = np.zeros(camera_size, bool)
    m = max(4, camera_size[0] // 40)
    inner[m:-m, m:-m] = True
    lit = inner & (total > 0.5)
    own_light = np.take_along_axis(light, own[None], 0)[0] / np.maximum(total, 1e-9)
    return {"accuracy": float((np.argmax(light, axis=0) == own)[lit].mean()),
            "own_light": float(own_light[lit].mean()), "addressable": shutter.addressable}


def calibrate(camera_size, rig_layout: str, model: str) -> dict:
    """The whole calibration of a simulated rig at the real ratio; figures against its truth."""
    from flexvox_calibration.geometry import homography_error_px
    from flexvox_calibration.pipeline import run_calibration
    from flexvox_calibration.session import RigSession
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="static", camera_size=camera_size, projector_size=DMD,
                   homography=rig_homography(camera_size), seed=0, subframes=16, pixel_layout=rig_layout,
                   clock=VirtualClock())
    session = RigSession.from_rig(rig)
    session.pixel_layout = model
    run = run_calibration(rig, session, tile=(4, 4))
    hom = run.keep.get("homography")
    shutter = run.report.get("shutter", {})
    return {"error_px": homography_error_px(hom.homography, rig.simulated.truth.homography, camera_size)
            if hom is not None and hom.homography is not None else float("nan"),
            "rms_px": hom.rms_px if hom is not None else float("nan"),
            "accuracy": shutter.get("accuracy", float("nan")), "crosstalk": shutter.get("crosstalk", float("nan")),
            "failed": run.report.get("failed")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--supersample", type=int, default=4)
    ap.add_argument("--calibrate", action="store_true", help="also run the whole calibration at 640x480 (minutes)")
    args = ap.parse_args()
    cases = (("square DMD (reference)", "square", "square"), ("diamond, stagger ignored", "square", "diamond"),
             ("diamond, stagger modelled", "diamond", "diamond"))
    for camera in ((480, 640), (1024, 1280)):
        t0 = time.perf_counter()
        sx = rig_homography(camera)[0, 0]
        print(f"camera {camera[1]}x{camera[0]} against the 912x1140 DMD: {sx:.3f} camera px per mirror column")
        print(f"  {'':<28}{'slot accuracy':>14}{'own-slot light':>16}{'addressable':>13}")
        for label, model, rig in cases:
            r = measure(camera, model, rig, args.supersample)
            print(f"  {label:<28}{r['accuracy']:>14.1%}{r['own_light']:>16.1%}{r['addressable']:>13.1%}")
        print(f"  ({time.perf_counter() - t0:.0f} s)")
    if args.calibrate:
        camera = (480, 640)
        print(f"\nthe whole calibration, simulated rig with the 912x1140 DMD and a {camera[1]}x{camera[0]} camera:")
        print(f"  {'':<28}{'H error (px)':>13}{'RMS (px)':>10}{'slot accuracy':>15}{'crosstalk':>11}")
        for label, model, rig in cases:
            t0 = time.perf_counter()
            r = calibrate(camera, rig, model)
            line = f"  {label:<28}{r['error_px']:>13.3f}{r['rms_px']:>10.3f}{r['accuracy']:>15.1%}"
            print(line + f"{r['crosstalk']:>11.1%}" + (f"  (failed at {r['failed']})" if r["failed"] else "")
                  + f"  {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
