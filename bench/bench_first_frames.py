"""First-frames benchmark: does a capture keep the camera's first frames, idle and under load?

``flexvox capture --rig mock --size 480x640`` once lost frames 1–38: the simulated camera warped the
patterns into camera pixels at its first exposure (about 1 s at VGA) on a clock that had stood still
through the rig's set-up. This runs the capture path ``flexvox capture`` runs
(:class:`~flexvox_app.capture.CaptureService` on the simulated rig, on a
:class:`~flexvox_app.capture.pacing.PacedClock`: real time at the camera rate) with

* ``stand-in``: a camera whose frames cost nothing to render (one blank frame, handed out again), so
  whatever is lost is the capture path's own start (a real camera would lose it too);
* ``simulated``: the simulated camera as ``flexvox capture`` uses it.

For each it prints the set-up's time (before the first trigger), the time from then to the first
frame, the frame ids the camera lost among the first frames and the drops in all. ``--load N``
runs N busy loops in other processes meanwhile.

    .venv/bin/python bench/bench_first_frames.py [--frames 100] [--rate 15] [--size 480x640] [--load 0]
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexvox_app.capture import CapturePlan, CaptureService  # noqa: E402
from flexvox_app.capture.pacing import PacedClock  # noqa: E402
from flexvox_calibration.capture_setup import CaptureCalibration  # noqa: E402
from rig_drivers.simulated_rig import SimulatedRig  # noqa: E402

FIRST = 40
"""How many of the first frames the report looks at."""


def _busy(stop) -> None:
    x = 0
    while not stop.is_set():
        for _ in range(100_000):
            x += 1


def run(camera: str, frames: int, rate: float, size: tuple[int, int]) -> dict:
    """One capture of ``frames`` frames; what the camera lost among the first :data:`FIRST` and in all."""
    clock = PacedClock()
    rig = SimulatedRig.create("balls", camera_size=size, subframes=64, clock=clock)
    if camera == "stand-in":
        blank = np.zeros(size, np.uint16)
        rig.camera._render = lambda *_: blank  # costs nothing: the capture path is all that is timed
    plan = CapturePlan(tile=(4, 4), camera_hz=rate)
    with tempfile.TemporaryDirectory() as tmp:
        svc = CaptureService(rig, plan, Path(tmp) / "first.zarr", frames=frames, calibration=CaptureCalibration())
        t0 = time.perf_counter()
        svc.start()  # the rig's set-up: the camera opens (renders the scene) and warms up, the projector starts
        t1 = time.perf_counter()
        while svc.latest()[0] is None and not svc.wait(0.001):
            pass
        first_s, start_s = time.perf_counter() - t1, t1 - t0
        svc.wait(frames / rate * 10 + 30)
        result = svc.stop()
        lost = sorted(rig.camera.dropped_ids)
    rig.close()
    return {"lost_first": [i for i in lost if i < FIRST], "lost": len(lost), "first_s": first_s, "start_s": start_s,
            "queue_drops": result.stats.queue_drops if result is not None else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--rate", type=float, default=15.0, help="camera rate in Hz (default 15)")
    ap.add_argument("--size", default="480x640")
    ap.add_argument("--load", type=int, default=0, help="busy loops in other processes (default 0)")
    ap.add_argument("--camera", choices=("stand-in", "simulated", "both"), default="both")
    args = ap.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    stop = multiprocessing.Event()
    loops = [multiprocessing.Process(target=_busy, args=(stop,), daemon=True) for _ in range(args.load)]
    for p in loops:
        p.start()
    try:
        cameras = ("stand-in", "simulated") if args.camera == "both" else (args.camera,)
        print(f"{size[0]}x{size[1]} at {args.rate:g} Hz, {args.frames} frames, {args.load} busy loop(s)")
        for camera in cameras:
            r = run(camera, args.frames, args.rate, size)
            lost_first = ", ".join(map(str, r["lost_first"])) or "none"
            print(f"  {camera:9s}: set-up {r['start_s']:.2f} s, first frame {r['first_s']:.3f} s after; lost among "
                  f"the first {FIRST}: "
                  f"{lost_first}; lost in all {r['lost']}, {r['queue_drops']} by the queue")
    finally:
        stop.set()
        for p in loops:
            p.join(5)


if __name__ == "__main__":
    main()
