"""Normalized convolution along time alone (a tensor (0, 0, c_t)), compiled (numba): one pass per output row.

The paper's Eq. 3 (the Gaussian of a diffusion tensor, §3.1) at its high-SR end, :math:`c_x = c_y = 0`.

With no spatial blur each pixel's estimate depends only on its own samples: one per camera frame, at
its slot. The time Gaussian then reaches a handful of them per sub-frame (2 r / K + 1 at K slots and
kernel radius r), instead of blurring the whole volume of mostly-zero sub-frames along time. The
weights depend only on the sub-frame s, the pixel's slot k and the frame f: a small table
``weight[s, k, b]`` for frames f = ``first[s]`` + b, normalised (divided by their sum, the blurred
mask). Each voxel is written once, from a float64 sum in a fixed order: the output bits do not depend on the number of
threads. :func:`flexvox_core.reconstruct.diffusion.diffuse` keeps the general path (spatial blur of
every sub-frame, then the time blur) as the reference the tests compare this against.

:func:`finish_plane`: the general path's last steps on a sub-frame (divide by the blurred mask, clip, give the samples
back) in one pass; ``diffusion._finish_numpy`` is its numpy reference, with the same bits.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(nogil=True, cache=True)
def time_only_rows(frames, order, weight, first, lo, hi, out, y0, y1, present, select, s0, s1, packed=None):
    """Rows [y0, y1) of sub-frames [s0, s1) of ``out`` (S, H, W): Σ_b weight[s, k, b] · frames[first[s] + b]
    (k = order[y, x], the weights normalised to sum 1), clipped to [lo, hi]. ``order`` repeats every
    m rows (a tiled code: m = its first axis).

    ``present`` (F,) bool or None: with it, each voxel of a present frame's sub-frame at its pixel's
    slot takes the sample itself (nc's ``keep_samples``). ``select`` (s1 - s0, H, W) bool or None (sub-frames
    s0 to s1): with it, only those voxels are written (the rest of ``out`` is left as it is; rows without one
    are skipped). ``packed`` (s1 - s0, H, ⌈W/8⌉) uint8 or None, in place of ``select``: the same selection with each
    row's voxels 8 to a byte, the first in the highest bit (:func:`numpy.packbits`)."""
    W = out.shape[2]
    B = weight.shape[2]
    m = order.shape[0]
    K = out.shape[0] // frames.shape[0]
    row_w = np.empty((m, B, W), np.float64)  # a sub-frame's weights along each row of the tile
    acc = np.empty(W, np.float64)
    pick = np.zeros(W, np.bool_)  # a packed selection's row, unpacked
    masked = select is not None or packed is not None
    for s in range(s0, s1):
        f0 = first[s]
        k = s % K
        keep = present is not None and present[s // K]
        for ym in range(m):
            for b in range(B):
                for x in range(W):
                    row_w[ym, b, x] = weight[s, order[ym, x], b]
        for y in range(y0, y1):
            chosen = pick
            if select is not None:
                chosen = select[s - s0, y]
                anything = False
                for x in range(W):
                    if chosen[x]:
                        anything = True
                        break
                if not anything:
                    continue
            elif packed is not None:
                bits = packed[s - s0, y]
                anything = False
                for i in range(bits.size):
                    if bits[i] != 0:
                        anything = True
                        break
                if not anything:
                    continue
                for x in range(W):
                    pick[x] = (bits[x >> 3] >> (7 - (x & 7))) & 1 != 0
            w = row_w[y % m]
            for x in range(W):
                acc[x] = 0.0
            for b in range(B):  # each row a contiguous pass: the compiler vectorises it
                src = frames[f0 + b, y]
                wb = w[b]
                for x in range(W):
                    acc[x] += wb[x] * src[x]
            dst = out[s, y]
            if not masked and not keep:
                for x in range(W):
                    dst[x] = min(max(acc[x], lo), hi)
                continue
            own = frames[s // K, y]
            slot = order[y % m]
            for x in range(W):
                if not masked or chosen[x]:
                    if keep and slot[x] == k:
                        dst[x] = own[x]
                    else:
                        dst[x] = min(max(acc[x], lo), hi)


@numba.njit(nogil=True, cache=True, error_model="numpy")
def finish_plane(num, den, floor, lo, hi, own, slot, keep):
    """nc's last steps on one sub-frame's numerator ``num`` (1-D, in place) in one pass: divided by the blurred mask
    ``den`` where it is above ``floor`` (left undivided elsewhere: those voxels take their nearest sample later),
    clipped to [lo, hi] as ``np.clip`` does (``x < lo ? lo : x``, then ``x > hi ? hi : x``: a tie, a signed
    zero, keeps x; NaN stays NaN), and with ``keep`` the samples ``own`` written at the voxels ``slot``. Returns
    how many voxels are at or below ``floor``.

    The same bits as ``diffusion._finish_numpy`` (a float32 division and a compare are exact in both); ``floor``,
    ``lo`` and ``hi`` come in ``num``'s dtype, as numpy compares and clips a float32 plane in float32."""
    low = 0
    for i in range(num.size):
        v = num[i]
        d = den[i]
        if d > floor:
            v = v / d
        else:
            low += 1
        v = lo if v < lo else v
        v = hi if v > hi else v
        if keep and slot[i]:
            v = own[i]
        num[i] = v
    return low
