"""Motion-aware's local choice blended in one pass a sub-frame, compiled (numba): no whole-plane temporaries.

:func:`blend_plane` is :func:`~flexvox_core.motion.local_choice.blend_numpy` on one sub-frame, the same operations
in the same types at each voxel (the tests compare them bit for bit); numpy made three temporary planes a sub-frame
and a fourth for the weights' complement, and wrote the whole plane through ``copyto``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(nogil=True, cache=True)
def blend_plane(video, other, weights, where):
    """``video ← video + (1 − w)·(other − video)`` at the voxels ``where`` (H, W), in place: ``w`` from
    ``weights`` (H, W), in the arrays' own types (float32 stays float32, as numpy computes it)."""
    H, W = video.shape
    one = weights.dtype.type(1)
    for y in range(H):
        for x in range(W):
            if where[y, x]:
                v = video[y, x]
                video[y, x] = v + (one - weights[y, x]) * (other[y, x] - v)
