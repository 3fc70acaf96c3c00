"""The rig set up for a capture plan: patterns, sync box, camera trigger and delay, in one place.

:func:`set_up_rig` is what a recording (:class:`~flexvox_app.capture.service.CaptureService`) and the
Capture workspace's live view both call, so the live view shows what a recording records:

1. the plan's timing must be one the projector and camera accept (:meth:`CapturePlan.timing`);
2. the projector shows :meth:`CapturePlan.patterns` through the calibration (the patterns
   calibration verifies), as a sequence the rig can run: pulsed by the sync box when the rig has
   one, VSYNC-triggered from the video input on a DLPC350, else timed internally;
3. the camera is triggered on the rig's line with the calibration's trigger delay when it can be
   told one (:func:`trigger_delay_by`); its exposure is the plan's.

A recording refuses what would record wrong data (a camera without a hardware trigger; a delay
nobody applies); the live view (``preview=True``) runs anyway and says why its picture is off.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

from flexvox_app.capture.plan import CapturePlan
from flexvox_calibration.capture_setup import CaptureCalibration
from rig_drivers.interfaces import (
    MIN_DARK_US,
    MIN_EXPOSURE_1BIT_US,
    CameraCapabilities,
    CameraSettings,
    DeviceState,
    PatternSequence,
    ProjectorTrigger,
    Rig,
    RunState,
    SyncSettings,
    TriggerConfig,
    TriggerSource,
)

_logger = logging.getLogger(__name__)


class CaptureError(RuntimeError):
    """The capture cannot start (bad settings, a device refusing its setup); the message says why."""


def trigger_delay_by(capabilities: CameraCapabilities, delay_us: float, set_by_hand: bool) -> str | None:
    """Who applies a camera trigger delay of ``delay_us``: ``"none"`` (no delay needed), ``"camera"`` (it can be
    told one), ``"operator"`` (set by hand, confirmed), or None: nobody, and the exposure opens part-way into a slot.
    """
    if delay_us <= 0:
        return "none"
    if capabilities.trigger_delay:
        return "camera"
    return "operator" if set_by_hand else None


def delay_refusal(camera_name: str, phase: int, delay_us: float) -> str:
    """Why a recording refuses a delay nobody applies, and what to do."""
    return (f"the calibration's phase {phase} needs a {delay_us:.0f} µs camera trigger delay, and {camera_name} "
            "cannot be told one: set it on the camera (its vendor's tool), then confirm that it is set (flexvox "
            "capture --delay-set-by-hand; in the Capture workspace, tick \"trigger delay set on the camera\")")


@dataclass(frozen=True)
class RigSetup:
    """How the rig was set up for a plan.

    Attributes
    ----------
    period_us : int
        Pattern period.
    camera_exposure_us : float
    camera_size, projector_size : (H, W)
    phase_slots : int
        The phase the patterns were made with.
    trigger_delay_us : float
        The calibration's camera trigger delay at this timing.
    delay_by : str
        ``camera``, ``operator``, ``none``, or ``unapplied`` (live view only).
    use_sync : bool
        The sync box clocks projector and camera.
    free_run : bool
        The camera runs free (live view of a camera without a hardware trigger).
    trigger_line : str
    warnings : tuple of str
        Everything worth reading: the calibration's warnings at this timing and the notes.
    notes : tuple of str
        What the rig set-up itself left out or found unneeded (a free-running camera, a delay not applied).
    """

    period_us: int
    camera_exposure_us: float
    camera_size: tuple[int, int]
    projector_size: tuple[int, int]
    phase_slots: int
    trigger_delay_us: float
    delay_by: str
    use_sync: bool
    free_run: bool
    trigger_line: str
    warnings: tuple[str, ...]
    notes: tuple[str, ...] = ()

    def rig_attrs(self, rig: Rig) -> dict:
        """The recording's ``rig`` attribute (the phase and the delay are in its ``calibration``)."""
        kind = "simulated" if rig.simulated is not None else "hardware"
        return {"kind": kind, "projector": rig.projector.name, "camera": rig.camera.name,
                "sync": rig.sync.name if self.use_sync else "projector TRIG_OUT_2",
                "period_us": self.period_us, "camera_exposure_us": self.camera_exposure_us,
                "trigger_line": self.trigger_line, "projector_size": list(self.projector_size),
                "trigger_delay_set_by": self.delay_by}


