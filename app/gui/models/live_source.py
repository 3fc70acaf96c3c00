"""Starting and stopping a live view on a rig (Qt-free): projector sequence, camera trigger, acquisition.

The projector plays the plan's code (one TRIG_OUT_2 per K patterns) and the camera is triggered
on the rig's trigger line. A camera without a hardware trigger (a UVC webcam) free-runs: preview
and alignment only, and :func:`start_live` says so.
"""

from __future__ import annotations

import logging

from app.capture.plan import CapturePlan
from app.gui.models.rig_service import RigService
from rig_drivers.errors import DeviceError, SettingError
from rig_drivers.interfaces import CameraSettings, RunState, TriggerConfig, TriggerSource

_logger = logging.getLogger(__name__)

DLPC350_SIZE = (1140, 912)
"""The LightCrafter 4500's DMD, rows × columns (its driver does not report it)."""


class LiveStartError(Exception):
    """The live view could not start; the message says why in words."""


def projector_size(projector) -> tuple[int, int]:
    """The projector's pattern size (H, W): its ``size`` where it has one, else the DLPC350's."""
    size = getattr(projector, "size", None)
    return tuple(size) if size is not None else DLPC350_SIZE


def start_live(service: RigService, plan: CapturePlan, calibration=None) -> str:
    """Connect the projector and camera, load and start the plan's sequence, start acquiring.

    The projector shows the capture service's patterns for the plan through ``calibration`` (a
    :class:`~calibration.capture_setup.CaptureCalibration`; default uncalibrated), and the camera's
    trigger is delayed by the calibration's delay where the camera can do it, so the live view
    shutters the camera as a recording will.

    Returns a note for the UI ("" or e.g. "free-running: preview only").

    Raises
    ------
    LiveStartError
        When the plan's timing is wrong or a device refuses.
    """
    timing = plan.timing()
    if not timing.ok:
        raise LiveStartError("; ".join(timing.errors))
    if not service.ensure_connected("projector", "camera"):
        errs = [s.last_error for s in service.statuses() if s.last_error]
        raise LiveStartError("cannot connect: " + "; ".join(errs))
    rig = service.rig
    note = ""
    put_scene_in_view(service)
    try:
        proj = rig.projector
        if proj.run_state is not RunState.STOPPED:
            proj.stop()
        cam = rig.camera
        proj.load_sequence(plan.sequence(projector_size(proj), camera_size=tuple(cam.sensor_shape),
                                         calibration=calibration))
        proj.start()
        cam.stop_acquisition()
        exposure = plan.camera_exposure_us or timing.sequence_us
        if cam.capabilities.hardware_trigger:
            delay = 0.0
            if calibration is not None and cam.capabilities.trigger_delay:
                delay = calibration.for_plan(plan.K, plan.period_us)[1]
            cam.configure(CameraSettings(exposure_us=exposure,
                                         trigger=TriggerConfig(source=rig.trigger_line, delay_us=delay)))
        else:
            cam.configure(CameraSettings(exposure_us=exposure, trigger=TriggerConfig(source=TriggerSource.FREE_RUN)))
            note = f"{cam.name} has no hardware trigger: free-running, preview and alignment only"
        cam.start_acquisition()
    except (DeviceError, SettingError, OSError) as exc:
        stop_live(service)
        raise LiveStartError(str(exc)) from exc
    for role in ("projector", "camera"):
        service.notify(role)
    _logger.info("live view started: K=%d, %g Hz, period %d µs", plan.K, plan.camera_hz, timing.period_us)
    return note


def put_scene_in_view(service: RigService) -> None:
    """The simulated rig's stand-in for the operator taking the calibration target away before capture."""
    sim = service.rig.simulated
    if sim is not None and sim.viewing != "scene":
        sim.show_scene()


def stop_live(service: RigService) -> None:
    """Stop the camera's acquisition and the projector's sequence (devices stay connected)."""
    rig = service.rig
    try:
        rig.camera.stop_acquisition()
    except (DeviceError, OSError) as exc:
        service.record_error("camera", f"stop acquisition failed: {exc}")
    try:
        if rig.projector.run_state is not RunState.STOPPED:
            rig.projector.stop()
    except (DeviceError, OSError) as exc:
        service.record_error("projector", f"stop failed: {exc}")
    for role in ("projector", "camera"):
        service.notify(role)
