"""Capture benchmark: N frames from the simulated rig at the rig's rate, streamed to a recording.

The rig is the one ``--rig mock`` opens (a projector twice as fine as the camera behind a hidden
homography, a sub-slot trigger offset), captured through a calibration made of its hidden truth,
so the projector runs the same patterns and the camera the same trigger delay as after calibration.

Prints frames, drops, the write rate reached against the camera rate, the queue's peak depth
and the writer's capacity (rows per second of time spent writing). The simulated rig runs on
a :class:`~flexvox_app.capture.pacing.PacedClock` (real time at the set camera rate); ``--virtual``
runs it on a virtual clock instead (frames as fast as they render: the pipeline's ceiling).

    .venv/bin/python bench/bench_capture.py [--frames 2000] [--rate 60] [--size 120x160] [--tile 4x4]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexvox_app.capture import CapturePlan, CaptureService  # noqa: E402
from flexvox_app.capture.pacing import PacedClock  # noqa: E402
from flexvox_calibration.capture_setup import CaptureCalibration, SyncTiming  # noqa: E402
from flexvox_core.recording import open_recording  # noqa: E402
from rig_drivers.simulated_camera import VirtualClock  # noqa: E402
from rig_drivers.simulated_rig import SimulatedRig  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--rate", type=float, default=60.0, help="camera rate in Hz (default 60)")
    ap.add_argument("--size", default="120x160")
    ap.add_argument("--tile", default="4x4")
    ap.add_argument("--virtual", action="store_true", help="virtual clock: as fast as frames render")
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.split("x"))
    m, n = (int(v) for v in args.tile.split("x"))
    plan = CapturePlan(tile=(m, n), camera_hz=args.rate)
    code = plan.code
    clock = VirtualClock() if args.virtual else PacedClock()
    rig = SimulatedRig.create("drummer", camera_size=(H, W), subframes=64, clock=clock)
    t = rig.truth  # what calibration finds (see tests/app/capture/test_one_chain.py), in slots of this plan
    offset = t.phase_slots + t.delay_us / plan.period_us
    phase, frac = int(offset) % plan.K, offset - int(offset)
    sync = SyncTiming((phase + 1) % plan.K, (1 - frac) * plan.period_us, plan.K, plan.period_us, phase)
    calibration = CaptureCalibration(t.homography, sync, "the simulated rig's truth", calibrated=True)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.zarr"
        svc = CaptureService(rig, plan, path, frames=args.frames, calibration=calibration)
        if not args.virtual:
            clock.resync()  # rendering the scene took wall time the camera must not count as overrun
        result = svc.run()
        s = result.stats
        rec = open_recording(path)
        set_hz = 1 / svc.frame_period_s
        print(f"simulated rig {H}x{W}, K = {code.shape[2]}, {'virtual clock' if args.virtual else 'paced real clock'}")
        print(f"frames: {s.rows_written} rows ({s.frames_received} received), in recording {rec.n_frames}")
        print(f"drops: {s.drops} ({s.queue_drops} by the queue); queue peak {s.max_queue_depth}/{s.queue_capacity}")
        print(f"camera rate: set {set_hz:.2f} Hz, measured {s.camera_rate_hz:.2f} Hz")
        print(f"write rate reached: {s.write_rate_hz:.2f} Hz ({s.write_rate_hz / set_hz:.1%} of the set camera rate)")
        print(f"writer capacity: {s.writer_capacity_hz:.0f} frames/s ({s.writer_capacity_hz / set_hz:.1f}x the camera)")
        print(f"elapsed: {s.elapsed_s:.1f} s; {result.message}")


if __name__ == "__main__":
    main()