def check_calibration_rig(calibration: CaptureCalibration, rig: Rig, projector_size=None) -> bool:
    """Refuse ``calibration`` on ``rig`` when it was made for another rig, camera or resolution.

    The rule and the words are those a calibration file made for another rig is refused with
    (:meth:`CaptureCalibration.check_rig`); a calibration tied to no rig passes.

    Returns
    -------
    bool
        False when the rig cannot say who it is yet (a closed camera that reports its size only once open, a
        projector that reports no size): :func:`set_up_rig` checks again once the devices are open.

    Raises
    ------
    flexvox_calibration.capture_setup.CalibrationRefused
        For a calibration made for another rig, camera or resolution.
    """
    if calibration.rig is None:
        return True
    from flexvox_calibration.errors import CalibrationError
    from flexvox_calibration.session import RigSession
    from rig_drivers.errors import DeviceError

    try:
        identity = RigSession.from_rig(rig, projector_size=projector_size).identity
    except (DeviceError, CalibrationError):
        return False
    calibration.check_rig(identity)
    return True


def _open(device) -> None:
    if device.state is DeviceState.CLOSED:
        device.open()
    device.enable()


def set_up_rig(rig: Rig, plan: CapturePlan, calibration: CaptureCalibration | None = None, *, projector_size=None,
               use_sync_box: bool | None = None, delay_set_by_hand: bool = False, preview: bool = False,
               open_device: Callable = _open) -> RigSetup:
    """Open the rig's devices and set them up to capture ``plan`` through ``calibration``, and start them.

    Parameters
    ----------
    rig : Rig
        Its projector, camera, sync box (None allowed), trigger line, projector size, pixel layout and
        video port (:class:`rig_drivers.interfaces.Rig`).
    plan : CapturePlan
    calibration : CaptureCalibration, optional
        Default uncalibrated.
    projector_size : (H, W), optional
        Default the rig's ``projector_size``.
    use_sync_box : bool or None
        None: when the rig has one.
    delay_set_by_hand : bool
        The operator confirmed the trigger delay is set on a camera that cannot be told one.
    preview : bool
        For the live view: run a camera without a hardware trigger free, and a delay nobody applies
        undelayed, with a warning each, instead of refusing.
    open_device : callable
        Opens and enables a device (the capture service counts what it opened).

    Raises
    ------
    CaptureError
        For a timing the projector or camera refuses, a missing sync box or projector size, a calibration made
        for another rig, camera or resolution (:func:`check_calibration_rig`), a camera that cannot shutter, or
        a trigger delay nobody applies (not in a preview).
    """
    cal = calibration or CaptureCalibration()
    timing = plan.timing()
    if not timing.ok:
        raise CaptureError("; ".join(timing.errors))
    projector, camera = rig.projector, rig.camera
    sync = rig.sync
    use_sync = (sync is not None) if use_sync_box is None else bool(use_sync_box)
    if use_sync and sync is None:
        raise CaptureError("the sync setting asks for a sync box, but the rig has none")
    notes = []
    open_device(camera)
    free_run = not camera.capabilities.hardware_trigger
    if free_run:
        message = (f"{camera.name} has no hardware trigger: it cannot shutter in sync with the projector (preview "
                   "and alignment only)")
        if not preview:
            raise CaptureError(message)
        notes.append(message)
    open_device(projector)
    if use_sync:
        open_device(sync)
    H, W = (int(v) for v in camera.sensor_shape)
    psize = projector_size or rig.projector_size
    if psize is None:
        raise CaptureError(f"the projector size of {projector.name} is unknown: give it (rows, columns)")
    psize = tuple(int(v) for v in psize)
    try:
        check_calibration_rig(cal, rig, psize)
    except ValueError as exc:  # CalibrationRefused: the calibration is another rig's
        raise CaptureError(str(exc)) from None
    K, period = plan.K, timing.period_us
    phase, delay, cal_warnings = cal.for_plan(K, period)
    delay_by = trigger_delay_by(camera.capabilities, delay, delay_set_by_hand)
    if delay_by is None:
        if not preview:
            raise CaptureError(delay_refusal(camera.name, phase, delay))
        delay_by = "unapplied"
        notes.append(f"the exposure is not delayed by {delay:.0f} µs ({camera.name} cannot be told it): every "
                        "slot of the live view mixes two patterns")
    elif delay_by == "camera" and delay_set_by_hand:
        notes.append(f"{camera.name} sets the {delay:.0f} µs trigger delay itself: setting it by hand is not needed")
    patterns = plan.patterns((H, W), psize, cal, layout=rig.pixel_layout).patterns
    video_port = rig.video_port  # a DLPC350 fed by its video input
    if use_sync and video_port:
        raise CaptureError(
            f"{projector.name} takes its patterns on the video port, paced by the video signal's VSYNC: "
            "a sync box cannot clock it. Wire TRIG_OUT_2 to the camera and use [sync] kind = "
            "\"projector-trigger\" in the rig profile")
    if use_sync:
        # The sync box pulses the projector once per pattern: each pattern is triggered,
        # so it must end 230 µs before the next trigger (DLPC350 timing rule).
        exposure = period - MIN_DARK_US if period - MIN_DARK_US >= MIN_EXPOSURE_1BIT_US else period
        seq = PatternSequence(patterns, exposure, period, trigger=ProjectorTrigger.EXTERNAL_RISING,
                              patterns_per_trigger=1)
    elif video_port:
        # VSYNC-triggered, as many patterns per video frame as fit; TRIG_OUT_2 once per K.
        seq = projector.video_sequence(patterns, period)
    else:
        seq = PatternSequence(patterns, timing.projector_exposure_us, period, trigger=ProjectorTrigger.INTERNAL)
    if projector.run_state is not RunState.STOPPED:
        projector.stop()
    projector.load_sequence(seq)
    if use_sync:
        if sync.running:
            sync.stop()
        sync.configure(SyncSettings(period_us=period, pulses_per_frame=K))
    line = rig.trigger_line
    trigger = TriggerConfig(source=TriggerSource.FREE_RUN) if free_run else \
        TriggerConfig(source=line, delay_us=delay if delay_by == "camera" else 0.0)
    camera.stop_acquisition()
    camera.configure(CameraSettings(exposure_us=timing.camera_exposure_us, trigger=trigger))
    camera.start_acquisition()
    projector.start()
    if use_sync:
        sync.start()
    _logger.info("rig set up: K = %d, period %d µs (%.3f Hz), phase %d, trigger delay %.0f µs (%s), %s", K, period,
                 1e6 / (K * period), phase, delay, delay_by, "sync box" if use_sync else "projector trigger")
    return RigSetup(period, timing.camera_exposure_us, (H, W), psize, phase, delay, delay_by, use_sync, free_run,
                    trigger.source.value, tuple(cal_warnings + notes), tuple(notes))


@dataclass(frozen=True)
class StopError:
    """A device that :func:`stop_rig` could not stop: its role ("projector", "camera", "sync") and why, in words."""

    role: str
    message: str

    def __str__(self) -> str:
        return self.message


def stop_rig(rig: Rig) -> list[StopError]:
    """Stop the camera's acquisition, the sync box and the projector (devices stay open); the errors, in words."""
    from rig_drivers.errors import DeviceError

    errors = []
    steps = [("camera", "stop the camera", lambda: rig.camera.stop_acquisition()
              if rig.camera.state is not DeviceState.CLOSED else None)]
    sync = rig.sync
    if sync is not None:
        steps.append(("sync", "stop the sync box",
                      lambda: sync.stop() if sync.state is not DeviceState.CLOSED else None))
    steps.append(("projector", "stop the projector", lambda: rig.projector.stop()
                  if rig.projector.state is not DeviceState.CLOSED and rig.projector.run_state is not RunState.STOPPED
                  else None))
    for role, what, step in steps:
        try:
            step()
        except (DeviceError, OSError) as exc:
            errors.append(StopError(role, f"could not {what}: {exc}"))
    return errors
