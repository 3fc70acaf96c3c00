"""Recording from the Capture workspace (Qt-free): build the capture service, say its counters and its end.

The Capture workspace records through :class:`flexvox_app.capture.service.CaptureService`, the same
service ``flexvox capture`` drives. :func:`make_capture` builds one from the workspace's plan
and the :class:`~flexvox_app.gui.models.rig_service.RigService`'s rig; :func:`counters_text` and
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

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.service import (
    CaptureResult,
    CaptureService,
    CaptureStats,
    SyncSetting,
    warnings_shown_by_caller,
)
from flexvox_app.gui.models.live_source import put_scene_in_view
from flexvox_app.gui.models.rig_service import RigService
from flexvox_calibration.capture_setup import CaptureCalibration

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
    flexvox_app.capture.service.CaptureError
        For a path that exists (without ``overwrite``), a folder that does not exist, a bad code.
    ValueError
        For a code the plan cannot make, or ground truth asked of a real rig.
    """
    path = Path(path)
    if ground_truth and service.rig.simulated is None:
        raise ValueError("ground truth exists only on the simulated rig")
    put_scene_in_view(service)
    with warnings_shown_by_caller():  # the Capture workspace shows them, and asks before a phase that is a guess
        return factory(service.rig, plan, path, frames=frames, calibration=calibration or CaptureCalibration(),
                       sync=SyncSetting(delay_set_by_hand=delay_set_by_hand), ground_truth=ground_truth,
                       overwrite=overwrite, durable=durable,
                       rig_info={"profile": "mock" if service.simulated else service.name, "source": "flexvox app"})


def megabytes(n_bytes: float) -> str:
    """``n_bytes`` in MB (10⁶ bytes), two significant figures at least."""
    mb = n_bytes / 1e6
    return f"{mb:.2g} MB" if mb < 10 else f"{mb:.0f} MB"


def ground_truth_cost(K: int, height: int, width: int, camera_hz: float, frames: int | None,
                      finish_s_per_frame: float | None = None) -> str:
    """What storing the simulated scene's ground truth costs, in words: its size per frame and per second of
    recording (K float32 pictures per camera frame, beside one 16-bit frame: 2·K times the frames' size before
    compression), and that it is written after the last frame, so finishing takes longer (``finish_s_per_frame``:
    as measured on this machine by the last recording that stored it)."""
    per_frame = K * height * width * 4
    ratio = per_frame / (height * width * 2)
    text = (f"ground truth adds {megabytes(per_frame)} per frame ({megabytes(per_frame * camera_hz)} per second at "
            f"{camera_hz:g} Hz, about {ratio:.0f}× the frames' size)")
    if frames:
        text += f", {megabytes(per_frame * frames)} for {frames} frames"
    text += "; it is written after the last frame, so finishing takes longer"
    if finish_s_per_frame is not None:
        what = f"{finish_s_per_frame * frames:.0f} s for {frames} frames" if frames else \
            f"{finish_s_per_frame:.2f} s per frame"
        text += f" (about {what} on this machine, measured on the last such recording)"
    return text


def video_seconds(frames: int, frame_period_s: float) -> str:
    """How long ``frames`` camera frames last in the recording ("4.20 s of video"), as ``flexvox info`` says it."""
    return f"{frames * frame_period_s:.2f} s of video"


def counters_text(s: CaptureStats, target: int | None = None, frame_period_s: float | None = None) -> str:
    """One line of counters: frames (and the video they make, with ``frame_period_s``), drops, queue depth, write
    and camera rates, and the time since Record (which includes setting the rig up)."""
    of = f" of {target}" if target else ""
    video = f" = {video_seconds(s.rows_written, frame_period_s)}" if frame_period_s else ""
    return (f"{s.rows_written}{of} frames written{video} ({s.frames_received} received) · "
            f"{s.drops} dropped ({s.queue_drops} by the queue) · queue {s.queue_depth}/{s.queue_capacity} "
            f"(max {s.max_queue_depth}) · write {s.write_rate_hz:.1f} Hz · camera {s.camera_rate_hz:.1f} Hz · "
            f"{s.elapsed_s:.1f} s since Record")


def result_text(result: CaptureResult | None, path, frame_period_s: float | None = None) -> str:
    """What the workspace says when a capture has ended (None: it did not stop in time); with ``frame_period_s``,
    how long the recording lasts."""
    if result is None:
        return (f"the capture did not stop within the time allowed (the disk may hang); {path} keeps what was "
                "written: open it in Review to see what it holds")
    held = result.frames_in_recording
    video = (f"{video_seconds(held, frame_period_s)} at {1 / frame_period_s:.3g} Hz; "
             if frame_period_s and held is not None else "")
    if result.ok:
        return f"recording done: {video}{result.message}"
    return f"recording failed: {result.message}" + (f" ({video[:-2]} kept)" if video else "")
