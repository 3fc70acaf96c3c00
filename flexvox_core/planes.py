"""Volumes read a band of sub-frames at a time: an array, or one made on demand.

Motion-aware's stages read their per-voxel volumes (the flow, the speed classes, the samples' mask) at a voxel's
own sub-frame. A volume that is cheap to make a sub-frame at a time (the flow from its own, smaller scale; the
classes from the flow; the mask from the code) need not be held whole: it is an object with ``shape`` and
``band(t0, t1)``. :func:`band` reads either kind.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class Bands(Protocol):
    """A volume made a band of sub-frames at a time."""

    @property
    def shape(self) -> tuple[int, ...]:
        """The whole volume's shape, sub-frames first."""

    def band(self, t0: int, t1: int) -> np.ndarray:
        """Sub-frames ``t0`` to ``t1`` (exclusive), C-contiguous; equal to the whole volume's ``[t0:t1]``."""


def band(volume: np.ndarray | Bands | Any, t0: int, t1: int) -> np.ndarray:
    """Sub-frames ``t0`` to ``t1`` (exclusive) of ``volume``: a slice of an array, or ``volume.band(t0, t1)``.

    Raises
    ------
    ValueError
        Unless ``t0`` and ``t1`` are whole numbers with ``0 <= t0 <= t1 <=`` the volume's sub-frames (one rule for
        every kind: a slice of an array would clip a range past the ends, or wrap a negative one, silently).
    """
    S = int(volume.shape[0])
    whole = all(isinstance(t, (int, np.integer)) and not isinstance(t, bool) for t in (t0, t1))
    if not (whole and 0 <= t0 <= t1 <= S):
        raise ValueError(f"sub-frames {t0!r} to {t1!r} must be whole numbers with 0 <= t0 <= t1 <= {S} (the "
                         "volume's sub-frames)")
    if isinstance(volume, np.ndarray):
        return volume[t0:t1]
    return volume.band(t0, t1)
