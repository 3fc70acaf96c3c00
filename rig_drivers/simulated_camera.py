"""A simulated camera: the scene simulator's exposures delivered as :class:`Frame` objects.

The camera integrates one *exposure* of K slots at a time: exposure ``e`` (a counter since
:meth:`~rig_drivers.interfaces.Device.open`) sees the scene's sub-frames
``(e·K + s) mod S`` for ``s = 0..K-1`` (the scene loops) lit by the light its
:class:`LightPath` says reached each camera pixel in each exposure slot, and the scene's
declared effects are applied by :func:`flexvox_core.simulate.simulator.render_exposures`.

When an exposure starts depends on the trigger:

``FreeRun``
    back to back, one exposure every ``exposure_us`` from :meth:`start_acquisition`;
``Software``
    one exposure per :meth:`trigger_software` call, starting at the call;
``Line0..3``
    at the light path's hardware triggers (in the coupled rig: the projector's TRIG_OUT_2,
    once per sequence). With nothing driving the line no frame ever comes and
    :meth:`read_frame` raises :class:`~rig_drivers.errors.DeviceTimeoutError` after its
    timeout.

Frames as a real machine-vision camera delivers them:

- ``frame_id`` is the exposure counter. A frame lost by the ``dropped_frames`` effect, or
  overwritten because the consumer fell more than ``buffer_frames`` behind, is *skipped*:
  its id is never delivered, so the consumer sees a gap, as with a GenICam camera.
- ``timestamp_s`` is the exposure start on the camera's clock (µs / 1e6).

Time comes from an injectable :class:`SimClock`; :class:`VirtualClock` jumps instead of
sleeping, so tests never wait. :class:`MonotonicClock` (the default) sleeps for real, but
never longer than the ``timeout_s`` of the call.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Protocol

import numpy as np

from flexvox_core.simulate.effects import Effect
from flexvox_core.simulate.simulator import render_exposures
from rig_drivers.errors import DeviceTimeoutError, SettingError
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

DEFAULT_SLOTS = 16
"""Slots per exposure when the light path has no pattern sequence (nothing projected)."""


# --------------------------------------------------------------------------- the scene's video


class SceneVideo:
    """A scene video ``(S, H, W)`` float32 whose shape is known at once and whose pixels come when first read.

    Rendering a built-in scene takes seconds (the drummer's 256 sub-frames: about 12 s on 2 cores); building a
    rig does not render it: the camera's :meth:`~rig_drivers.interfaces.Device.open` does (before any exposure
    is timed), or the first read of :attr:`array`.

    Parameters
    ----------
    shape : (S, H, W)
    render : callable
        ``render() -> ndarray`` of that shape, called once.
    """

    def __init__(self, shape: tuple[int, int, int], render: Callable[[], np.ndarray]):
        if len(shape) != 3 or min(shape) < 1:
            raise SettingError(f"a scene video's shape must be (S, H, W) with S, H, W >= 1; got {shape}")
        self._shape = (int(shape[0]), int(shape[1]), int(shape[2]))
        self._render: Callable[[], np.ndarray] | None = render
        self._array: np.ndarray | None = None
        self._lock = threading.Lock()

    @classmethod
    def of(cls, video) -> SceneVideo:
        """An already rendered video ``(S, H, W)`` (floating point kept, else float32)."""
        video = np.asarray(video)
        if video.ndim != 3 or video.shape[0] < 1 or min(video.shape[1:]) < 1:
            raise SettingError(f"`video` must have shape (S, H, W) with S, H, W >= 1; got {video.shape}")
        if not np.issubdtype(video.dtype, np.floating):
            video = video.astype(np.float32)
        scene = cls(video.shape, lambda: video)
        scene._array, scene._render = video, None
        return scene

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(S, H, W)``."""
        return self._shape

    @property
    def rendered(self) -> bool:
        """True once the pixels exist."""
        return self._array is not None

    @property
    def array(self) -> np.ndarray:
        """The pixels, rendered on the first read."""
        if self._array is None:
            with self._lock:
                if self._array is None:
                    assert self._render is not None
                    video = np.asarray(self._render())
                    if video.shape != self._shape:
                        raise SettingError(f"the scene rendered {video.shape}, not its declared {self._shape}")
                    self._array, self._render = video, None
        return self._array


# --------------------------------------------------------------------------- clocks


class SimClock(Protocol):
    """Time for simulated devices, in whole microseconds."""

    def now_us(self) -> int:
        """The current time."""

    def sleep_until_us(self, t_us: int) -> None:
        """Return when the time is at least ``t_us`` (immediately when it already is)."""


