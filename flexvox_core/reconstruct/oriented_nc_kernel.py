"""The sums of :func:`~flexvox_core.reconstruct.oriented_nc.oriented_nc` for one sub-frame, compiled (numba).

For sub-frame s the samples are first blurred along time — each pixel's own samples weighed by
``weight[k, b]`` (its slot k, frame ``first`` + b), the table of
:func:`~flexvox_core.reconstruct.diffusion.time_weights` — into two planes, values and weights; then
each wanted voxel sums them under its kernel of the bank, chosen from the structure tensor there, with
reflecting borders. Each voxel is written once from float64 sums in a fixed order, so the bits do not
depend on how sub-frames are spread over threads.
"""

from __future__ import annotations

import numba
import numpy as np

_ANGLES = 8  # the sectors below are written for 8 directions (oriented_nc.ANGLES)


@numba.njit(inline="always", nogil=True, cache=True)
def _reflect(i, n):
    """Index i folded into [0, n) as a reflecting border repeats the picture (edge pixel doubled), however
    far outside it lies (a kernel wider than the picture folds more than once)."""
    i %= 2 * n
    if i >= n:
        i = 2 * n - 1 - i
    return i


def bank_of(jxx, jxy, jyy, low, high, tan1):
    """As :func:`~flexvox_core.reconstruct.oriented_nc.bank_index` (the same comparisons), for one voxel;
    ``low``, ``high``: where the anisotropy rounds up to the next level; ``tan1``: the sectors' edge slope.
    Written once, compiled for the CPU here (:func:`_bank_index`) and for the GPU as a device function
    (:mod:`flexvox_core.motion.gpu.oriented_nc`)."""
    a = jxx - jyy
    b = 2.0 * jxy
    trace = jxx + jyy
    spread2 = a * a + b * b  # (λ1 − λ2)², so A² = spread2 / trace²
    if not trace > 0.0 or not spread2 > (low * trace) ** 2:
        return 0
    level = 1 if spread2 <= (high * trace) ** 2 else 2
    ax = abs(a)
    by = abs(b)
    if by <= tan1 * ax:
        angle = 0 if a >= 0 else 4
    elif ax <= tan1 * by:
        angle = 2 if b > 0 else 6
    elif a > 0:
        angle = 1 if b > 0 else 7
    else:
        angle = 3 if b > 0 else 5
    return 1 + (level - 1) * _ANGLES + angle


_bank_index = numba.njit(inline="always", nogil=True, cache=True)(bank_of)


