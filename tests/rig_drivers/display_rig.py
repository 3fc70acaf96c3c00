"""A DLPC350 on the fake transport whose display sink is a 'screen' a fake camera looks at.

The camera sees only what reached the projector's video input through the display sink: the
packed frames are unpacked, each slot's pattern averaged over the exposure (the K slots of the
loaded sequence), and imaged one projector pixel per camera pixel with a little defocus and seeded noise.
It is triggered by the projector (TRIG_OUT_2): while the sequence is stopped no frame comes
(``read_frame`` times out at once), so the calibration session's drain and frame-id rules are
exercised for real.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from rig_drivers.dlpc350.bitplanes import unpack_bitplanes
from rig_drivers.errors import DeviceTimeoutError
from rig_drivers.interfaces import (
    Camera,
    CameraCapabilities,
    Frame,
    RunState,
    TriggerSource,
)
from rig_drivers.profile import DeviceSpec, ProfileRig, RigSpec


class RecordingScreen:
    """A display sink that keeps every call: the frames and the projector's run state at that moment."""

    def __init__(self):
        self.calls: list[np.ndarray] = []
        self.run_states: list[RunState] = []
        self.projector: DLPC350 | None = None

    def __call__(self, frames: np.ndarray) -> None:
        self.calls.append(np.array(frames, copy=True))
        if self.projector is not None:
            self.run_states.append(self.projector.run_state)

    @property
    def current(self) -> np.ndarray | None:
        return self.calls[-1] if self.calls else None


class ScreenCamera(Camera):
    """Sees the projector's video input (what the display sink last received) while the sequence runs."""

    def __init__(self, projector: DLPC350, screen, shape=(48, 64), *, seed: int = 0):
        super().__init__(name="screen camera")
        self.projector = projector
        self.screen = screen
        self.shape = tuple(shape)
        self._rng = np.random.default_rng(seed)
        self._id = 0

    @property
    def capabilities(self) -> CameraCapabilities:
        return CameraCapabilities(hardware_trigger=True, frame_ids=True, device_timestamps=False)

    @property
    def sensor_shape(self) -> tuple[int, int]:
        return self.shape

    def _do_open(self) -> None:
        """Nothing to open: the camera is a view of the display sink."""

    def _do_close(self) -> None:
        """Nothing to close."""

    def _do_configure(self, settings) -> None:
        """Settings do not change what this fake sees."""

    def _do_start_acquisition(self) -> None:
        """Frames come whenever the projector runs; nothing to start."""

    def _do_stop_acquisition(self) -> None:
        """Nothing to stop."""

    def _do_trigger_software(self) -> None:
        """Triggered by the projector only; a software trigger does nothing."""

    def _do_read_frame(self, timeout_s: float) -> Frame:
        seq = self.projector.sequence
        frames = self.screen.current
        if self.projector.run_state is not RunState.RUNNING or seq is None or frames is None:
            raise DeviceTimeoutError(f"no trigger within {timeout_s:g} s (the projector is stopped)")
        light = gaussian_filter(unpack_bitplanes(frames, seq.K).mean(axis=0), 0.7)  # a little defocus
        H, W = self.shape
        image = 0.05 + 0.85 * light[:H, :W] + self._rng.normal(0.0, 0.002, (H, W))
        self._id += 1
        return Frame(image.astype(np.float32), self._id, self._id / 15.0)


def display_rig(screen=None, *, shape=(48, 64)) -> ProfileRig:
    """A real-rig :class:`~rig_drivers.profile.ProfileRig`: DLPC350 (fake USB) + :class:`ScreenCamera`, TRIG_OUT_2
    sync."""
    screen = RecordingScreen() if screen is None else screen
    projector = DLPC350(FakeDLPC350Transport(), poll_interval_s=0, display=screen)
    projector.size = tuple(shape)  # a DMD as small as the camera (the real one is 1140 x 912), so tests are quick
    if isinstance(screen, RecordingScreen):
        screen.projector = projector
    camera = ScreenCamera(projector, screen, shape)
    spec = RigSpec(name="display test rig", projector=DeviceSpec("dlpc350"),
                   camera=DeviceSpec("genicam", {"cti": "none.cti"}), sync=DeviceSpec("projector-trigger"))
    assert spec.trigger_line is TriggerSource.LINE0
    return ProfileRig(projector, camera, None, spec)
