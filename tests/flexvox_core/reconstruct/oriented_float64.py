"""Oriented nc as it was before its kernel and its structure tensor were float32 vector code: the kernel in float64
(tap lists, float64 sums in a fixed order, the kernels' choice per voxel), the tensor by OpenCV's filters
(``oriented_reference.structure_opencv``). The tests measure the float32 kernel's error against it, and
``bench/bench_motion_throughput.py --ab choice-float64`` puts it back.

:func:`oriented_nc_float64` is :func:`~flexvox_core.reconstruct.oriented_nc.oriented_nc` with these (its checks and
blocks shared).
"""

from __future__ import annotations

import threading

import numba
import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.planes import band
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, gaussian_kernel, time_weights
from flexvox_core.reconstruct.oriented_nc import (
    _HIGH,
    _LOW,
    _PAD,
    _TAN,
    SIGMA,
    _aligned_columns,
    _blocks,
    _check_subframes,
    check_inputs,
    kernel_bank,
)
from flexvox_core.reconstruct.oriented_nc_kernel import _bank_index, _reflect, tap_lists
from flexvox_core.threads import for_each

from .oriented_reference import structure_opencv


@numba.njit(nogil=True, cache=True)
def oriented_plane_float64(frames, order, weight, first, slot, frame, present, j, select, offsets, weights, counts, h,
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



def oriented_nc_float64(frames, code, guide, *, where=None, fallback=None, missing=None, out=None, subframes=None,
                        loo=None, workspace: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~flexvox_core.reconstruct.oriented_nc.oriented_nc` (the same arguments and results) with the float64
    kernel above."""
    f, c, g, where, missing = check_inputs(frames, code, guide, where, fallback, missing, subframes)
    F, H, W = f.shape
    K = c.shape[2]
    s0, s1 = _check_subframes(subframes, F * K)
    present = None if missing is None else ~missing
    gt = gaussian_kernel(SIGMA, np.float64)
    weight, first = time_weights(gt, K, F, present)
    floor = NC_MIN_WEIGHT * float(gt.max())
    bank = kernel_bank()
    offsets, weights, counts = tap_lists(bank)
    m = c.shape[0]
    order = tiled_order(c, min(H, m), W).astype(np.int64)  # repeats every m rows
    samples = np.ascontiguousarray(f, dtype=np.float32)
    n = s1 - s0
    fall = None if fallback is None else band(fallback, s0, s1)
    if out is not None:
        if (not isinstance(out, np.ndarray) or out.shape != (n, H, W) or out.dtype != np.float32
                or not out.flags.c_contiguous or not out.flags.writeable
                or any(np.may_share_memory(out, a) for a in (frames, guide, where, fall)
                       if isinstance(a, np.ndarray))):
            raise ValueError(f"`out` must be a writable C-contiguous float32 array of shape {(n, H, W)} that shares "
                             "no memory with the other inputs")
        video = out
    else:
        video = np.empty((n, H, W), np.float32)
    if loo is None:
        loo = np.full((F, H, W), np.nan, np.float32)
    elif (not isinstance(loo, np.ndarray) or loo.shape != (F, H, W) or loo.dtype != np.float32
          or not loo.flags.c_contiguous or not loo.flags.writeable):
        raise ValueError(f"`loo` must be a writable C-contiguous float32 array of shape {(F, H, W)}")
    chosen = None if where is None else band(where, s0, s1)
    if chosen is not None and chosen.dtype != bool:
        raise ValueError(f"`where` must be a bool (S, H, W) = {(F * K, H, W)} array; its sub-frames {s0} to {s1} are "
                         f"{chosen.dtype}")
    present_f = np.ones(F, bool) if present is None else present
    everywhere = np.ones((H, W), bool)
    # Planes a thread works in, taken from the pool and given back (fresh memory costs page faults every time).
    pool = [] if workspace is None else workspace
    lock = threading.Lock()

    def one(i):
        s = s0 + i
        if fall is None:  # each sub-frame starts as the fallback, on the thread that estimates it
            video[i].fill(np.nan)
        else:
            np.copyto(video[i], fall[i], casting="unsafe")
        wanted = everywhere if chosen is None else chosen[i]
        blocks = _blocks(wanted)
        if not blocks:
            return
        with lock:
            planes = pool.pop() if pool else None
        if planes is None or planes[0].shape != (3, H, W):
            planes = (np.zeros((3, H, W), np.float32), np.empty((H, W)), np.empty((H, W)))
        j, vt, mt = planes
        for y0, y1, x0, x1 in blocks:
            b0, b1 = max(0, y0 - _PAD), min(H, y1 + _PAD)
            a0, a1 = _aligned_columns(x0, x1, W)
            j[:, b0:b1, a0:a1] = structure_opencv(np.asarray(g[s, b0:b1, a0:a1], np.float32))
            oriented_plane_float64(samples, order, weight[s], int(first[s]), s % K, s // K, bool(present_f[s // K]),
                           j, wanted, offsets, weights, counts, bank.shape[1] // 2, floor, y0, y1, x0, x1, vt, mt,
                           video[i], loo, _LOW, _HIGH, _TAN)
        with lock:
            pool.append(planes)

    for_each(one, n)
    return video, loo
