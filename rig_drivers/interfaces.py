"""Device interfaces: the lifecycle every device shares, the projector, camera and sync
controller contracts with their typed settings, and the :class:`Rig` that holds one of each.

The pattern follows python-microscope's ``abc.py``: a public method validates its arguments
and checks the device state, then calls a ``_do_*`` hook that a driver implements. A driver
therefore never re-checks state, and a caller never reaches a driver with a bad value.

Lifecycle::

    CLOSED --open()--> OPEN --enable()--> ENABLED
       ^                 |  <--disable()--   |
       +----close()------+-------close()-----+

``open`` connects (no light, no triggers); ``enable`` makes the device ready to act (a
projector leaves standby, a camera may acquire); ``close`` always ends CLOSED, disabling
first. Devices are context managers (``with dev: ...`` opens and closes).

Units are in the names: ``*_us`` microseconds (whole numbers where the hardware counts whole
microseconds), ``*_s`` seconds. Every blocking call takes a timeout; no call waits forever.
"""

from __future__ import annotations

import enum
import logging
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np

from rig_drivers.errors import IncompatibleStateError, SettingError

_logger = logging.getLogger(__name__)


# --------------------------------------------------------------------------- helpers


def check_int(name: str, value: object, low: int, high: int, unit: str = "") -> int:
    """Return ``value`` as an int in ``[low, high]`` or raise :class:`SettingError`."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise SettingError(f"`{name}` must be a whole number{unit and ' of ' + unit}; got {value!r}")
    if not low <= int(value) <= high:
        suffix = f" {unit}" if unit else ""
        raise SettingError(f"`{name}` must be between {low} and {high}{suffix}; got {int(value)}")
    return int(value)


def check_positive_float(name: str, value: object, high: float, unit: str) -> float:
    """Return ``value`` as a finite float in ``(0, high]`` or raise :class:`SettingError`."""
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise SettingError(f"`{name}` must be a finite number of {unit}; got {value!r}")
    if not 0 < float(value) <= high:
        raise SettingError(f"`{name}` must be > 0 and <= {high:g} {unit}; got {float(value):g}")
    return float(value)


def check_timeout(timeout_s: object) -> float:
    """Validate a timeout in seconds (finite, > 0, at most an hour)."""
    return check_positive_float("timeout_s", timeout_s, 3600.0, "s")


# --------------------------------------------------------------------------- lifecycle


class DeviceState(enum.Enum):
    """Where a device is in its lifecycle."""

    CLOSED = "closed"
    OPEN = "open"
    ENABLED = "enabled"


class Device(ABC):
    """A device with an open/enable/disable/close lifecycle.

    Subclasses implement ``_do_open``, ``_do_close`` and optionally ``_do_enable`` /
    ``_do_disable``. The constructor does no I/O.
    """

    kind = "device"
    """A short noun for messages ("projector", "camera", "sync box")."""

    def __init__(self, *, name: str | None = None):
        self._state = DeviceState.CLOSED
        self.name = name or type(self).__name__

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} ({self.kind}): {self._state.value}>"

    # -- state
    @property
    def state(self) -> DeviceState:
        """The lifecycle state."""
        return self._state

    def _require(self, action: str, *allowed: DeviceState) -> None:
        if self._state not in allowed:
            wanted = " or ".join(s.value for s in allowed)
            raise IncompatibleStateError(
                f"cannot {action}: {self.name} is {self._state.value}, it must be {wanted}"
                + (" (call open() first)" if self._state is DeviceState.CLOSED else "")
                + (" (call enable() first)" if allowed == (DeviceState.ENABLED,)
                   and self._state is DeviceState.OPEN else "")
            )

    # -- lifecycle
    def open(self) -> None:
        """Connect to the device. Allowed only when CLOSED."""
        self._require("open", DeviceState.CLOSED)
        self._do_open()
        self._state = DeviceState.OPEN
        _logger.info("%s opened", self.name)

    def enable(self) -> None:
        """Make the device ready to act. No-op when already ENABLED."""
        if self._state is DeviceState.ENABLED:
            return
        self._require("enable", DeviceState.OPEN)
        self._do_enable()
        self._state = DeviceState.ENABLED

    def disable(self) -> None:
        """Stop acting (stop sequences and acquisitions). No-op when OPEN."""
        if self._state is DeviceState.OPEN:
            return
        self._require("disable", DeviceState.ENABLED)
        try:
            self._do_disable()
        finally:
            self._state = DeviceState.OPEN

    def close(self) -> None:
        """Disable if needed and disconnect. Always ends CLOSED; no-op when CLOSED."""
        if self._state is DeviceState.CLOSED:
            return
        try:
            if self._state is DeviceState.ENABLED:
                self.disable()
        finally:
            try:
                self._do_close()
            finally:
                self._state = DeviceState.CLOSED
                _logger.info("%s closed", self.name)

    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- hooks
    @abstractmethod
    def _do_open(self) -> None: ...

    @abstractmethod
    def _do_close(self) -> None: ...

    def _do_enable(self) -> None:  # noqa: B027 - optional hook
        """Hook: make the device ready (default: nothing to do)."""

    def _do_disable(self) -> None:  # noqa: B027 - optional hook
        """Hook: stop acting (default: nothing to do)."""


# --------------------------------------------------------------------------- projector

MIN_DARK_US = 230
"""DLPC350 rule: pattern exposure equals the period, or is at least 230 µs shorter
(DLPC350 Programmer's Guide DLPU010G §2.4.3.4.3)."""

MIN_EXPOSURE_1BIT_US = 235
"""Shortest 1-bit pattern exposure of the DLPC350 (DLPU010G Table 2-48 / DLPU011F Table 4-1)."""

MAX_PERIOD_US = 10_000_000
"""Longest pattern period accepted (10 s); far beyond any flexible-voxel use."""

MAX_PATTERNS = 128
"""Most patterns in one sequence (the DLPC350 pattern LUT holds 128 entries)."""


class ProjectorTrigger(enum.Enum):
    """What starts a group of patterns (a "trigger point") in the sequence."""

    VSYNC = "vsync"
    """The projector's video input VSYNC (patterns streamed through the video port)."""
    INTERNAL = "internal"
    """The projector's own timer."""
    EXTERNAL_RISING = "external_rising"
    """A rising edge on the projector's trigger input (e.g. from the sync box)."""
    EXTERNAL_FALLING = "external_falling"
    """A falling edge on the projector's trigger input."""


class RunState(enum.Enum):
    """Whether a pattern sequence is being displayed."""

    STOPPED = "stopped"
    PAUSED = "paused"
    RUNNING = "running"


def check_pattern_timing(exposure_us: object, period_us: object) -> tuple[int, int]:
    """Validate a pattern exposure and period in whole microseconds.

    The rule (DLPC350 Programmer's Guide DLPU010G §2.4.3.4.3): the exposure equals the
    period, or it is at least :data:`MIN_DARK_US` (230 µs) shorter.

    Raises
    ------
    SettingError
        Naming the value and the rule.
    """
    period = check_int("period_us", period_us, MIN_EXPOSURE_1BIT_US, MAX_PERIOD_US, "µs")
    exposure = check_int("exposure_us", exposure_us, MIN_EXPOSURE_1BIT_US, MAX_PERIOD_US, "µs")
    if exposure > period:
        raise SettingError(
            f"`exposure_us` must not exceed `period_us`; got exposure {exposure} µs > period {period} µs"
        )
    if exposure != period and exposure > period - MIN_DARK_US:
        raise SettingError(
            f"`exposure_us` must equal `period_us` or be at most period - {MIN_DARK_US} µs "
            f"= {period - MIN_DARK_US} µs; got exposure {exposure} µs with period {period} µs"
        )
    return exposure, period


@dataclass(frozen=True, eq=False)
class PatternSequence:
    """A sequence of K binary patterns shown one after another, repeating.

    Parameters
    ----------
    patterns : ndarray, shape (K, H, W), bool
        Pattern k is shown in slot k; True = mirror on (light reaches the scene).
    exposure_us, period_us : int
        Exposure and period of each pattern in whole microseconds; see
        :func:`check_pattern_timing`. The sequence lasts ``K * period_us``.
    trigger : ProjectorTrigger
        What starts each group of ``patterns_per_trigger`` patterns.
    patterns_per_trigger : int, optional
        Patterns shown per trigger; default K (one trigger per sequence). Must divide K.
    trigger_out_every : int, optional
        The projector's frame trigger output (DLPC350 TRIG_OUT_2) pulses once per this many
        patterns; default K, i.e. once per camera frame.
    repeat : bool
        Repeat the sequence until stopped (True) or play it once.
    """

    patterns: np.ndarray
    exposure_us: int
    period_us: int
    trigger: ProjectorTrigger = ProjectorTrigger.INTERNAL
    patterns_per_trigger: int | None = None
    trigger_out_every: int | None = None
    repeat: bool = True

    def __post_init__(self) -> None:
        arr = np.asarray(self.patterns)
        if arr.ndim != 3:
            raise SettingError(f"`patterns` must have shape (K, H, W); got {arr.ndim} dimensions {arr.shape}")
        K, H, W = arr.shape
        if not 1 <= K <= MAX_PATTERNS:
            raise SettingError(f"`patterns` must hold between 1 and {MAX_PATTERNS} patterns; got {K}")
        if H < 1 or W < 1:
            raise SettingError(f"`patterns` must have H, W >= 1; got {(H, W)}")
        if arr.dtype != bool:
            if not np.issubdtype(arr.dtype, np.number) or not np.all((arr == 0) | (arr == 1)):
                raise SettingError("`patterns` values must be 0/1 (or bool)")
            arr = arr.astype(bool)
        arr = np.array(arr, dtype=bool, copy=True)
        arr.setflags(write=False)
        object.__setattr__(self, "patterns", arr)
        exposure, period = check_pattern_timing(self.exposure_us, self.period_us)
        object.__setattr__(self, "exposure_us", exposure)
        object.__setattr__(self, "period_us", period)
        if not isinstance(self.trigger, ProjectorTrigger):
            raise SettingError(f"`trigger` must be a ProjectorTrigger; got {self.trigger!r}")
        ppt = K if self.patterns_per_trigger is None else check_int(
            "patterns_per_trigger", self.patterns_per_trigger, 1, K)
        if K % ppt:
            raise SettingError(f"`patterns_per_trigger` must divide the {K} patterns; got {ppt}")
        object.__setattr__(self, "patterns_per_trigger", ppt)
        every = K if self.trigger_out_every is None else check_int(
            "trigger_out_every", self.trigger_out_every, 1, 256)
        object.__setattr__(self, "trigger_out_every", every)
        if not isinstance(self.repeat, bool):
            raise SettingError(f"`repeat` must be True or False; got {self.repeat!r}")

    @property
    def K(self) -> int:
        """Number of patterns."""
        return int(self.patterns.shape[0])

    @property
    def shape(self) -> tuple[int, int]:
        """Pattern size ``(H, W)``."""
        return int(self.patterns.shape[1]), int(self.patterns.shape[2])

    @property
    def sequence_us(self) -> int:
        """Duration of one pass through the sequence, ``K * period_us``."""
        return self.K * self.period_us

    @classmethod
    def for_camera_rate(cls, patterns: np.ndarray, camera_fps: float, **kwargs: Any) -> PatternSequence:
        """A sequence whose K patterns fill one camera frame at ``camera_fps``.

        The period is ``floor(1e6 / (camera_fps * K))`` whole µs (the projector counts whole
        µs, so the sequence is slightly shorter than the camera frame: use hardware sync),
        and the exposure equals the period unless ``exposure_us`` is given.
        """
        fps = check_positive_float("camera_fps", camera_fps, 10_000.0, "Hz")
        K = int(np.asarray(patterns).shape[0]) if np.ndim(patterns) == 3 else 0
        if K < 1:
            raise SettingError(f"`patterns` must have shape (K, H, W); got {np.shape(patterns)}")
        period = int(1e6 // (fps * K))
        kwargs.setdefault("exposure_us", period)
        return cls(patterns=patterns, period_us=period, **kwargs)


Display = Callable[[np.ndarray], None]
"""A display sink: shows ``(N, H, W, 3)`` uint8 frames on the projector's video input, returns when shown."""


class LedControl(Protocol):
    """A projector's LED currents (a LightCrafter 4500's): :attr:`Projector.led_control`, None for a projector
    whose LEDs flexvox does not set."""

    @property
    def configured_led_currents(self) -> tuple[int, int, int] | None:
        """The (red, green, blue) PWM values 0..255 set whenever the projector is enabled (a rig profile's
        ``led_current``); None leaves the projector's own."""

    def led_currents(self) -> tuple[int, int, int]:
        """The (red, green, blue) PWM values read back from the open projector."""

    def set_led_currents(self, red: int, green: int, blue: int) -> None:
        """Send (red, green, blue) PWM values 0..255 to the open projector."""


class DisplayInput(Protocol):
    """The video input of a projector that takes its patterns there (:attr:`Projector.display_input`): the
    app plugs in a display sink, which every sequence loaded is shown through."""

    @property
    def display(self) -> Display | None:
        """The display sink, None when none is plugged in (nothing is shown)."""

    @display.setter
    def display(self, display: Display | None) -> None: ...


class Projector(Device):
    """A pattern projector used as a per-pixel shutter.

    State rules: :meth:`load_sequence` needs OPEN or ENABLED and a stopped sequence;
    :meth:`start` needs ENABLED and a loaded sequence; :meth:`pause` needs RUNNING.
    """

    kind = "projector"

    size: tuple[int, int] | None = None
    """Pattern size (rows, columns); None where the driver does not know it (its user then gives it)."""
    pixel_layout: str = "square"
    """How its pixels sit: one of :data:`rig_drivers.pixel_layout.LAYOUTS` (a diamond DMD staggers its rows)."""
    video_port: bool = False
    """True for a projector that takes its patterns on its video input, each exposure triggered by the video
    signal's VSYNC (the DLPC350): its sequences come from :meth:`video_sequence`, and no sync box can clock it."""

    def __init__(self, *, name: str | None = None):
        super().__init__(name=name)
        self._sequence: PatternSequence | None = None
        self._run_state = RunState.STOPPED

    @property
    def led_control(self) -> LedControl | None:
        """Its LED currents, where flexvox sets them (a LightCrafter 4500); None here (the projector's own)."""
        return None

    @property
    def display_input(self) -> DisplayInput | None:
        """Its video input, where a display sink shows its patterns (:attr:`video_port`); None here."""
        return None

    def video_sequence(self, patterns: np.ndarray, period_us: int, *, repeat: bool = True) -> PatternSequence:
        """A sequence of ``patterns`` this projector runs from its video port (only where :attr:`video_port`).

        Raises
        ------
        SettingError
            For a projector without a video port (build a :class:`PatternSequence` instead).
        """
        raise SettingError(f"{self.name} takes no patterns on a video port: build a PatternSequence for it")

    @property
    def sequence(self) -> PatternSequence | None:
        """The loaded (and device-validated) sequence, or None."""
        return self._sequence

    @property
    def run_state(self) -> RunState:
        """Whether the sequence is stopped, paused or running."""
        return self._run_state

    def load_sequence(self, sequence: PatternSequence) -> None:
        """Configure the device for ``sequence`` and have it validated.

        Raises
        ------
        IncompatibleStateError
            When closed or while a sequence runs or is paused (stop it first).
        SettingError
            When the projector cannot show this sequence (the message says why).
        ProtocolError
            When the device rejects the configuration.
        """
        if not isinstance(sequence, PatternSequence):
            raise SettingError(f"`sequence` must be a PatternSequence; got {type(sequence).__name__}")
        self._require("load a sequence", DeviceState.OPEN, DeviceState.ENABLED)
        if self._run_state is not RunState.STOPPED:
            raise IncompatibleStateError(
                f"cannot load a sequence while it is {self._run_state.value}: call stop() first")
        self._sequence = None
        self._do_load_sequence(sequence)
        self._sequence = sequence

    def start(self) -> None:
        """Start (or resume) the loaded sequence."""
        self._require("start", DeviceState.ENABLED)
        if self._sequence is None:
            raise IncompatibleStateError("cannot start: no sequence loaded (call load_sequence() first)")
        if self._run_state is RunState.RUNNING:
            return
        self._do_start()
        self._run_state = RunState.RUNNING

    def pause(self) -> None:
        """Pause the running sequence; :meth:`start` resumes it at the current pattern."""
        self._require("pause", DeviceState.ENABLED)
        if self._run_state is not RunState.RUNNING:
            raise IncompatibleStateError(f"cannot pause: the sequence is {self._run_state.value}, not running")
        self._do_pause()
        self._run_state = RunState.PAUSED

    def stop(self) -> None:
        """Stop the sequence (the next start begins at pattern 0). No-op when stopped."""
        self._require("stop", DeviceState.OPEN, DeviceState.ENABLED)
        if self._run_state is RunState.STOPPED:
            return
        try:
            self._do_stop()
        finally:
            self._run_state = RunState.STOPPED

    def _do_disable(self) -> None:
        self.stop()

    @abstractmethod
    def _do_load_sequence(self, sequence: PatternSequence) -> None: ...

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_pause(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...


# --------------------------------------------------------------------------- camera


class TriggerSelector(enum.Enum):
    """Which acquisition event the trigger starts (GenICam ``TriggerSelector``)."""

    FRAME_START = "FrameStart"


class TriggerSource(enum.Enum):
    """Where the camera's trigger comes from (GenICam ``TriggerSource`` names)."""

    FREE_RUN = "FreeRun"
    """No trigger: the camera runs at its own rate (``TriggerMode=Off``)."""
    SOFTWARE = "Software"
    """:meth:`Camera.trigger_software` fires one frame."""
    LINE0 = "Line0"
    LINE1 = "Line1"
    LINE2 = "Line2"
    LINE3 = "Line3"


class TriggerActivation(enum.Enum):
    """Which edge or level of a hardware trigger line fires (GenICam ``TriggerActivation``)."""

    RISING_EDGE = "RisingEdge"
    FALLING_EDGE = "FallingEdge"
    ANY_EDGE = "AnyEdge"
    LEVEL_HIGH = "LevelHigh"
    LEVEL_LOW = "LevelLow"


@dataclass(frozen=True)
class TriggerConfig:
    """A camera trigger: selector, source and activation (delay in µs)."""

    source: TriggerSource = TriggerSource.FREE_RUN
    activation: TriggerActivation = TriggerActivation.RISING_EDGE
    selector: TriggerSelector = TriggerSelector.FRAME_START
    delay_us: float = 0.0

    def __post_init__(self) -> None:
        for name, cls in (("source", TriggerSource), ("activation", TriggerActivation),
                          ("selector", TriggerSelector)):
            if not isinstance(getattr(self, name), cls):
                raise SettingError(f"`{name}` must be a {cls.__name__}; got {getattr(self, name)!r}")
        if isinstance(self.delay_us, bool) or not isinstance(self.delay_us, Real) \
                or not 0 <= float(self.delay_us) <= 1e6:
            raise SettingError(f"`delay_us` must be between 0 and 1e6 µs; got {self.delay_us!r}")

    @property
    def is_hardware(self) -> bool:
        """True when a hardware line triggers the camera."""
        return self.source.value.startswith("Line")


MAX_CAMERA_EXPOSURE_US = 10_000_000.0


@dataclass(frozen=True)
class CameraSettings:
    """Camera acquisition settings.

    Parameters
    ----------
    exposure_us : float
        Exposure time in µs, in ``(0, 1e7]``.
    trigger : TriggerConfig
        Trigger configuration (default free-running).
    gain_db : float
        Analogue gain in dB, in ``[0, 48]``.
    """

    exposure_us: float
    trigger: TriggerConfig = field(default_factory=TriggerConfig)
    gain_db: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "exposure_us",
                           check_positive_float("exposure_us", self.exposure_us, MAX_CAMERA_EXPOSURE_US, "µs"))
        if not isinstance(self.trigger, TriggerConfig):
            raise SettingError(f"`trigger` must be a TriggerConfig; got {self.trigger!r}")
        if isinstance(self.gain_db, bool) or not isinstance(self.gain_db, Real) \
                or not 0 <= float(self.gain_db) <= 48:
            raise SettingError(f"`gain_db` must be between 0 and 48 dB; got {self.gain_db!r}")


@dataclass(frozen=True)
class CameraCapabilities:
    """What a camera can do; the app greys out what it cannot."""

    hardware_trigger: bool
    """Can start a frame on a trigger line (needed to shutter in sync with the projector)."""
    frame_ids: bool
    """Delivers a device frame counter (so dropped frames show as gaps)."""
    device_timestamps: bool
    """Timestamps come from the device clock (else host arrival time)."""
    trigger_delay: bool = False
    """Delays the exposure after its trigger (:attr:`TriggerConfig.delay_us`; GenICam ``TriggerDelay``).
    Capture uses it to open the exposure on a slot boundary; a camera without it needs the delay set
    another way (and capture asks the operator to confirm it)."""


@dataclass(frozen=True, eq=False)
class Frame:
    """One camera frame.

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Raw pixel values (uint8/uint16, or float32 for simulated frames).
    frame_id : int
        The device's frame counter (or a host counter where the device has none); a gap
        between consecutive ids means dropped frames.
    timestamp_s : float
        Capture time in seconds (device clock where available).
    """

    image: np.ndarray
    frame_id: int
    timestamp_s: float

    def __post_init__(self) -> None:
        if np.ndim(self.image) != 2:
            raise SettingError(f"`image` must have shape (H, W); got shape {np.shape(self.image)}")
        if isinstance(self.frame_id, bool) or not isinstance(self.frame_id, Integral) or self.frame_id < 0:
            raise SettingError(f"`frame_id` must be a whole number >= 0; got {self.frame_id!r}")
        if not isinstance(self.timestamp_s, Real) or not np.isfinite(self.timestamp_s):
            raise SettingError(f"`timestamp_s` must be a finite number of seconds; got {self.timestamp_s!r}")


class Camera(Device):
    """A camera delivering :class:`Frame` objects.

    Implementations provide the ``_do_*`` hooks below. State rules: :meth:`configure`
    needs OPEN or ENABLED and no acquisition; :meth:`start_acquisition` needs ENABLED;
    :meth:`read_frame` needs an acquisition; :meth:`trigger_software` needs an acquisition
    with ``TriggerSource.SOFTWARE``.
    """

    kind = "camera"

    def __init__(self, *, name: str | None = None):
        super().__init__(name=name)
        self._settings: CameraSettings | None = None
        self._acquiring = False

    @property
    @abstractmethod
    def capabilities(self) -> CameraCapabilities:
        """What this camera can do."""

    @property
    @abstractmethod
    def sensor_shape(self) -> tuple[int, int]:
        """Frame size ``(H, W)``."""

    @property
    def settings(self) -> CameraSettings | None:
        """The applied settings, or None before :meth:`configure`."""
        return self._settings

    @property
    def acquiring(self) -> bool:
        """True between :meth:`start_acquisition` and :meth:`stop_acquisition`."""
        return self._acquiring

    def configure(self, settings: CameraSettings) -> None:
        """Apply ``settings``.

        Raises
        ------
        SettingError
            When the camera cannot do it (e.g. a hardware trigger on a camera without one).
        """
        if not isinstance(settings, CameraSettings):
            raise SettingError(f"`settings` must be CameraSettings; got {type(settings).__name__}")
        self._require("configure", DeviceState.OPEN, DeviceState.ENABLED)
        if self._acquiring:
            raise IncompatibleStateError("cannot configure while acquiring: call stop_acquisition() first")
        if settings.trigger.is_hardware and not self.capabilities.hardware_trigger:
            raise SettingError(
                f"{self.name} has no hardware trigger: it cannot shutter in sync with the "
                f"projector; use it for preview and alignment only (trigger source FreeRun)")
        self._do_configure(settings)
        self._settings = settings

    def start_acquisition(self) -> None:
        """Start delivering frames. No-op when already acquiring."""
        self._require("start acquisition", DeviceState.ENABLED)
        if self._settings is None:
            raise IncompatibleStateError("cannot start acquisition: call configure() first")
        if self._acquiring:
            return
        self._do_start_acquisition()
        self._acquiring = True

    def stop_acquisition(self) -> None:
        """Stop delivering frames. No-op when not acquiring."""
        if not self._acquiring:
            return
        try:
            self._do_stop_acquisition()
        finally:
            self._acquiring = False

    def read_frame(self, timeout_s: float = 1.0) -> Frame:
        """Return the next frame, waiting at most ``timeout_s``.

        Raises
        ------
        DeviceTimeoutError
            When no frame arrives in time (a missing trigger, a dropped frame).
        """
        timeout_s = check_timeout(timeout_s)
        if not self._acquiring:
            raise IncompatibleStateError("cannot read a frame: call start_acquisition() first")
        return self._do_read_frame(timeout_s)

    def trigger_software(self) -> None:
        """Fire one frame (trigger source SOFTWARE only)."""
        if not self._acquiring:
            raise IncompatibleStateError("cannot trigger: call start_acquisition() first")
        source = self._settings.trigger.source if self._settings is not None else None
        if source is not TriggerSource.SOFTWARE:
            raise IncompatibleStateError(
                f"cannot trigger by software: the trigger source is {source.value if source else 'not set'}")
        self._do_trigger_software()

    def _do_disable(self) -> None:
        self.stop_acquisition()

    @abstractmethod
    def _do_configure(self, settings: CameraSettings) -> None: ...

    @abstractmethod
    def _do_start_acquisition(self) -> None: ...

    @abstractmethod
    def _do_stop_acquisition(self) -> None: ...

    @abstractmethod
    def _do_read_frame(self, timeout_s: float) -> Frame: ...

    @abstractmethod
    def _do_trigger_software(self) -> None: ...


# --------------------------------------------------------------------------- sync controller

SYNC_MIN_PERIOD_US = 20
SYNC_MAX_PERIOD_US = 1_000_000
SYNC_MAX_PULSES = 1024


@dataclass(frozen=True)
class SyncSettings:
    """A trigger box's timing.

    The box pulses its *pattern* output every ``period_us`` and its *frame* output on
    every ``pulses_per_frame``-th pattern pulse (starting with the first), so one camera
    frame spans ``pulses_per_frame`` projector slots.

    Parameters
    ----------
    period_us : int
        Pattern pulse period, whole µs in ``[20, 1_000_000]``.
    pulses_per_frame : int
        Pattern pulses per frame pulse (K), in ``[1, 1024]``.
    """

    period_us: int
    pulses_per_frame: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "period_us", check_int(
            "period_us", self.period_us, SYNC_MIN_PERIOD_US, SYNC_MAX_PERIOD_US, "µs"))
        object.__setattr__(self, "pulses_per_frame", check_int(
            "pulses_per_frame", self.pulses_per_frame, 1, SYNC_MAX_PULSES))

    @property
    def frame_period_us(self) -> int:
        """Time between frame pulses, ``period_us * pulses_per_frame``."""
        return self.period_us * self.pulses_per_frame


class SyncController(Device):
    """A trigger box driving the projector and the camera from one clock.

    State rules: :meth:`configure` needs OPEN or ENABLED and a stopped box; :meth:`start`
    needs ENABLED and settings; counters need OPEN or ENABLED.
    """

    kind = "sync box"

    def __init__(self, *, name: str | None = None):
        super().__init__(name=name)
        self._settings: SyncSettings | None = None
        self._running = False

    @property
    def settings(self) -> SyncSettings | None:
        """The applied settings, or None."""
        return self._settings

    @property
    def running(self) -> bool:
        """True while pulses are being generated."""
        return self._running

    def configure(self, settings: SyncSettings) -> None:
        """Apply ``settings`` (the box must be stopped)."""
        if not isinstance(settings, SyncSettings):
            raise SettingError(f"`settings` must be SyncSettings; got {type(settings).__name__}")
        self._require("configure", DeviceState.OPEN, DeviceState.ENABLED)
        if self._running:
            raise IncompatibleStateError("cannot configure while running: call stop() first")
        self._do_configure(settings)
        self._settings = settings

    def start(self) -> None:
        """Start pulsing (counters restart at zero). No-op when running."""
        self._require("start", DeviceState.ENABLED)
        if self._settings is None:
            raise IncompatibleStateError("cannot start: call configure() first")
        if self._running:
            return
        self._do_start()
        self._running = True

    def stop(self) -> None:
        """Stop pulsing. No-op when stopped."""
        self._require("stop", DeviceState.OPEN, DeviceState.ENABLED)
        if not self._running:
            return
        try:
            self._do_stop()
        finally:
            self._running = False

    def pulse_count(self) -> int:
        """Pattern pulses emitted since the last start."""
        self._require("read the pulse count", DeviceState.OPEN, DeviceState.ENABLED)
        return self._do_pulse_count()

    def elapsed_us(self) -> int:
        """Microseconds since the last start (box clock)."""
        self._require("read the time", DeviceState.OPEN, DeviceState.ENABLED)
        return self._do_elapsed_us()

    def firmware_version(self) -> str:
        """The box's firmware identification."""
        self._require("read the version", DeviceState.OPEN, DeviceState.ENABLED)
        return self._do_firmware_version()

    def _do_disable(self) -> None:
        self.stop()

    @abstractmethod
    def _do_configure(self, settings: SyncSettings) -> None: ...

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_pulse_count(self) -> int: ...

    @abstractmethod
    def _do_elapsed_us(self) -> int: ...

    @abstractmethod
    def _do_firmware_version(self) -> str: ...


# --------------------------------------------------------------------------- the rig


@runtime_checkable
class Rig(Protocol):
    """A projector, a camera and, optionally, a sync box that work as one flexible-voxel rig.

    Two classes implement it: :class:`~rig_drivers.profile.ProfileRig` (what ``--rig`` names: a
    profile's real devices, or the simulated ones of ``mock``) and
    :class:`~rig_drivers.simulated_rig.SimulatedRig` (the simulated rig itself). Building a rig opens
    no device; each is opened as any other, and :meth:`close` closes them all.
    """

    @property
    def name(self) -> str:
        """The rig's name, as calibration files record it (a calibration is refused on another rig)."""

    @property
    def projector(self) -> Projector:
        """The projector that shutters each camera pixel."""

    @property
    def camera(self) -> Camera:
        """The camera."""

    @property
    def sync(self) -> SyncController | None:
        """The sync box that can clock projector and camera; None when the projector's TRIG_OUT_2 triggers
        the camera."""

    @property
    def trigger_line(self) -> TriggerSource:
        """The camera line the frame trigger arrives on."""

    @property
    def projector_size(self) -> tuple[int, int] | None:
        """The projector's pattern size (rows, columns); None where its driver does not know it."""

    @property
    def pixel_layout(self) -> str:
        """How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`)."""

    @property
    def video_port(self) -> bool:
        """True when the projector takes its patterns on its video input (:attr:`Projector.video_port`)."""

    @property
    def simulated(self) -> object | None:
        """The :class:`~rig_drivers.simulated_rig.SimulatedRig` behind this rig (its clock, its view; itself for
        one); None for real devices."""

    @property
    def truth(self) -> object | None:
        """What a simulated rig hides (:class:`~rig_drivers.simulated_rig.RigTruth`: homography, timing, the
        scene's video), for tests and a capture's ground truth; None for real devices."""

    def close(self) -> None:
        """Close every device (each is closed even when another fails)."""
