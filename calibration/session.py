"""A rig session for calibration: show a pattern, grab frames taken after the change.

Every calibration step talks to the rig through :class:`RigSession`. It owns one rule that
every wizard needs: **a frame counts only if it was exposed after the pattern changed.**
The session stops the projector, drains every frame still queued in the camera (their ids
are remembered), loads the new sequence, starts it, and then accepts only frames whose
``frame_id`` is larger than the last id seen before the change, after skipping
``settle_frames`` more (a real projector may show a partial first sequence). No sleeps:
the camera's frame ids and its read timeout do the waiting.

Static patterns are shown as a sequence of ``slots`` copies of the same pattern (the
camera, triggered once per sequence by the projector's TRIG_OUT_2 or by the sync box,
integrates the pattern over the whole exposure).

A projector that takes its patterns on a video input (the DLPC350) says how to run a
sequence from it with ``projector.video_sequence(patterns, period_us, repeat=)`` (VSYNC
triggers, as many patterns per VSYNC as fit); the session uses it when no sync box drives
the projector. Such a projector shows the patterns' frames through its display sink inside
``load_sequence``, which returns once they are on the screen, so the frame-id rule below
holds for it too.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from flexvox_calibration.errors import CalibrationError
from rig_drivers.errors import DeviceTimeoutError
from rig_drivers.interfaces import (
    CameraSettings,
    DeviceState,
    Frame,
    PatternSequence,
    ProjectorTrigger,
    Rig,
    SyncSettings,
    TriggerConfig,
    TriggerSource,
)
from rig_drivers.pixel_layout import check_layout

_logger = logging.getLogger(__name__)

DEFAULT_PERIOD_US = 4166
"""Pattern period of calibration sequences (240 Hz slots, the paper's rate)."""

EXPOSURE_MARGIN_US = 300
"""Camera exposure = sequence length minus this (the camera must be ready for the next trigger)."""

MAX_DRAIN_FRAMES = 64
"""Most queued frames drained before a pattern change (bounded: a free-running camera never empties)."""


@dataclass(frozen=True)
class RigIdentity:
    """What a calibration file is tied to.

    Attributes
    ----------
    name : str
        The rig's name (profile ``name``, or ``simulated rig (mock, seed S)``).
    camera : str
        The camera's name.
    projector : str
        The projector's name.
    camera_size, projector_size : (H, W)
        Resolutions in pixels.
    pixel_layout : str
        How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`): a homography fitted in
        one layout's mirror coordinates is wrong in another's.
    """

    name: str
    camera: str
    projector: str
    camera_size: tuple[int, int]
    projector_size: tuple[int, int]
    pixel_layout: str = "square"

    def as_dict(self) -> dict:
        """JSON-ready form."""
        return {"name": self.name, "camera": self.camera, "projector": self.projector,
                "camera_size": list(self.camera_size), "projector_size": list(self.projector_size),
                "pixel_layout": self.pixel_layout}


def _size(name: str, value) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in value)
    except (TypeError, ValueError):
        raise CalibrationError(f"`{name}` must be (H, W) in pixels; got {value!r}") from None
    if h < 2 or w < 2:
        raise CalibrationError(f"`{name}` must be at least 2x2 pixels; got {h}x{w}")
    return h, w