class MonotonicClock:
    """Real time: ``time.monotonic_ns`` and ``time.sleep``."""

    def __repr__(self) -> str:
        return "<MonotonicClock: real time>"

    def now_us(self) -> int:
        """The monotonic clock in µs."""
        return time.monotonic_ns() // 1000

    def sleep_until_us(self, t_us: int) -> None:
        """Sleep until ``t_us`` (callers bound ``t_us`` by their timeout)."""
        delay = (int(t_us) - self.now_us()) / 1e6
        if delay > 0:
            time.sleep(delay)


class VirtualClock:
    """Simulated time that jumps: :meth:`sleep_until_us` advances it instantly.

    Parameters
    ----------
    start_us : int
        The initial time.
    """

    def __init__(self, start_us: int = 0):
        self.now = int(start_us)

    def __repr__(self) -> str:
        return f"<VirtualClock at {self.now} µs>"

    def now_us(self) -> int:
        """The current virtual time."""
        return self.now

    def __call__(self) -> int:
        """Same as :meth:`now_us` (a plain ``clock_us`` callable for the projector)."""
        return self.now

    def sleep_until_us(self, t_us: int) -> None:
        """Jump to ``t_us`` when it lies ahead."""
        self.now = max(self.now, int(t_us))

    def advance(self, us: int) -> None:
        """Move time forward by ``us`` µs."""
        if us < 0:
            raise SettingError(f"`us` must be >= 0 (time does not run backwards); got {us}")
        self.now += int(us)


# --------------------------------------------------------------------------- light paths


class LightPath(Protocol):
    """What reaches the camera from the projector: hardware triggers and per-slot light."""

    def slots(self) -> int | None:
        """K of the pattern sequence in use, or None when none is loaded."""

    def next_trigger_us(self, line: TriggerSource, after_us: int, now_us: int) -> tuple[int, int] | None:
        """``(time, period)`` of the first trigger on ``line`` at or after ``after_us`` (µs).

        ``period`` is the spacing of the following triggers (µs). None when no trigger
        will come (nothing drives the line).
        """

    def exposure_light(self, start_us: int, now_us: int, K: int, height: int, width: int) -> np.ndarray | None:
        """Light per exposure slot, ``(K, H, W)`` float32 in [0, 1], for an exposure
        starting at ``start_us``; None when no projected light reaches the camera."""

    def warm_up(self) -> None:
        """Compute now what the first exposure would otherwise compute (the patterns in camera pixels)."""


class DarkLightPath:
    """No projector: no hardware triggers and no projected light (only ambient effects)."""

    def slots(self) -> int | None:
        """No sequence."""
        return None

    def next_trigger_us(self, line: TriggerSource, after_us: int, now_us: int) -> tuple[int, int] | None:
        """Nothing drives any trigger line."""
        return None

    def exposure_light(self, start_us, now_us, K, height, width) -> np.ndarray | None:
        """Dark."""
        return None

    def warm_up(self) -> None:
        """Nothing to compute."""


# --------------------------------------------------------------------------- the camera


