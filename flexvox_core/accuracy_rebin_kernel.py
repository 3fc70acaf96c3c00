"""Re-binning's closed-form estimate a voxel at a time, compiled (numba): the two passes of
:func:`~flexvox_core.accuracy_rebin.rebin_error` over the clip, without a volume per corner.

The stencil is separable: each voxel ``(t, y, x)`` reads the block of each of its 8 corners through the axis tables
``i0, i1, w1`` of :func:`~flexvox_core.accuracy_rebin._axis` (time, rows, columns), its weight the product of the
three axes' weights. The whole-volume numpy form (the reference in ``tests/flexvox_core/accuracy_rebin_reference.py``)
held the 8 corners' blocks, weights and lags for every voxel: about 250 bytes a voxel, 19 GB for a 1-s 640×480 clip at
K = 16. Here a voxel's corners are made, used and dropped in registers, in the reference's order of operations:

* :func:`pair_increments`: the truth's increments the pairs of samples span, a row lag at a time;
* :func:`lag_mass` (pass 1): a corner's weights summed per space-time lag to its sample, in the voxels' order
  (``numpy.bincount``'s);
* :func:`frame_error` (pass 2, once the lags' increments are known): the error of every voxel of one camera frame's
  sub-frames, its noise and pair terms then its lags' increments added in the reference's order: the same bits.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np


@numba.njit(inline="always", nogil=True, cache=True)
def _corner(c: int, t: int, y: int, x: int, axes: Any, nh: int, nw: int) -> tuple[int, float]:
    """Corner ``c`` (bits: time, row, column) of voxel ``(t, y, x)``: its block and its weight."""
    it0, it1, wt1, iy0, iy1, wy1, ix0, ix1, wx1 = axes
    if c & 4:
        bt, wt = it1[t], wt1[t]
    else:
        bt, wt = it0[t], 1.0 - wt1[t]
    if c & 2:
        by, wy = iy1[y], wy1[y]
    else:
        by, wy = iy0[y], 1.0 - wy1[y]
    if c & 1:
        bx, wx = ix1[x], wx1[x]
    else:
        bx, wx = ix0[x], 1.0 - wx1[x]
    return (bt * nh + by) * nw + bx, wt * wy * wx


@numba.njit(inline="always", nogil=True, cache=True)
def _lag(t: int, y: int, x: int, b: int, pos_t: Any, pos_y: Any, pos_x: Any, half: Any) -> int:
    """The flat index of the lag from block ``b``'s sample to voxel ``(t, y, x)``, clipped to the box ``half``."""
    T, Y, X = half
    dt = min(max(t - pos_t[b], -T), T)
    dy = min(max(y - pos_y[b], -Y), Y)
    dx = min(max(x - pos_x[b], -X), X)
    return int(((dt + T) * (2 * Y + 1) + dy + Y) * (2 * X + 1) + dx + X)


@numba.njit(nogil=True, cache=True)
def lag_mass(c: int, shape: Any, axes: Any, blocks: Any, pos_t: Any, pos_y: Any, pos_x: Any, half: Any, kept: Any,
             out: Any) -> None:
    """Pass 1, corner ``c``: ``out[lag]`` += its weight over the kept voxels of a clip ``shape`` (S, H, W), the
    voxels in order (``out`` (box,) float64; the nearest block is corner 0 of axes whose ``i1`` is ``i0``, ``w1``
    0)."""
    S, H, W = shape
    nh, nw = blocks[1], blocks[2]
    for t in range(S):
        if not kept[t]:
            continue
        for y in range(H):
            for x in range(W):
                b, w = _corner(c, t, y, x, axes, nh, nw)
                out[_lag(t, y, x, b, pos_t, pos_y, pos_x, half)] += w


@numba.njit(nogil=True, cache=True)
def pair_increments(dy: int, slots: Any, y: Any, var: Any, ok: Any, half: Any, reach: int, total: Any,
                    count: Any) -> None:
    """:func:`~flexvox_core.accuracy_rebin.increments`'s sums at row lag ``dy``: for every column lag and every pair
    of kept frames ``f``, ``g`` at most ``reach`` apart, ``(y_g − y_f)² − σ_g² − σ_f²`` of the pixel pairs whose
    sub-frames (``slots`` (F, H, W)) lie at most ``T`` apart, summed per time lag in the pixels' order and added
    to ``total[:, dy + Y, dx + X]`` (``count`` their number) a frame pair at a time, as ``numpy.bincount`` did."""
    F, H, W = y.shape
    T, Y, X = half
    part = np.zeros(2 * T + 1)
    n = np.zeros(2 * T + 1)
    for dx in range(-X, X + 1):
        for f in range(F):
            if not ok[f]:
                continue
            for g in range(max(0, f - reach), min(F, f + reach + 1)):
                if not ok[g]:
                    continue
                part[:] = 0.0
                n[:] = 0.0
                for r in range(max(0, -dy), H - max(0, dy)):
                    for c in range(max(0, -dx), W - max(0, dx)):
                        dt = slots[g, r + dy, c + dx] - slots[f, r, c]
                        if -T <= dt <= T:
                            d = y[g, r + dy, c + dx] - y[f, r, c]
                            part[dt + T] += d * d - var[g, r + dy, c + dx] - var[f, r, c]
                            n[dt + T] += 1.0
                for i in range(2 * T + 1):
                    total[i, dy + Y, dx + X] += part[i]
                    count[i, dy + Y, dx + X] += n[i]


@numba.njit(nogil=True, cache=True)
def frame_error(t0: int, shape: Any, axes: Any, corners: int, blocks: Any, pos_t: Any, pos_y: Any, pos_x: Any,
                half: Any, yb: Any, vb: Any, est: Any, out: Any) -> None:
    """Pass 2: the error of sub-frames ``[t0, t0 + len(out))`` of a clip ``shape`` into ``out`` (n, H, W) float64:
    each corner's ``w²·σ²`` and, for each later corner, ``− w·w'·((y − y')² − σ² − σ'²)`` of the two blocks'
    samples (their pair's increment less its noise), then each corner's ``w·D(lag)`` (``est``, flat)."""
    n, H, W = out.shape
    nh, nw = blocks[1], blocks[2]
    bs = np.empty(8, np.int64)
    ws = np.empty(8, np.float64)
    for i in range(n):
        t = t0 + i
        for y in range(H):
            for x in range(W):
                for c in range(corners):
                    bs[c], ws[c] = _corner(c, t, y, x, axes, nh, nw)
                e = 0.0
                for c in range(corners):
                    j = bs[c]
                    e += ws[c] * ws[c] * vb[j]
                    for c2 in range(c + 1, corners):
                        k = bs[c2]
                        d = yb[j] - yb[k]
                        e -= ws[c] * ws[c2] * (d * d - vb[j] - vb[k])
                for c in range(corners):
                    e += ws[c] * est[_lag(t, y, x, bs[c], pos_t, pos_y, pos_x, half)]
                out[i, y, x] = e