class RigSession:
    """Drive a projector and a camera (and optionally a sync box) for calibration.

    Parameters
    ----------
    projector : Projector
    camera : Camera
    sync : SyncController, optional
        A sync box that triggers both the projector and the camera. When given, it is
        configured with the sequence timing and started with every sequence, and the
        projector waits for its external trigger. None: the projector's TRIG_OUT_2 (or
        the camera's own clock) triggers the camera.
    projector_size : (H, W), optional
        The projector's resolution; default its driver's ``size`` (:attr:`Projector.size`).
    trigger : TriggerConfig, optional
        Camera trigger; default a rising edge on ``Line0``.
    period_us : int
        Pattern period of every sequence.
    slots : int
        Copies of a static pattern per sequence (one camera exposure).
    settle_frames : int
        Frames skipped after a pattern change, on top of the frame-id rule.
    timeout_s : float
        Longest wait for one frame.
    rig_name : str
        Recorded in calibration files.
    free_run_period_us : float, optional
        A free-running camera's frame period (its exposure); default one sequence.
    """

    def __init__(self, projector, camera, *, sync=None, projector_size=None, trigger: TriggerConfig | None = None,
                 period_us: int = DEFAULT_PERIOD_US, slots: int = 4, settle_frames: int = 1,
                 timeout_s: float = 1.0, rig_name: str = "rig",
                 free_run_period_us: float | None = None):
        self.projector = projector
        self.camera = camera
        self.sync = sync
        size = projector_size if projector_size is not None else projector.size
        if size is None:
            raise CalibrationError("`projector_size` is needed: this projector driver does not report its "
                                   "resolution")
        self.projector_size = _size("projector_size", size)
        self.pixel_layout = check_layout(projector.pixel_layout)
        """How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`), as its driver says."""
        self.trigger = trigger or TriggerConfig(source=TriggerSource.LINE0)
        if not isinstance(self.trigger, TriggerConfig):
            raise CalibrationError(f"`trigger` must be a TriggerConfig; got {trigger!r}")
        if isinstance(slots, bool) or not isinstance(slots, int) or not 1 <= slots <= 128:
            raise CalibrationError(f"`slots` must be a whole number 1..128; got {slots!r}")
        if isinstance(settle_frames, bool) or not isinstance(settle_frames, int) or not 0 <= settle_frames <= 16:
            raise CalibrationError(f"`settle_frames` must be a whole number 0..16; got {settle_frames!r}")
        self.period_us = int(period_us)
        self.slots = slots
        self.settle_frames = settle_frames
        self.timeout_s = float(timeout_s)
        self.rig_name = str(rig_name)
        self.free_run_period_us = free_run_period_us
        self._last_id = -1
        self._camera_delay_us = 0.0
        self._camera_slots = 0
        self._changed_at = -1
        self.frames_read = 0
        """Frames delivered to calibration steps so far (for progress and logs)."""

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_rig(cls, rig: Rig, **kwargs) -> RigSession:
        """A session on a :class:`rig_drivers.interfaces.Rig` (``open_rig(...)``, or a simulated rig): its
        trigger line, name and projector size unless ``kwargs`` give them.

        With the simulated rig the sync box is not used (its projector triggers the camera).
        """
        kwargs.setdefault("trigger", TriggerConfig(source=rig.trigger_line))
        kwargs.setdefault("rig_name", rig.name)
        if kwargs.get("projector_size") is None:
            kwargs["projector_size"] = rig.projector_size
        sync = None if rig.simulated is not None else rig.sync
        return cls(rig.projector, rig.camera, sync=sync, **kwargs)

    @property
    def camera_size(self) -> tuple[int, int]:
        """``(H, W)`` of the camera."""
        return tuple(int(v) for v in self.camera.sensor_shape)

    @property
    def identity(self) -> RigIdentity:
        """What calibration files made with this session are tied to."""
        return RigIdentity(self.rig_name, self.camera.name, self.projector.name, self.camera_size,
                           self.projector_size, self.pixel_layout)

    # ------------------------------------------------------------------ lifecycle
    def open(self) -> None:
        """Open and enable every device that is closed (already open devices are kept)."""
        for dev in (self.projector, self.camera, self.sync):
            if dev is None:
                continue
            if dev.state is DeviceState.CLOSED:
                dev.open()
            dev.enable()
        self._configure_camera(self.slots)

    def close(self) -> None:
        """Stop and close every device."""
        for dev in (self.camera, self.projector, self.sync):
            if dev is not None:
                dev.close()

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ camera
    def _configure_camera(self, slots: int, delay_us: float | None = None) -> None:
        delay = self._camera_delay_us if delay_us is None else float(delay_us)
        trig = TriggerConfig(source=self.trigger.source, activation=self.trigger.activation,
                             selector=self.trigger.selector, delay_us=delay)
        exposure = max(1.0, slots * self.period_us - EXPOSURE_MARGIN_US) if self.trigger.is_hardware \
            else float(self.free_run_period_us or slots * self.period_us)
        self.camera.stop_acquisition()
        self.camera.configure(CameraSettings(exposure_us=exposure, trigger=trig))
        self.camera.start_acquisition()
        self._camera_delay_us = delay
        self._camera_slots = slots

    def set_camera_delay(self, delay_us: float) -> None:
        """Set the camera's trigger delay (µs) for the following captures."""
        self._drain()
        self._configure_camera(self._camera_slots or self.slots, delay_us)

    @property
    def camera_delay_us(self) -> float:
        """The camera trigger delay now in use."""
        return self._camera_delay_us

    def _read(self) -> Frame:
        frame = self.camera.read_frame(self.timeout_s)
        self._last_id = max(self._last_id, frame.frame_id)
        return frame

    def _drain(self) -> None:
        """Stop the projector and read out every queued frame (bounded)."""
        if self.sync is not None and self.sync.running:
            self.sync.stop()
        self.projector.stop()
        for _ in range(MAX_DRAIN_FRAMES):
            try:
                frame = self.camera.read_frame(min(self.timeout_s, 0.05))
            except DeviceTimeoutError:
                return
            self._last_id = max(self._last_id, frame.frame_id)
        _logger.warning("the camera kept delivering frames with the projector stopped: it is not triggered "
                        "by the projector (free-running?)")

    # ------------------------------------------------------------------ showing patterns
    def show(self, patterns, *, repeat: bool = True) -> None:
        """Show ``patterns`` ``(K, Hp, Wp)`` bool as one sequence (one camera exposure)."""
        pats = np.asarray(patterns, dtype=bool)
        if pats.ndim != 3 or pats.shape[1:] != self.projector_size:
            raise CalibrationError(f"`patterns` must be (K, {self.projector_size[0]}, {self.projector_size[1]}) "
                                   f"projector pixels; got {pats.shape}")
        self._drain()
        K = pats.shape[0]
        if self.sync is not None:
            seq = PatternSequence(pats, self.period_us, self.period_us, trigger=ProjectorTrigger.EXTERNAL_RISING,
                                  patterns_per_trigger=1, repeat=repeat)
        elif self.projector.video_port:
            seq = self.projector.video_sequence(pats, self.period_us, repeat=repeat)
        else:
            seq = PatternSequence(pats, self.period_us, self.period_us, repeat=repeat)
        self.projector.load_sequence(seq)
        if K != self._camera_slots:
            self._configure_camera(K)
        self.projector.start()
        if self.sync is not None:
            self.sync.configure(SyncSettings(period_us=self.period_us, pulses_per_frame=K))
            self.sync.start()
        self._changed_at = self._last_id

    def frames(self, n: int = 1) -> list[Frame]:
        """``n`` frames exposed after the last :meth:`show` (skipping ``settle_frames``)."""
        out: list[Frame] = []
        skipped = 0
        for _ in range(n + self.settle_frames + MAX_DRAIN_FRAMES):
            frame = self._read()
            if frame.frame_id <= self._changed_at:
                continue
            if skipped < self.settle_frames:
                skipped += 1
                continue
            out.append(frame)
            self.frames_read += 1
            if len(out) == n:
                return out
        raise CalibrationError(f"the camera delivered only frames taken before the pattern change "
                               f"(after {MAX_DRAIN_FRAMES} frames)")

    def capture(self, pattern, *, average: int = 1) -> np.ndarray:
        """The mean of ``average`` frames of one static projector ``pattern`` ``(Hp, Wp)``, float64."""
        pat = np.asarray(pattern, dtype=bool)
        self.show(np.repeat(pat[None], self.slots, axis=0))
        frames = self.frames(average)
        return np.mean([f.image.astype(np.float64) for f in frames], axis=0)

    def capture_single_shot(self, patterns) -> np.ndarray:
        """Play ``patterns`` once (no repeat) and return the frame its trigger exposed, float64."""
        self.show(patterns, repeat=False)
        saved, self.settle_frames = self.settle_frames, 0  # a single shot triggers exactly one frame
        try:
            frame = self.frames(1)[0]
        finally:
            self.settle_frames = saved
        return frame.image.astype(np.float64)