class SimulatedCamera(Camera):
    """A camera that renders the scene simulator's frames, on an injectable clock.

    Parameters
    ----------
    video : ndarray, shape (S, H, W), or SceneVideo
        The scene's radiance per sub-frame in [0, 1]; it loops. The frame size is (H, W). A
        :class:`SceneVideo` not rendered yet is rendered by :meth:`~rig_drivers.interfaces.Device.open`.
    effects : list of Effect
        The scene's declared effects (only these are simulated).
    seed : int
        Seeds every effect; the noise of exposure ``e`` uses stream ``e``, so a seed and a
        sequence of calls give the same frames every time.
    electrons_per_unit : float
        Electrons from a white scene in one open slot (the sensor effects' scale).
    light_path : LightPath, optional
        Where the light and the hardware triggers come from (default: dark, no triggers).
    clock : SimClock, optional
        Default :class:`MonotonicClock`.
    buffer_frames : int
        Completed frames the camera holds for a slow consumer; older ones are lost (gaps).
    default_slots : int
        Slots per exposure when no pattern sequence is loaded.
    """

    def __init__(self, video, *, effects: list[Effect] | tuple = (), seed: int = 0,
                 electrons_per_unit: float = 1000.0, light_path: LightPath | None = None,
                 clock: SimClock | None = None, buffer_frames: int = 16,
                 default_slots: int = DEFAULT_SLOTS, name: str | None = None):
        super().__init__(name=name or "simulated camera")
        self._scene = video if isinstance(video, SceneVideo) else SceneVideo.of(video)
        self._effects = list(effects)
        for e in self._effects:
            if not isinstance(e, Effect):
                raise SettingError(f"`effects` must hold Effect objects; got {type(e).__name__}")
        self._seed = check_int("seed", seed, 0, 2**63 - 1)
        if isinstance(electrons_per_unit, bool) or not electrons_per_unit > 0:
            raise SettingError(f"`electrons_per_unit` must be > 0; got {electrons_per_unit!r}")
        self._electrons_per_unit = float(electrons_per_unit)
        self._light_path = light_path or DarkLightPath()
        self._clock = clock or MonotonicClock()
        self._buffer_frames = check_int("buffer_frames", buffer_frames, 1, 10_000)
        self._default_slots = check_int("default_slots", default_slots, 1, 1024)
        self._exposures = 0
        self._next_start_us: int | None = None
        self._hw_cursor_us = 0
        self._soft_triggers: deque[int] = deque()
        self.dropped_ids: list[int] = []
        """Frame ids lost so far (dropped frames and buffer overruns); for tests and logs."""

    # ------------------------------------------------------------------ properties
    @property
    def capabilities(self) -> CameraCapabilities:
        """A machine-vision camera: trigger line (with a delay), frame counter, device clock."""
        return CameraCapabilities(hardware_trigger=True, frame_ids=True, device_timestamps=True, trigger_delay=True)

    @property
    def sensor_shape(self) -> tuple[int, int]:
        """``(H, W)`` of the scene video."""
        return self._scene.shape[1], self._scene.shape[2]

    @property
    def scene(self) -> SceneVideo:
        """The scene video the camera looks at now."""
        return self._scene

    @property
    def clock(self) -> SimClock:
        """The camera's clock."""
        return self._clock

    def set_view(self, video, effects: list[Effect] | tuple = ()) -> None:
        """Look at another scene ``(S, H, W)`` of the same size, met with ``effects`` (e.g. a calibration target).

        Exposures go on counting (frame ids and noise streams continue); the new video starts
        at its sub-frame ``(e·K) mod S`` like the old one. An open camera renders a :class:`SceneVideo` now.
        """
        scene = video if isinstance(video, SceneVideo) else SceneVideo.of(video)
        if scene.shape[1:] != self.sensor_shape:
            raise SettingError(f"`video` must have shape (S, {self.sensor_shape[0]}, {self.sensor_shape[1]}); "
                               f"got {scene.shape}")
        effects = list(effects)
        for e in effects:
            if not isinstance(e, Effect):
                raise SettingError(f"`effects` must hold Effect objects; got {type(e).__name__}")
        if self.state is not DeviceState.CLOSED:
            scene.array  # noqa: B018 - rendered before the next exposure is timed
        self._scene = scene
        self._effects = effects

    def subframes_of(self, frame_id: int, K: int) -> np.ndarray:
        """Scene sub-frame indices integrated by exposure ``frame_id`` with K slots."""
        return (int(frame_id) * K + np.arange(K)) % self._scene.shape[0]

    # ------------------------------------------------------------------ hooks
    def _do_open(self) -> None:
        self._scene.array  # noqa: B018 - a scene not rendered yet is rendered here, before any exposure is timed
        self._exposures = 0
        self.dropped_ids = []

    def _do_close(self) -> None:
        self._soft_triggers.clear()

    def _do_configure(self, settings: CameraSettings) -> None:
        _logger.debug("%s: exposure %g µs, trigger %s", self.name, settings.exposure_us,
                      settings.trigger.source.value)

    def _do_start_acquisition(self) -> None:
        self._warm_up()
        now = self._clock.now_us()
        self._next_start_us = now
        self._hw_cursor_us = now
        self._soft_triggers.clear()

    def _warm_up(self) -> None:
        """Before the first trigger can come: compute what the first exposure would (the loaded patterns in camera
        pixels, the renderer's first pass), so the simulation's own start-up costs the capture no frame. A clock
        paced to the wall (one with ``resync()``: its time stands still between sleeps) is then brought up to the
        wall, so the warm-up does not look like frames the camera overran."""
        t0 = time.perf_counter()
        warm_up = getattr(self._light_path, "warm_up", None)
        if warm_up is not None:
            warm_up()
        H, W = self.sensor_shape
        K = self._light_path.slots() or self._default_slots
        render_exposures(self._scene.array[self.subframes_of(0, K)], np.zeros((K, H, W), np.float32),
                         effects=self._effects, seed=self._seed, stream=0, rate_hz=15.0,
                         electrons_per_unit=self._electrons_per_unit)
        resync = getattr(self._clock, "resync", None)
        if resync is not None:
            resync()
        _logger.debug("%s: warmed up in %.3f s", self.name, time.perf_counter() - t0)

    def _do_stop_acquisition(self) -> None:
        self._next_start_us = None
        self._soft_triggers.clear()

    def _do_trigger_software(self) -> None:
        self._soft_triggers.append(self._clock.now_us())
        while len(self._soft_triggers) > self._buffer_frames:
            self._soft_triggers.popleft()
            self._lose(self._exposures, "buffer overrun")

    # ------------------------------------------------------------------ timing
    def _exposure_us(self) -> int:
        return max(1, int(round(self._settings.exposure_us)))

    def _next_exposure(self, now: int) -> tuple[int, int, int] | None:
        """``(start, duration, period)`` of the next exposure to deliver, or None."""
        source = self._settings.trigger.source
        if source is TriggerSource.SOFTWARE:
            if not self._soft_triggers:
                return None
            duration = self._exposure_us()
            return self._soft_triggers[0], duration, duration
        if source is TriggerSource.FREE_RUN:
            duration = self._exposure_us()
            return self._next_start_us, duration, duration
        nxt = self._light_path.next_trigger_us(source, self._hw_cursor_us, now)
        if nxt is None:
            return None
        trigger, period = nxt
        # The exposure starts after the camera's own trigger delay and integrates one
        # sequence (the time to the next trigger).
        return trigger + self._trigger_delay_us(), max(1, period), max(1, period)

    def _trigger_delay_us(self) -> int:
        return int(round(self._settings.trigger.delay_us))

    def _consume(self, start: int, period: int, count: int = 1) -> None:
        source = self._settings.trigger.source
        if source is TriggerSource.SOFTWARE:
            self._soft_triggers.popleft()
        elif source is TriggerSource.FREE_RUN:
            self._next_start_us = start + count * period
        else:
            trigger = start - self._trigger_delay_us()
            self._hw_cursor_us = trigger + (count - 1) * period + 1

    def _lose(self, exposure: int, why: str) -> None:
        self.dropped_ids.append(exposure)
        self._exposures = exposure + 1
        _logger.debug("%s: frame %d lost (%s)", self.name, exposure, why)

    def _dropped(self, exposure: int) -> bool:
        for e in self._effects:
            if e.stage == "frames":
                # The draw render_exposures makes for stream `exposure` (one frame).
                return bool(e.drops(1, e.rng(self._seed, exposure))[0])
        return False

    # ------------------------------------------------------------------ reading
    def _do_read_frame(self, timeout_s: float) -> Frame:
        now = self._clock.now_us()
        deadline = now + int(math.ceil(timeout_s * 1e6))
        # Bounded: each pass consumes one exposure that ends before the deadline.
        for _ in range(100_000):
            nxt = self._next_exposure(now)
            if nxt is None:
                break
            start, duration, period = nxt
            # Frames completed long ago were overwritten in the camera's buffer.
            waiting = (now - start - duration) // period + 1 if now >= start + duration else 0
            if waiting > self._buffer_frames and self._settings.trigger.source is not TriggerSource.SOFTWARE:
                lost = int(waiting - self._buffer_frames)
                first = self._exposures
                self.dropped_ids.extend(range(first, first + lost))
                self._exposures += lost
                _logger.debug("%s: %d frames lost (buffer overrun)", self.name, lost)
                self._consume(start, period, lost)
                continue
            end = start + duration
            if end > deadline:
                break
            self._clock.sleep_until_us(end)
            now = max(now, end)
            exposure = self._exposures
            self._consume(start, period)
            if self._dropped(exposure):
                self._lose(exposure, "dropped_frames effect")
                continue
            self._exposures = exposure + 1
            image = self._render(exposure, start, now, duration)
            return Frame(image, frame_id=exposure, timestamp_s=start / 1e6)
        self._clock.sleep_until_us(deadline)
        raise DeviceTimeoutError(
            f"{self.name}: no frame within {timeout_s:g} s (trigger source "
            f"{self._settings.trigger.source.value}: " + self._why_no_frame() + ")")

    def _why_no_frame(self) -> str:
        source = self._settings.trigger.source
        if source is TriggerSource.SOFTWARE:
            return "call trigger_software() for each frame"
        if source is TriggerSource.FREE_RUN:
            return "the exposure is longer than the timeout"
        return "is the projector running and its trigger output wired to the camera?"

    def _render(self, exposure: int, start: int, now: int, duration: int) -> np.ndarray:
        H, W = self.sensor_shape
        K = self._light_path.slots() or self._default_slots
        light = self._light_path.exposure_light(start, now, K, H, W)
        if light is None:
            light = np.zeros((K, H, W), np.float32)
        K = light.shape[0]
        video = self._scene.array[self.subframes_of(exposure, K)]
        frames, _dropped, _storage = render_exposures(
            video, light, effects=self._effects, seed=self._seed, stream=exposure,
            rate_hz=1e6 / duration, electrons_per_unit=self._electrons_per_unit)
        return frames[0]
