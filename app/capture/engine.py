"""The acquisition engine: the rig set up for a plan, its camera read, the rig put back.

:class:`AcquisitionEngine` holds the devices' side of a capture and nothing of the recording's:
:meth:`~AcquisitionEngine.set_up` opens what is closed and sets the rig up through
:func:`~flexvox_app.capture.rig_setup.set_up_rig` (patterns, sync box, camera trigger and delay; the
projector and the sync box start, so the camera is triggered from then on),
:meth:`~AcquisitionEngine.frames` reads the camera until told to stop, and
:meth:`~AcquisitionEngine.tear_down` stops the devices and closes those it opened.
:class:`~flexvox_app.capture.service.CaptureService` drives it on its reader thread and hands each frame
to the recording sink (:mod:`flexvox_app.capture.sink`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator

from flexvox_app.capture.pacing import PacedClock
from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.rig_setup import CaptureError, RigSetup, set_up_rig, stop_rig
from flexvox_app.capture.settings import SyncSetting
from flexvox_calibration.capture_setup import CaptureCalibration
from rig_drivers.errors import DeviceError, DeviceTimeoutError
from rig_drivers.interfaces import DeviceState, Frame, Rig

_logger = logging.getLogger(__name__)


class CameraStopped(CaptureError):
    """The camera stopped delivering frames: it failed (unplugged?), or sent none for the no-frame timeout."""


class AcquisitionEngine:
    """Set a rig up for a plan, read its camera, and put it back.

    Parameters
    ----------
    rig : Rig
        Closed devices are opened by :meth:`set_up` and closed again by :meth:`tear_down`; open
        ones are left open (stopped).
    plan : CapturePlan
    calibration : CaptureCalibration
    sync : SyncSetting
    projector_size : (H, W), optional
        Default: the rig's ``projector_size``.
    """

    def __init__(self, rig: Rig, plan: CapturePlan, calibration: CaptureCalibration, sync: SyncSetting, *,
                 projector_size=None):
        self.rig = rig
        self.plan = plan
        self.calibration = calibration
        self.sync = sync
        self.projector_size = projector_size
        self.setup: RigSetup | None = None
        """How the rig was set up (after :meth:`set_up`)."""
        self._opened: list = []

    @property
    def frame_period_s(self) -> float:
        """The camera frame period set up on the rig (K projector periods; 0 before :meth:`set_up`)."""
        return 0.0 if self.setup is None else self.plan.K * self.setup.period_us / 1e6

    def ground_truth(self) -> Callable:
        """The simulated scene's truth: ``(frame_id, K) -> (K, H, W)``; refused on a real rig."""
        truth = self.rig.truth
        if truth is None:
            raise CaptureError("ground truth exists only on the simulated rig (a real scene has none)")
        return truth.subframe_video

    def set_up(self) -> RigSetup:
        """Open and set up the devices, and start the projector (and the sync box).

        Raises
        ------
        CaptureError
            When a device refuses its setup; the devices are stopped and closed again first.
        """
        sim = self.rig.simulated
        if sim is not None and isinstance(sim.clock, PacedClock):  # building the rig took wall time, not frames
            sim.clock.resync()
        try:
            self.setup = set_up_rig(self.rig, self.plan, self.calibration, projector_size=self.projector_size,
                                    use_sync_box=self.sync.use_sync_box,
                                    delay_set_by_hand=self.sync.delay_set_by_hand, open_device=self._open)
        except CaptureError:
            self.tear_down()
            raise
        except (DeviceError, ValueError) as exc:
            self.tear_down()
            raise CaptureError(f"cannot set up the rig: {exc}") from exc
        for warning in self.setup.warnings:
            _logger.info("capture: %s", warning)
        return self.setup

    def frames(self, stop: threading.Event) -> Iterator[Frame]:
        """The camera's frames as they arrive, until ``stop`` is set (checked at least every ``read_slice_s``).

        Raises
        ------
        CameraStopped
            When the camera fails, or sends no frame for the no-frame timeout.
        """
        camera = self.rig.camera
        slice_s = self.sync.read_slice_s
        no_frame_s = self.sync.no_frame_s(self.plan.camera_hz)
        last_frame_t = time.perf_counter()
        while not stop.is_set():
            try:
                frame = camera.read_frame(slice_s)
            except DeviceTimeoutError as exc:
                if time.perf_counter() - last_frame_t > no_frame_s:
                    raise CameraStopped(f"no frame from the camera for {no_frame_s:g} s ({exc})") from None
                continue
            except DeviceError as exc:
                raise CameraStopped(f"the camera failed (unplugged?): {exc}") from None
            last_frame_t = time.perf_counter()
            yield frame

    def tear_down(self) -> None:
        """Stop the devices, and close those :meth:`set_up` opened (errors are logged)."""
        for message in stop_rig(self.rig):
            _logger.error("capture teardown: %s", message)
        for device in reversed(self._opened):
            try:
                device.close()
            except DeviceError as exc:
                _logger.error("capture teardown: could not close %s: %s", device.name, exc)
        self._opened = []

    def _open(self, device) -> None:
        if device.state is DeviceState.CLOSED:
            device.open()
            self._opened.append(device)
        device.enable()
