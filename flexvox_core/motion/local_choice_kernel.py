"""Motion-aware's local choice, compiled (numba): the blend and the weights' per-pixel arithmetic, one pass a plane,
no whole-plane temporaries.

Each is its numpy form's operations in the same types at each pixel, so the same bits (the tests compare them):
:func:`blend_plane` is :func:`~flexvox_core.motion.local_choice.blend_numpy` on one sub-frame (numpy made four
temporary planes a sub-frame and wrote the whole plane through ``copyto``); :func:`squared_errors` and
:func:`weight_of_a` are the two halves of :func:`~flexvox_core.motion.local_choice.local_weights_numpy`'s frame
around the pooling (numpy made some twenty passes a frame, float64 planes among them).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
import numpy.typing as npt


@numba.njit(nogil=True, cache=True)
def blend_plane(video: npt.NDArray[Any], other: npt.NDArray[Any], weights: npt.NDArray[Any],
                where: npt.NDArray[np.bool_]) -> None:
    """``video ← video + (1 − w)·(other − video)`` at the voxels ``where`` (H, W), in place: ``w`` from
    ``weights`` (H, W), in the arrays' own types (float32 stays float32, as numpy computes it); ``other`` is read at
    those voxels alone (elsewhere it may hold anything)."""
    H, W = video.shape
    one = weights.dtype.type(1)
    for y in range(H):
        for x in range(W):
            if where[y, x]:
                v = video[y, x]
                video[y, x] = v + (one - weights[y, x]) * (other[y, x] - v)


@numba.njit(nogil=True, cache=True)
def squared_errors(a: npt.NDArray[np.float32], b: npt.NDArray[np.float32], y: npt.NDArray[np.float32],
                   ea: npt.NDArray[np.float32], eb: npt.NDArray[np.float32]) -> bool:
    """Where both estimates ``a`` and ``b`` (H, W) are finite, their squared errors (a − y)² into ``ea`` and
    (b − y)² into ``eb`` (in the inputs' type), 0 elsewhere; returns whether any pixel had both. The first half
    of :func:`~flexvox_core.motion.local_choice.local_weights_numpy`'s frame."""
    H, W = a.shape
    found = False
    for i in range(H):
        for j in range(W):
            va = a[i, j]
            vb = b[i, j]
            if np.isfinite(va) and np.isfinite(vb):
                da = va - y[i, j]
                db = vb - y[i, j]
                ea[i, j] = da * da
                eb[i, j] = db * db
                found = True
            else:
                ea[i, j] = 0
                eb[i, j] = 0
    return found


@numba.njit(nogil=True, cache=True)
def weight_of_a(pa: npt.NDArray[np.float32], pb: npt.NDArray[np.float32], out: npt.NDArray[np.float32]) -> None:
    """``out`` ← E_b² / (E_a² + E_b²) from the pooled errors ``pa``, ``pb`` (H, W), squared in float64; 1 where
    that sum is at most 1e-30. The second half of :func:`~flexvox_core.motion.local_choice.local_weights_numpy`'s
    frame at its default power, 2."""
    H, W = pa.shape
    for i in range(H):
        for j in range(W):
            ea = np.float64(pa[i, j])
            eb = np.float64(pb[i, j])
            ea = ea * ea
            eb = eb * eb
            total = ea + eb
            out[i, j] = eb / total if total > 1e-30 else 1.0
