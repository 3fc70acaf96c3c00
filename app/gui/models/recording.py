"""Recording from the Capture workspace (Qt-free): build the capture service, say its counters and its end.

The Capture workspace records through :class:`app.capture.service.CaptureService`, the same
service ``flexvox capture`` drives. :func:`make_capture` builds one from the workspace's plan
and the :class:`~app.gui.models.rig_service.RigService`'s rig; :func:`counters_text` and
:func:`result_text` are the lines the workspace shows while and after it records.

Device ownership: while it records, the capture service owns the projector, camera and sync
box (its reader thread is the only one that reads the camera). The workspace therefore stops
its own live view first, and feeds its display from :meth:`CaptureService.latest` (the newest
frame only, a reference swap that never slows capture).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from app.capture.plan import CapturePlan
from app.capture.service import CaptureResult, CaptureService, CaptureStats, SyncSetting
from app.gui.models.live_source import put_scene_in_view
from app.gui.models.rig_service import RigService
from calibration.capture_setup import CaptureCalibration

_logger = logging.getLogger(__name__)

CaptureFactory = Callable[..., CaptureService]
"""``(rig, plan, path, **options) -> CaptureService``: tests inject slow or failing writers through it."""


def make_capture(service: RigService, plan: CapturePlan, path, *, frames: int | None = None,
                 overwrite: bool = False, durable: bool = False, ground_truth: bool = False,
                 calibration: CaptureCalibration | None = None, delay_set_by_hand: bool = False,
                 factory: CaptureFactory = CaptureService) -> CaptureService:
    """A capture service for ``plan`` on the rig of ``service``, writing ``path``.

    Parameters
    ----------
    service : RigService
    plan : CapturePlan
        Its code and camera rate are used (the service derives the exposures itself).
    path : str or Path
        The recording to create.
    frames : int or None
        Frames to record; None records until stopped.
    overwrite : bool
        Replace an existing recording (never one another capture is writing).
    durable : bool
        Flush every frame to the disk before the next (``flexvox capture --durable``).
    ground_truth : bool
        Simulated rig only: store the scene's high-speed video as the recording's ground truth.
    calibration : CaptureCalibration, optional
        Homography, phase and trigger delay (default uncalibrated).
    delay_set_by_hand : bool
        The operator confirmed the trigger delay is set on a camera that cannot be told it.
    factory : callable, optional
        Builds the service (default :class:`CaptureService`).

    Raises
    ------
    app.capture.service.CaptureError
        For a path that exists (without ``overwrite``), a folder that does not exist, a bad code.
    ValueError
        For a code the plan cannot make, or ground truth asked of a real rig.
    """
    path = Path(path)
    if ground_truth and service.rig.simulated is None:
        raise ValueError("ground truth exists only on the simulated rig")
    put_scene_in_view(service)
    return factory(service.rig, plan, path, frames=frames, calibration=calibration or CaptureCalibration(),
                   sync=SyncSetting(delay_set_by_hand=delay_set_by_hand), ground_truth=ground_truth,
                   overwrite=overwrite, durable=durable,
                   rig_info={"profile": "mock" if service.simulated else service.name, "source": "flexvox app"})


def counters_text(s: CaptureStats, target: int | None = None) -> str:
    """One line of counters: frames, drops, queue depth, write and camera rates."""
    of = f" of {target}" if target else ""
    return (f"{s.rows_written}{of} frames written ({s.frames_received} received) · "
            f"{s.drops} dropped ({s.queue_drops} by the queue) · queue {s.queue_depth}/{s.queue_capacity} "
            f"(max {s.max_queue_depth}) · write {s.write_rate_hz:.1f} Hz · camera {s.camera_rate_hz:.1f} Hz · "
            f"{s.elapsed_s:.1f} s")


def result_text(result: CaptureResult | None, path) -> str:
    """What the workspace says when a capture has ended (None: it did not stop in time)."""
    if result is None:
        return (f"the capture did not stop within the time allowed (the disk may hang); {path} keeps what was "
                "written — check it with `flexvox info`")
    if result.ok:
        return f"recording done: {result.message}"
    return f"recording failed: {result.message}"
