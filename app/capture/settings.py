"""A capture's timing beyond the plan's rate, and the bounded queue between camera and disk."""

from __future__ import annotations

from dataclasses import dataclass

from flexvox_app.capture.rig_setup import CaptureError


@dataclass(frozen=True)
class SyncSetting:
    """Timing of a capture beyond the plan's rate.

    Parameters
    ----------
    use_sync_box : bool or None
        Drive projector and camera from the rig's sync box (None: when the rig has one).
    delay_set_by_hand : bool
        The operator has set the calibration's camera trigger delay on a camera that cannot be
        told it (no trigger-delay feature), e.g. in the vendor's tool. Without it such a camera
        refuses a calibration that needs a delay.
    read_slice_s : float
        Longest single wait for a frame (stop() is noticed within it).
    no_frame_timeout_s : float or None
        Capture stops with an error when no frame arrives for this long
        (None: ``max(2 s, 10 frame periods)``).
    """

    use_sync_box: bool | None = None
    delay_set_by_hand: bool = False
    read_slice_s: float = 0.2
    no_frame_timeout_s: float | None = None

    def __post_init__(self):
        if not 0 < self.read_slice_s <= 5:
            raise CaptureError(f"`read_slice_s` must be in (0, 5] s; got {self.read_slice_s!r}")

    def no_frame_s(self, camera_hz: float) -> float:
        """The no-frame timeout in seconds for a camera at ``camera_hz``."""
        if self.no_frame_timeout_s is not None:
            return float(self.no_frame_timeout_s)
        return max(2.0, 10.0 / camera_hz)


@dataclass(frozen=True)
class QueuePolicy:
    """The bounded queue between camera and disk (see :mod:`flexvox_app.capture.service`).

    Parameters
    ----------
    capacity : int
        Frames held at most.
    block_s : float
        How long the camera reader waits for room before it discards a frame.
    """

    capacity: int = 64
    block_s: float = 0.5

    def __post_init__(self):
        if isinstance(self.capacity, bool) or not isinstance(self.capacity, int) or not 1 <= self.capacity <= 100_000:
            raise CaptureError(f"`capacity` must be a whole number 1..100000; got {self.capacity!r}")
        if not 0 <= self.block_s <= 60:
            raise CaptureError(f"`block_s` must be between 0 and 60 s; got {self.block_s!r}")
