"""Counters and pictures of a live camera stream (Qt-free): fps, drops, histogram, saturation."""

from __future__ import annotations

from collections import deque

import numpy as np

from rig_drivers.interfaces import Frame


def saturation_level(image: np.ndarray) -> float:
    """The value at which a pixel counts as saturated: the integer type's maximum, or 1.0 for
    float frames (relative units, where 1 is a white scene in one open slot)."""
    dt = np.asarray(image).dtype
    if np.issubdtype(dt, np.integer):
        return float(np.iinfo(dt).max)
    return 1.0


def histogram(image: np.ndarray, *, bins: int = 64, top: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Counts and bin edges of ``image`` over [0, top] (default its saturation level)."""
    top = saturation_level(image) if top is None else float(top)
    counts, edges = np.histogram(np.asarray(image, dtype=np.float32), bins=bins, range=(0.0, top))
    return counts, edges


def saturation_mask(image: np.ndarray, level: float | None = None) -> np.ndarray:
    """Bool (H, W): pixels at or above the saturation level."""
    level = saturation_level(image) if level is None else float(level)
    return np.asarray(image) >= level


class LiveStats:
    """Running counters of a live view.

    Parameters
    ----------
    window : int
        Frames over which the frame rate is measured.
    """

    def __init__(self, window: int = 30):
        if window < 2:
            raise ValueError(f"`window` must be >= 2; got {window}")
        self._times: deque[float] = deque(maxlen=window)
        self.received = 0
        self.dropped = 0
        self.last_id: int | None = None
        self.saturated_fraction = 0.0

    def update(self, frame: Frame, *, level: float | None = None) -> None:
        """Count ``frame``: gaps in frame ids are dropped frames; the fps uses its timestamp."""
        if self.last_id is not None and frame.frame_id > self.last_id + 1:
            self.dropped += frame.frame_id - self.last_id - 1
        self.last_id = frame.frame_id
        self.received += 1
        self._times.append(frame.timestamp_s)
        self.saturated_fraction = float(saturation_mask(frame.image, level).mean())

    @property
    def fps(self) -> float:
        """Frames per second over the window (0 until two frames arrived)."""
        if len(self._times) < 2 or self._times[-1] <= self._times[0]:
            return 0.0
        return (len(self._times) - 1) / (self._times[-1] - self._times[0])

    def text(self) -> str:
        """One line for the status bar of the live view."""
        return (f"{self.fps:.1f} fps · {self.received} frames · {self.dropped} dropped · "
                f"{self.saturated_fraction:.1%} saturated")
