"""The moving average in time of :func:`~flexvox_core.flow.baseline.box_in_time`, compiled (numba): SciPy's
``uniform_filter1d(v, size, axis=0, mode="nearest")`` bit for bit (its reference: the tests compare the two), its
running box's arithmetic (a running sum since SciPy 1.0, scipy/scipy#7516): each line in time read as float64 with
its edges held, the first ``size`` values summed in order, then at each next sub-frame ``entering − leaving`` added
to the sum; each result the sum divided by ``size``, rounded to float32 once. The lines run side by side (the pixels
of a band of columns at once, unit stride), not one at a time through a copied line buffer as SciPy's do."""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt


@numba.njit(nogil=True, cache=True, error_model="numpy")
def box_columns(src: npt.NDArray[np.float32], size: int, j0: int, j1: int, out: npt.NDArray[np.float32]) -> None:
    """``out[:, j0:j1]`` = the running box of ``size`` sub-frames of ``src[:, j0:j1]`` (S, N) float32 along its
    first axis, edges held (sub-frames s − size//2 … s − size//2 + size − 1, clipped to 0 … S − 1)."""
    S = src.shape[0]
    n = j1 - j0
    before = size // 2
    fsize = np.float64(size)
    acc = np.zeros(n, np.float64)
    for i in range(size):  # the first window, summed in order
        t = min(max(i - before, 0), S - 1)
        for j in range(n):
            acc[j] += np.float64(src[t, j0 + j])
    for j in range(n):
        out[0, j0 + j] = np.float32(acc[j] / fsize)
    for s in range(1, S):
        enter = min(s - before + size - 1, S - 1)
        leave = max(s - before - 1, 0)
        for j in range(n):
            acc[j] += np.float64(src[enter, j0 + j]) - np.float64(src[leave, j0 + j])
            out[s, j0 + j] = np.float32(acc[j] / fsize)
