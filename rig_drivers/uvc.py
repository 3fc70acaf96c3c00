"""UVC (USB webcam) cameras through OpenCV, for preview and alignment only.

A UVC camera has no trigger input and no frame counter, so it cannot shutter in sync with
the projector: its :attr:`UvcCamera.capabilities` say so, and
:meth:`~rig_drivers.interfaces.Camera.configure` refuses a hardware trigger. Use it to aim
and focus the rig, or for a co-location check.

- Frame ids are **synthesised** by flexvox (0, 1, 2, ... per frame read since open); a frame
  the camera or the driver dropped does *not* show as a gap (:attr:`UvcCamera.synthesised_ids`).
- Timestamps are the host's monotonic clock when the frame was read.
- Colour frames become grey (``cv2.COLOR_BGR2GRAY``).
- Exposure is best effort: ``CAP_PROP_AUTO_EXPOSURE`` to manual and ``CAP_PROP_EXPOSURE`` in
  the V4L2 unit of 100 µs; a backend that refuses is logged and listed in
  :attr:`UvcCamera.unapplied`.
- :meth:`read_frame` asks OpenCV for a read timeout (``CAP_PROP_READ_TIMEOUT_MSEC``, honoured
  by some backends) and polls ``read()`` until a frame comes or its own timeout passes.

The capture object comes from an injectable factory (default ``cv2.VideoCapture``), so tests
drive the driver with a fake capture.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

import numpy as np

from rig_drivers.errors import DeviceNotFoundError, DeviceTimeoutError, IncompatibleStateError, SettingError
from rig_drivers.interfaces import (
    Camera,
    CameraCapabilities,
    CameraSettings,
    DeviceState,
    Frame,
    TriggerSource,
    check_int,
)

_logger = logging.getLogger(__name__)

MAX_READ_ATTEMPTS = 10_000
"""Most ``read()`` calls in one :meth:`UvcCamera.read_frame` (the timeout usually ends it first)."""


def _cv2():
    import cv2

    return cv2


class UvcCamera(Camera):
    """A UVC camera through ``cv2.VideoCapture`` (no trigger, no frame ids).

    Parameters
    ----------
    index : int
        OpenCV's camera index (``/dev/video<index>`` on Linux).
    capture_factory : callable, optional
        ``(index) -> capture`` with OpenCV's ``isOpened/read/get/set/release`` (default
        ``cv2.VideoCapture``).
    clock_s, sleep_s : callable, optional
        Host clock and sleep (default ``time.monotonic`` / ``time.sleep``); tests inject fakes.
    poll_interval_s : float
        Pause between failed ``read()`` calls.
    """

    synthesised_ids = True
    """Frame ids are counted by flexvox, not by the camera: dropped frames do not show as gaps."""

    def __init__(self, index: int = 0, *, capture_factory: Callable | None = None,
                 clock_s: Callable[[], float] | None = None, sleep_s: Callable[[float], None] | None = None,
                 poll_interval_s: float = 0.005, name: str | None = None):
        super().__init__(name=name or f"UVC camera {index}")
        self.index = check_int("index", index, 0, 255)
        self._factory = capture_factory
        self._clock_s = clock_s or time.monotonic
        self._sleep_s = sleep_s or time.sleep
        if isinstance(poll_interval_s, bool) or not isinstance(poll_interval_s, int | float) \
                or not 0 <= poll_interval_s <= 0.1:
            raise SettingError(f"`poll_interval_s` must be between 0 and 0.1 s; got {poll_interval_s!r}")
        self._poll_s = float(poll_interval_s)
        self._cap = None
        self._shape = (0, 0)
        self._next_id = 0
        self.unapplied: list[str] = []
        """Properties the backend refused at the last configure()."""

    @property
    def capabilities(self) -> CameraCapabilities:
        """No trigger line, no frame counter, host timestamps."""
        return CameraCapabilities(hardware_trigger=False, frame_ids=False, device_timestamps=False)

    @property
    def sensor_shape(self) -> tuple[int, int]:
        """``(H, W)`` as the capture reports it at open."""
        if self.state is DeviceState.CLOSED:
            raise IncompatibleStateError(f"cannot read the sensor shape: {self.name} is closed (call open() first)")
        return self._shape

    def _do_open(self) -> None:
        factory = self._factory or _cv2().VideoCapture
        cap = factory(self.index)
        if not cap.isOpened():
            cap.release()
            raise DeviceNotFoundError(
                f"no UVC camera at index {self.index}: is it plugged in, and not held by another program "
                f"(a browser, a video call)? On Linux check that /dev/video{self.index} exists and that you "
                f"are in the `video` group")
        cv2 = _cv2()
        self._cap = cap
        self._shape = (int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)))
        self._next_id = 0
        _logger.info("%s opened (%dx%d); frame ids are synthesised by flexvox: preview and alignment only",
                     self.name, self._shape[1], self._shape[0])

    def _do_close(self) -> None:
        cap, self._cap = self._cap, None
        if cap is not None:
            cap.release()

    def _do_configure(self, settings: CameraSettings) -> None:
        if settings.trigger.source is not TriggerSource.FREE_RUN:
            raise SettingError(f"{self.name} can only run free (trigger source FreeRun): UVC cameras have no "
                               f"{settings.trigger.source.value} trigger")
        cv2 = _cv2()
        self.unapplied = []
        for prop, label, value in (
            (cv2.CAP_PROP_AUTO_EXPOSURE, "auto exposure off", 1.0),  # V4L2: 1 = manual
            (cv2.CAP_PROP_EXPOSURE, "exposure", settings.exposure_us / 100.0),  # V4L2 unit: 100 µs
            (cv2.CAP_PROP_GAIN, "gain", settings.gain_db),
        ):
            if not self._cap.set(prop, value):
                self.unapplied.append(label)
                _logger.warning("%s: the backend refused %s (%g); left at the camera's setting",
                                self.name, label, value)

    def _do_start_acquisition(self) -> None:
        """Nothing to start: a UVC camera streams while it is open."""

    def _do_stop_acquisition(self) -> None:
        """Nothing to stop."""

    def _do_trigger_software(self) -> None:  # pragma: no cover - configure() refuses Software
        raise IncompatibleStateError(f"{self.name} has no software trigger")

    def _do_read_frame(self, timeout_s: float) -> Frame:
        cv2 = _cv2()
        self._cap.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, math.ceil(timeout_s * 1000))
        deadline = self._clock_s() + timeout_s
        for _ in range(MAX_READ_ATTEMPTS):
            ok, image = self._cap.read()
            if ok and image is not None:
                return self._frame(np.asarray(image))
            if self._clock_s() >= deadline:
                break
            self._sleep_s(min(self._poll_s, max(0.0, deadline - self._clock_s())))
        raise DeviceTimeoutError(
            f"{self.name}: no frame within {timeout_s:g} s: is the camera still connected and not in use "
            f"by another program?")

    def _frame(self, image: np.ndarray) -> Frame:
        if image.ndim == 3 and image.shape[2] == 1:
            image = image[:, :, 0]
        elif image.ndim == 3:
            cv2 = _cv2()
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
        frame_id, self._next_id = self._next_id, self._next_id + 1
        return Frame(image, frame_id=frame_id, timestamp_s=float(self._clock_s()))
