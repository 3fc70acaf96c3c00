"""Starting and stopping the Capture workspace's live view on a rig (Qt-free).

The live view sets the rig up exactly as a recording does (:func:`flexvox_app.capture.rig_setup.set_up_rig`:
the plan's patterns through the calibration, the sync box when the rig has one, the camera's
trigger and delay), with ``preview=True``: a camera without a hardware trigger (a UVC webcam)
free-runs, and a trigger delay the camera cannot be told is left out; the note says so.
"""

from __future__ import annotations

import logging

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.rig_setup import CaptureError, set_up_rig, stop_rig
from flexvox_app.gui.models.rig_service import RigService
from rig_drivers.errors import DeviceError, SettingError

_logger = logging.getLogger(__name__)


class LiveStartError(Exception):
    """The live view could not start; the message says why in words."""


def projector_size(projector) -> tuple[int, int]:
    """The projector's pattern size (H, W), as its driver reports it."""
    size = projector.size
    if size is None:
        raise LiveStartError(f"{projector.name} does not report its pattern size")
    return tuple(int(v) for v in size)


def put_scene_in_view(service: RigService) -> None:
    """The simulated rig's stand-in for the operator taking the calibration target away before capture."""
    sim = service.rig.simulated
    if sim is not None and sim.viewing != "scene":
        sim.show_scene()


def start_live(service: RigService, plan: CapturePlan, calibration=None, *, delay_set_by_hand: bool = False) -> str:
    """Connect the projector and camera, set the rig up for ``plan`` as a recording would, start it.

    Returns a note for the UI ("" or, e.g., "free-running: preview only").

    Raises
    ------
    LiveStartError
        When the plan's timing is wrong or a device refuses.
    """
    if not service.ensure_connected("projector", "camera"):
        errs = [s.last_error for s in service.statuses() if s.last_error]
        raise LiveStartError("cannot connect: " + "; ".join(errs))
    put_scene_in_view(service)
    try:
        setup = set_up_rig(service.rig, plan, calibration, delay_set_by_hand=delay_set_by_hand, preview=True)
    except (CaptureError, DeviceError, SettingError, OSError) as exc:
        stop_live(service)
        raise LiveStartError(str(exc)) from exc
    for role in ("projector", "camera", "sync"):
        service.notify(role)
    _logger.info("live view started: K=%d, %g Hz, period %d µs", plan.K, plan.camera_hz, setup.period_us)
    return "; ".join(setup.notes)


def stop_live(service: RigService) -> None:
    """Stop the camera's acquisition, the sync box and the projector's sequence (devices stay connected)."""
    for error in stop_rig(service.rig):
        service.record_error(error.role, error.message)
    for role in ("projector", "camera", "sync"):
        service.notify(role)
