"""A simulated-rig clock paced to real time, for demos and rate benchmarks.

:class:`~rig_drivers.simulated_camera.MonotonicClock` reads the wall clock at every call, so
time moves while one frame is being computed (the rig now asks the projector for its state
at the camera's reading, so this no longer repeats exposures). :class:`PacedClock` goes
further: its time is *virtual* (constant between sleeps) and only :meth:`sleep_until_us`
moves it, after sleeping for real until the wall clock reaches the target, so every frame
is computed at one instant. When the consumer is late, time jumps to the wall clock, so the
simulated camera sees its buffer overrun and drops frames as a real one would. Call
:meth:`resync` right before starting a capture.
"""

from __future__ import annotations

import threading
import time


class PacedClock:
    """Virtual µs time advanced only by :meth:`sleep_until_us`, which waits for real time."""

    def __init__(self):
        self._wall0 = time.monotonic_ns() // 1000
        self._now = 0
        self._lock = threading.Lock()

    def _wall(self) -> int:
        return time.monotonic_ns() // 1000 - self._wall0

    def now_us(self) -> int:
        """The current (virtual) time."""
        return self._now

    def __call__(self) -> int:
        """Same as :meth:`now_us`."""
        return self._now

    def resync(self) -> None:
        """Bring the virtual time up to the wall clock (call just before a capture starts, so the
        time spent building the rig does not look like frames the camera overran)."""
        with self._lock:
            self._now = max(self._now, self._wall())

    def sleep_until_us(self, t_us: int) -> None:
        """Sleep until the wall clock reaches ``t_us``, then set the time to it (or to the
        wall clock when that is already later)."""
        wall = self._wall()
        if t_us > wall:
            time.sleep((t_us - wall) / 1e6)
        with self._lock:
            self._now = max(self._now, int(t_us) if t_us > wall else wall)
