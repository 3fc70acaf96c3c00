"""The successive-sub-frame flow's temporal mean, compiled (numba): one sub-frame's velocity from the forward flows
of the pairs around it, each weighted by its confidence, with the values of
:func:`~flexvox_core.flow.estimate.successive_flow`'s numpy form bit for bit (each weighted flow one float32 product,
``flow * (conf + 1e-3)``; float32 sums from 0, offsets in increasing order, one division). Vector code for the usual
one to three pairs a pixel (a loop each, the pixels eight at a time)."""

from __future__ import annotations

import numba
import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float32]


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def _add(f: Array, c: Array, i: int, nu: np.float32, nv: np.float32,
         den: np.float32) -> tuple[np.float32, np.float32, np.float32]:
    """The sums with pixel ``i``'s weighted flow and weight added (``f``, ``c``: a pair's flattened planes)."""
    weight = c[i] + np.float32(1e-3)
    return nu + f[2 * i] * weight, nv + f[2 * i + 1] * weight, den + weight


@numba.njit(nogil=True, cache=True, error_model="numpy")
def pair_mean(flow: Array, conf: Array, c: int, reach: int, out: Array) -> None:
    """``out`` (h, w, 2): the sum of ``flow[c + o] * (conf[c + o] + 1e-3)`` ((P, h, w, 2) and (P, h, w), both
    C-contiguous) over o = -reach..reach (the pairs that exist) divided by the sum of ``conf[c + o] + 1e-3``
    (float32)."""
    P, h, w = conf.shape
    n = h * w
    first = c + max(-reach, -c)
    count = c + min(reach, P - 1 - c) - first + 1
    f0, c0 = flow[first].reshape(2 * n), conf[first].reshape(n)
    f1, c1 = flow[min(first + 1, P - 1)].reshape(2 * n), conf[min(first + 1, P - 1)].reshape(n)
    f2, c2 = flow[min(first + 2, P - 1)].reshape(2 * n), conf[min(first + 2, P - 1)].reshape(n)
    of = out.reshape(2 * n)
    zero = np.float32(0)
    if count == 3:
        for i in range(n):
            nu, nv, den = _add(f0, c0, i, zero, zero, zero)
            nu, nv, den = _add(f1, c1, i, nu, nv, den)
            nu, nv, den = _add(f2, c2, i, nu, nv, den)
            of[2 * i] = nu / den
            of[2 * i + 1] = nv / den
    elif count == 2:
        for i in range(n):
            nu, nv, den = _add(f0, c0, i, zero, zero, zero)
            nu, nv, den = _add(f1, c1, i, nu, nv, den)
            of[2 * i] = nu / den
            of[2 * i + 1] = nv / den
    elif count == 1:
        for i in range(n):
            nu, nv, den = _add(f0, c0, i, zero, zero, zero)
            of[2 * i] = nu / den
            of[2 * i + 1] = nv / den
    else:  # more pairs: a pass each, the sums in `out` and `dens`
        dens = np.zeros(n, np.float32)
        of[:] = zero
        for k in range(first, first + count):
            fk, ck = flow[k].reshape(2 * n), conf[k].reshape(n)
            for i in range(n):
                of[2 * i], of[2 * i + 1], dens[i] = _add(fk, ck, i, of[2 * i], of[2 * i + 1], dens[i])
        for i in range(n):
            of[2 * i] /= dens[i]
            of[2 * i + 1] /= dens[i]
