"""A volume read by bands (:class:`flexvox_core.planes.Bands`) for the tests: it counts what it hands out
and refuses a band longer than it allows."""

import numpy as np


class Counted:
    """``array`` handed out a band at a time (a C-contiguous copy), at most ``longest`` sub-frames at once;
    ``handed`` counts the sub-frames handed out, ``calls`` the bands."""

    def __init__(self, array: np.ndarray, longest: int):
        self.array, self.longest, self.handed, self.calls = array, longest, 0, 0

    @property
    def shape(self) -> tuple[int, ...]:
        return self.array.shape

    def band(self, t0: int, t1: int) -> np.ndarray:
        assert 0 <= t0 < t1 <= len(self.array) and t1 - t0 <= self.longest, (t0, t1)
        self.handed += t1 - t0
        self.calls += 1
        return np.ascontiguousarray(self.array[t0:t1])
