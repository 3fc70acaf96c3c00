"""A bool volume held one bit per voxel, read a band of sub-frames at a time (:mod:`~flexvox_core.planes`).

Motion-aware's speed classes (still, slow, gathered voxels) are read at a voxel's own sub-frame; held as bool
volumes they cost a byte per voxel each (74 MB at 640×480 × 240 sub-frames), packed an eighth of it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt


class PackedVolume:
    """A bool volume ``(S, H, W)``, each sub-frame's rows packed 8 voxels to a byte (:func:`numpy.packbits`), with
    each sub-frame's count of True voxels.

    Sub-frames are written once each with :meth:`put` (from any thread: each writes its own rows); a sub-frame
    not written reads as False.
    """

    def __init__(self, shape: tuple[int, int, int]) -> None:
        S, H, W = (int(v) for v in shape)
        self._shape = (S, H, W)
        self.packed = np.zeros((S, H, (W + 7) // 8), np.uint8)
        self.counts = np.zeros(S, np.int64)
        """True voxels per sub-frame."""

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S, H, W)."""
        return self._shape

    def put(self, t: int, plane: np.ndarray) -> None:
        """Set sub-frame ``t`` to ``plane`` (H, W) bool."""
        if plane.shape != self._shape[1:]:
            raise ValueError(f"`plane` must have shape {self._shape[1:]}; got {plane.shape}")
        self.packed[t] = np.packbits(plane, axis=-1)
        self.counts[t] = np.count_nonzero(plane)

    def band(self, t0: int, t1: int) -> npt.NDArray[np.bool_]:
        """Sub-frames ``t0`` to ``t1`` (exclusive; clipped to the sub-frames, as a slice is), a bool array."""
        bits = np.unpackbits(self.packed[t0:t1], axis=-1, count=self._shape[2])
        return bits.view(np.bool_)  # unpackbits gives 0 and 1: bytes of bool

    def any(self) -> bool:
        """Whether any voxel is True (from the counts: no volume read)."""
        return bool(self.counts.any())

    def any_in(self, t0: int, t1: int) -> bool:
        """Whether any voxel of sub-frames ``t0`` to ``t1`` (exclusive) is True."""
        return bool(self.counts[t0:t1].any())