def tap_lists(bank: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The non-zero taps of each kernel of ``bank`` (B, 2h + 1, 2h + 1): offsets (B, T, 2) int64 as (dy, dx),
    weights (B, T) float64 and counts (B,), T the most of any kernel (the rest zero)."""
    B, n, _ = bank.shape
    h = n // 2
    counts = (bank != 0).reshape(B, -1).sum(axis=1)
    T = int(counts.max())
    offsets = np.zeros((B, T, 2), np.int64)
    weights = np.zeros((B, T), np.float64)
    for b in range(B):
        dy, dx = np.nonzero(bank[b])
        offsets[b, :len(dy), 0] = dy - h
        offsets[b, :len(dy), 1] = dx - h
        weights[b, :len(dy)] = bank[b][dy, dx]
    return offsets, weights, counts.astype(np.int64)


@numba.njit(nogil=True, cache=True)
def oriented_plane(frames, order, weight, first, slot, frame, present, j, select, offsets, weights, counts, h,
                   floor, y0, y1, x0, x1, vt, mt, out, loo, low, high, tan1):
    """Rows [y0, y1) and columns [x0, x1) of sub-frame s (its ``slot`` = s mod K, ``frame`` = s div K): at each
    ``select``ed voxel, the kernel-weighted mean of the time-blurred samples into ``out`` (H, W) — the sample itself
    at the pixels of this slot in a ``present`` frame, whose leave-one-out estimate goes to ``loo[frame]`` —, left as
    it is where the weights sum to at most ``floor``. ``order`` (m, W) repeats every m rows. The kernels are given as
    tap lists (:func:`tap_lists`) reaching ``h`` px; ``vt`` and ``mt`` (H, W) float64 are scratch planes for the
    time-blurred values and weights; ``low``, ``high``, ``tan1``: the bank's rounding (:func:`_bank_index`). The
    planes are read and written within h px of the block alone (``j`` within it)."""
    F, H, W = frames.shape
    m = order.shape[0]
    B = weight.shape[1]
    # The rows and columns the kernels read (a reflection at the picture's edge stays within them).
    lo, hi = max(0, y0 - h), min(H, y1 + h)
    left, right = max(0, x0 - h), min(W, x1 + h)
    for y in range(lo, hi):
        ym = y % m
        for x in range(left, right):
            k = order[ym, x]
            acc = 0.0
            wsum = 0.0
            for b in range(B):
                w = weight[k, b]
                if w != 0.0:
                    acc += w * frames[first + b, y, x]
                    wsum += w
            vt[y, x] = acc
            mt[y, x] = wsum
    own = weight[slot, frame - first] if 0 <= frame - first < B else 0.0
    flat = offsets[:, :, 0] * W + offsets[:, :, 1]  # the taps' offsets in the flattened planes
    vflat = vt.reshape(H * W)
    mflat = mt.reshape(H * W)
    for y in range(y0, y1):
        ym = y % m
        for x in range(x0, x1):
            if not select[y, x]:
                continue
            kb = _bank_index(float(j[0, y, x]), float(j[1, y, x]), float(j[2, y, x]), low, high, tan1)
            num = 0.0
            den = 0.0
            self_w = 0.0  # the weight of the taps that land on the voxel itself (the centre, more at a border)
            if y - h >= 0 and y + h < H and x - h >= 0 and x + h < W:
                # Inside: no reflection, the voxel itself is the centre tap alone (weight 1). Four partial
                # sums in a fixed order: one running sum would wait on each add (the kernel's bound).
                n0 = n1 = n2 = n3 = 0.0
                d0 = d1 = d2 = d3 = 0.0
                base = y * W + x
                n = counts[kb]
                t = 0
                while t + 4 <= n:
                    i0 = base + flat[kb, t]
                    i1 = base + flat[kb, t + 1]
                    i2 = base + flat[kb, t + 2]
                    i3 = base + flat[kb, t + 3]
                    n0 += weights[kb, t] * vflat[i0]
                    n1 += weights[kb, t + 1] * vflat[i1]
                    n2 += weights[kb, t + 2] * vflat[i2]
                    n3 += weights[kb, t + 3] * vflat[i3]
                    d0 += weights[kb, t] * mflat[i0]
                    d1 += weights[kb, t + 1] * mflat[i1]
                    d2 += weights[kb, t + 2] * mflat[i2]
                    d3 += weights[kb, t + 3] * mflat[i3]
                    t += 4
                while t < n:
                    i0 = base + flat[kb, t]
                    n0 += weights[kb, t] * vflat[i0]
                    d0 += weights[kb, t] * mflat[i0]
                    t += 1
                num = (n0 + n1) + (n2 + n3)
                den = (d0 + d1) + (d2 + d3)
                self_w = 1.0
            else:
                for t in range(counts[kb]):
                    g = weights[kb, t]
                    yy = _reflect(y + offsets[kb, t, 0], H)
                    xx = _reflect(x + offsets[kb, t, 1], W)
                    num += g * vt[yy, xx]
                    den += g * mt[yy, xx]
                    if yy == y and xx == x:
                        self_w += g
            if present and order[ym, x] == slot:
                y_own = frames[frame, y, x]
                out[y, x] = y_own
                c = self_w * own
                rest = den - c
                if rest > floor:
                    loo[frame, y, x] = (num - c * y_own) / rest
            elif den > floor:
                out[y, x] = num / den

