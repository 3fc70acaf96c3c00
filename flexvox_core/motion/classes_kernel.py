"""Motion-aware's speed classes: the rule (:func:`speed_class`) and its compiled form on one sub-frame
(:func:`classify_plane`, numba), which writes the classes straight into rows of packed bits
(:class:`~flexvox_core.motion.packed.PackedVolume`'s layout: :func:`numpy.packbits`, the first voxel in the top
bit) with their counts: no bool planes are made (numpy's compares and ``packbits`` cost about 0.7 ms a 640×480
sub-frame, 0.17 s of CPU on the 1-s clip)."""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import numpy.typing as npt


def speed_class(speed: Any, still_below: Any, slow_below: Any, skipped: Any) -> tuple[Any, Any, Any]:
    """(still, slow, gathered) of voxels moving at ``speed`` (px per sub-frame): still below ``still_below``, slow
    below ``slow_below`` when not still and not ``skipped`` (a sub-frame outside the gathered ones), gathered when
    none of these. The rule both engines classify by: numpy runs it on whole planes
    (:func:`~flexvox_core.motion.stages.speed_classes`), the CPU's stage compiles it per voxel
    (:func:`classify_plane`), the GPU as a device function (``x ^ True`` is the logical not of a bool there, in
    numpy and in Python)."""
    still = speed < still_below
    slow = (speed < slow_below) & (still ^ True) & (skipped ^ True)
    return still, slow, (still | slow | skipped) ^ True


_speed_class = numba.njit(inline="always", nogil=True, cache=True)(speed_class)


@numba.njit(nogil=True, cache=True)
def classify_plane(speed: npt.NDArray[np.float32], still_below: np.float32, slow_below: np.float32, skipped: bool,
                   still: npt.NDArray[np.uint8], slow: npt.NDArray[np.uint8],
                   gathered: npt.NDArray[np.uint8]) -> tuple[int, int, int]:
    """:func:`speed_class` at each voxel of ``speed`` (H, W) float32, into the rows of packed bits ``still``,
    ``slow`` and ``gathered`` (H, ⌈W/8⌉) uint8 (every byte written); returns the three counts."""
    H, W = speed.shape
    n_still = n_slow = n_gathered = 0
    for y in range(H):
        for j in range(still.shape[1]):
            b_still = b_slow = b_gathered = 0
            for k in range(8):
                x = 8 * j + k
                if x < W:
                    is_still, is_slow, is_gathered = _speed_class(speed[y, x], still_below, slow_below, skipped)
                    bit = 1 << (7 - k)
                    if is_still:
                        b_still |= bit
                        n_still += 1
                    if is_slow:
                        b_slow |= bit
                        n_slow += 1
                    if is_gathered:
                        b_gathered |= bit
                        n_gathered += 1
            still[y, j] = b_still
            slow[y, j] = b_slow
            gathered[y, j] = b_gathered
    return n_still, n_slow, n_gathered
