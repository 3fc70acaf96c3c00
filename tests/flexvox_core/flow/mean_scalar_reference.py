"""The successive-sub-frame flow's temporal mean as it was before it weighed the flows itself: a scalar compiled
loop a pixel over flows weighted beforehand (``fwd *= conf + 1e-3``, a pass of its own), the same values bit for
bit; ``bench/bench_motion_throughput.py --ab flow-mean-unfused`` runs it."""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt


@numba.njit(nogil=True, error_model="numpy")
def pair_mean_scalar(weighted: npt.NDArray[np.float32], conf: npt.NDArray[np.float32], c: int, reach: int,
                     out: npt.NDArray[np.float32]) -> None:
    """``out`` (h, w, 2): the sum of ``weighted[c + o]`` (P, h, w, 2) over o = -reach..reach (the pairs that
    exist) divided by the sum of ``conf[c + o] + 1e-3`` (float32)."""
    P, h, w = conf.shape
    eps = np.float32(1e-3)
    lo = max(-reach, -c)
    hi = min(reach, P - 1 - c)
    for y in range(h):
        for x in range(w):
            nu = np.float32(0)
            nv = np.float32(0)
            den = np.float32(0)
            for o in range(lo, hi + 1):
                nu += weighted[c + o, y, x, 0]
                nv += weighted[c + o, y, x, 1]
                den += conf[c + o, y, x] + eps
            out[y, x, 0] = nu / den
            out[y, x, 1] = nv / den
