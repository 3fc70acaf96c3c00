r"""The trajectory gather's sums read from the camera frames and the code: no sample volume.

An identity code's samples lie on a lattice: at sub-frame s = f·K + k, pixel (y, x) holds a sample iff
``code[y % m, x % n, k]`` and frame f was not dropped, and its value is ``frames[f, y, x]``; slot k is open in
one pixel (i, j) of the tile, so the test is y % m == i and x % n == j (a row and a column table per slot). A
bilinear read of the sample volume at (y, x) is then the sum over the cell's four corners that hold a sample of
their bilinear weight times the frame's value, and the read of the mask the sum of those weights (0 outside the
picture, as OpenCV's ``BORDER_CONSTANT``). This module computes the gather's unblurred sums that way, one
sub-frame's box at a time (:func:`~flexvox_core.motion.mcnc.trajectory_gather` calls it from its threads: the
kernel releases the GIL). The positions are exact (the GPU's
:func:`~flexvox_core.motion.gpu.mcnc.bilinear_zero`), not rounded to 1/32 px as OpenCV's remap rounds them.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

from flexvox_core.motion.exp_kernel import exp32
from flexvox_core.motion.gather_weights import CUTOFF, MIN_WEIGHT


@numba.njit(inline="always", nogil=True, cache=True)
def own_reach(e: Any, reach: int) -> int:
    """The largest offset d <= ``reach`` with ``e``^(d²) >= :data:`CUTOFF` (0 where ``e`` <= CUTOFF):
    :func:`~flexvox_core.motion.mcnc.reaches` of one voxel."""
    e64 = min(float(e), 1.0)
    if e64 <= CUTOFF:
        return 0
    if e64 >= 1.0:
        return reach
    return min(reach, int(math.floor(math.sqrt(math.log(CUTOFF) / math.log(e64)))))


@numba.njit(nogil=True, cache=True)
def reach_thresholds(reach: int) -> Any:
    """float32 ``(reach + 2,)``: entry d (1 <= d <= ``reach``) the smallest float32 e with
    :func:`own_reach` (e, ``reach``) >= d, found by bisection over the float32 numbers of [0, 1] (whose bit
    patterns are in their order) with :func:`own_reach` itself; entry 0 is 0, entry reach + 1 is 2 (above every e).
    :func:`own_reach` rises with e, so it is the number of entries 1 … reach that e reaches: ``reach`` comparisons
    without a branch, where it takes two logarithms and a square root."""
    th = np.zeros(reach + 2, np.float32)
    th[reach + 1] = 2
    buf = np.zeros(1, np.float32)
    bits = buf.view(np.uint32)
    for d in range(1, reach + 1):
        lo = 0
        hi = 0x3F800000  # 1.0: own_reach is `reach` there
        while lo < hi:
            mid = (lo + hi) // 2
            bits[0] = mid
            if own_reach(buf[0], reach) >= d:
                hi = mid
            else:
                lo = mid + 1
        bits[0] = lo
        th[d] = buf[0]
    return th


def slot_tables(code: np.ndarray, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(row_hit, col_hit): :func:`lattice_sums`'s tables of an identity ``code`` (m, n, K) on a
    ``height`` × ``width`` picture, (K, height + 2) and (K, width + 2) float32."""
    m, n, K = code.shape
    pixel = np.argwhere(np.transpose(code, (2, 0, 1)))  # slot k's tile pixel (k, i, j), in slot order
    if len(pixel) != K or (pixel[:, 0] != np.arange(K)).any():
        raise ValueError(f"`code` must open each of its {K} slots in exactly one tile pixel (an identity code)")
    rows = np.zeros((K, height + 2), np.float32)
    cols = np.zeros((K, width + 2), np.float32)
    rows[:, 1:-1] = (np.arange(height)[None] % m) == pixel[:, 1, None]
    cols[:, 1:-1] = (np.arange(width)[None] % n) == pixel[:, 2, None]
    return rows, cols


@numba.njit(nogil=True, cache=True)
def lattice_sums(frames: Any, present: Any, row_hit: Any, col_hit: Any, flow_t: Any, near: Any, y0: int, x0: int,
                 t: int, S: int, inv_4nc1: Any, reach: int, num: Any, den: Any, thresholds: Any) -> None:
    """The unblurred sums (numerator into ``num``, weight into ``den``, both (h, w) float32) along the
    trajectories of the voxels of sub-frame ``t`` where ``near`` (h, w) is True, the box's top-left at
    (``y0``, ``x0``); 0 elsewhere in the box.

    ``frames`` (F, H, W) float32; ``present`` (F,) bool, the frames not dropped; ``row_hit`` (K, H + 2) and
    ``col_hit`` (K, W + 2) float32 (:func:`slot_tables`): 1 at the rows and the columns of an identity code's slot
    k's samples, shifted by one (pixel (y, x) holds slot k's iff ``row_hit[k, y + 1]`` and ``col_hit[k, x + 1]``;
    the first and last entries, outside the picture, are 0); ``flow_t`` (H, W, 2) float32 the sub-frame's flow
    (NaN or infinity read as still); ``inv_4nc1`` 1 / (4 n c1) float32; ``reach`` the largest offset;
    ``thresholds`` :func:`reach_thresholds` (``reach``): each voxel's own reach is counted on it (the bits of
    :func:`own_reach`, a tenth of the kernel's time faster on the 1-s clip), or an empty array: :func:`own_reach`.

    A row of the box at a time, its ``near`` voxels as a list, the offsets d outside the list: offset d's two
    sub-frames (their frame and slot) are the same for every voxel, and each read is split in two passes
    (:func:`_reads`), the positions' cells and fractions (vectorized: no loads through computed indices) and the
    loads with the sums. Each voxel's sum is added up in the order of a voxel's loop over d (forward, then back),
    so the bits are those of a kernel per voxel (``tests/flexvox_core/motion/lattice_reference.py``, a test).
    """
    K = row_hit.shape[0]
    h, w = near.shape
    one = np.float32(1)
    zero = np.float32(0)
    f_t = t // K
    k_t = t - f_t * K
    own = present[f_t]
    by_table = len(thresholds) > 0
    # The row's voxels to gather (their columns in the box) and their state along the offsets.
    cols = np.empty(w, np.int64)
    reach_of = np.empty(w, np.int32)
    e_of = np.empty(w, np.float32)
    flow_u = np.empty(w, np.float32)
    flow_v = np.empty(w, np.float32)
    e2 = np.empty(w, np.float32)
    weight = np.empty(w, np.float32)  # e^(d²)
    step = np.empty(w, np.float32)  # e^(2d + 1)
    fwd_x = np.empty(w, np.float32)
    fwd_y = np.empty(w, np.float32)
    back_x = np.empty(w, np.float32)
    back_y = np.empty(w, np.float32)
    acc_n = np.empty(w, np.float32)
    acc_d = np.empty(w, np.float32)
    cells = np.empty((8, w), np.int32)  # _reads' scratch
    frac = np.empty((2, w), np.float32)
    for i in range(h):
        y = y0 + i
        own_row = own and row_hit[k_t, y + 1] > 0
        n = 0
        for j in range(w):
            if near[i, j]:
                cols[n] = j
                n += 1
            else:
                num[i, j] = 0
                den[i, j] = 0
        for q in range(n):  # loads through the list (not vectorized)
            x = x0 + cols[q]
            flow_u[q] = flow_t[y, x, 0]
            flow_v[q] = flow_t[y, x, 1]
            if own_row and col_hit[k_t, x + 1] > 0:
                acc_n[q] = frames[f_t, y, x]
                acc_d[q] = one
            else:
                acc_n[q] = zero
                acc_d[q] = zero
        fy = np.float32(y)
        for q in range(n):  # vectorized: exp32 is arithmetic, no call
            u = flow_u[q]
            v = flow_v[q]
            ok = math.isfinite(u) and math.isfinite(v)
            u = u if ok else zero
            v = v if ok else zero
            flow_u[q] = u
            flow_v[q] = v
            e = exp32(-(one + u * u + v * v) * inv_4nc1)
            e_of[q] = e
            e2[q] = e * e
            weight[q] = one
            step[q] = e
            fx = np.float32(x0 + cols[q])
            fwd_x[q] = fx
            back_x[q] = fx
            fwd_y[q] = fy
            back_y[q] = fy
            reach_of[q] = 0
        if by_table:
            for d in range(1, reach + 1):  # own_reach(e, reach) counted on the table
                th = thresholds[d]
                for q in range(n):
                    reach_of[q] += e_of[q] >= th
        else:
            for q in range(n):
                reach_of[q] = own_reach(e_of[q], reach)
        longest = 0
        for q in range(n):
            longest = max(longest, reach_of[q])
        # The frame and slot of sub-frames t + d and t - d, stepped along with d (no division per offset).
        ff = bf = f_t
        fk = bk = k_t
        for d in range(1, longest + 1):
            fk += 1
            if fk == K:
                fk = 0
                ff += 1
            bk -= 1
            if bk < 0:
                bk = K - 1
                bf -= 1
            for q in range(n):  # every voxel stepped (vectorized); the reads count those reaching d alone
                weight[q] = weight[q] * step[q]
                step[q] = step[q] * e2[q]
                fwd_x[q] = fwd_x[q] + flow_u[q]
                fwd_y[q] = fwd_y[q] + flow_v[q]
                back_x[q] = back_x[q] - flow_u[q]
                back_y[q] = back_y[q] - flow_v[q]
            if t + d < S and present[ff]:
                _reads(frames[ff], row_hit[fk], col_hit[fk], fwd_y, fwd_x, weight, reach_of, d, n, acc_n, acc_d,
                       cells, frac)
            if t - d >= 0 and present[bf]:
                _reads(frames[bf], row_hit[bk], col_hit[bk], back_y, back_x, weight, reach_of, d, n, acc_n, acc_d,
                       cells, frac)
        for q in range(n):
            num[i, cols[q]] = acc_n[q]
            den[i, cols[q]] = acc_d[q]


@numba.njit(inline="always", nogil=True, cache=True)
def _reads(plane: Any, rows: Any, cols: Any, py: Any, px: Any, weight: Any, reach_of: Any, d: int, n: int,
           acc_n: Any, acc_d: Any, cells: Any, frac: Any) -> None:
    """:func:`lattice_sums`' reads of one sub-frame's ``plane`` (H, W) at (``py[q]``, ``px[q]``) for the list's
    first ``n`` voxels, the bilinear read of the samples and of their mask (0 outside the picture, as OpenCV's
    ``BORDER_CONSTANT``), weighted by ``weight[q]`` into ``acc_n[q]`` and ``acc_d[q]`` where ``reach_of[q]`` >= ``d``.
    ``rows`` (H + 2) and ``cols`` (W + 2) are the slot's tables (:func:`slot_tables`): a corner holds a sample where
    both are 1. Two passes: the cells' corners clamped into the tables' range (−1 … H, the tables' 0 outside the
    picture) and into the picture, and the fractions, into ``cells`` (8, n) and ``frac`` (2, n) (no load through a
    computed index, so it vectorizes); then the loads and the sums (the bits of a cell read as it is where it lies
    in the picture: a clamped corner of a cell outside it weighs 0)."""
    H, W = plane.shape
    one = np.float32(1)
    lo = np.int32(-1)
    top = np.int32(H)
    right = np.int32(W)
    first = np.int32(0)
    for q in range(n):
        y = py[q]
        x = px[q]
        y0 = np.int32(y)  # the floor (y, x are finite)
        y0 -= y < y0
        x0 = np.int32(x)
        x0 -= x < x0
        frac[0, q] = np.float32(y - np.float32(y0))
        frac[1, q] = np.float32(x - np.float32(x0))
        ya = min(max(y0, lo), top)
        yb = min(max(y0 + np.int32(1), lo), top)
        xa = min(max(x0, lo), right)
        xb = min(max(x0 + np.int32(1), lo), right)
        cells[0, q] = ya + np.int32(1)
        cells[1, q] = yb + np.int32(1)
        cells[2, q] = xa + np.int32(1)
        cells[3, q] = xb + np.int32(1)
        cells[4, q] = min(max(ya, first), top - np.int32(1))
        cells[5, q] = min(max(yb, first), top - np.int32(1))
        cells[6, q] = min(max(xa, first), right - np.int32(1))
        cells[7, q] = min(max(xb, first), right - np.int32(1))
    for q in range(n):
        if d > reach_of[q]:
            continue
        ay = frac[0, q]
        ax = frac[1, q]
        # unsigned indices (all >= 0 here): no wraparound of negative ones
        wya = (one - ay) * rows[np.uint32(cells[0, q])]
        wyb = ay * rows[np.uint32(cells[1, q])]
        wxa = (one - ax) * cols[np.uint32(cells[2, q])]
        wxb = ax * cols[np.uint32(cells[3, q])]
        ia = np.uint32(cells[4, q])
        ib = np.uint32(cells[5, q])
        ja = np.uint32(cells[6, q])
        jb = np.uint32(cells[7, q])
        val = (wya * (wxa * plane[ia, ja] + wxb * plane[ia, jb])
               + wyb * (wxa * plane[ib, ja] + wxb * plane[ib, jb]))
        w = weight[q]
        acc_n[q] += w * val
        acc_d[q] += w * ((wya + wyb) * (wxa + wxb))


@numba.njit(nogil=True, cache=True)
def divide_box(num: Any, den: Any, inside: Any, sampled: Any, y: Any, own_y: Any, own_x: Any, wide: Any, wide_y: Any,
               wide_x: Any, loo: Any, out: Any, short: Any) -> int:
    """The gather's last step on a box, after the spatial blur (:func:`~flexvox_core.motion.mcnc._finish`): at the
    voxels ``inside`` (h, w) bool, N / D into ``out`` (h, w) where D = ``den`` > float32 MIN_WEIGHT (``short``
    (h, w) bool set where not: the caller writes the fallback there); returns how many are short.

    With ``loo`` (h, w) float32 (an empty array: none) the leave-one-out at the voxels ``inside`` and ``sampled``
    (h, w; their values ``y``): (N − c·y) / (D − c) in float64, NaN where D − c <= MIN_WEIGHT, c = ``own_y[i]`` ·
    ``own_x[j]`` (float64: the weight a voxel gives itself in the blur, reflecting borders), mixed with
    ``wide_y[i]`` · ``wide_x[j]`` by ``wide`` (h, w) float32 g where given (an empty array: no mixture):
    c + g·(c_wide − c). The bits of the numpy steps this replaces (a test)."""
    h, w = num.shape
    limit = np.float32(MIN_WEIGHT)
    has_loo = loo.size > 0
    has_wide = wide.size > 0
    count = 0
    for i in range(h):
        for j in range(w):
            short[i, j] = False
            if not inside[i, j]:
                continue
            n = num[i, j]
            d = den[i, j]
            if has_loo and sampled[i, j]:
                own = own_y[i] * own_x[j]
                if has_wide:
                    own = own + np.float64(wide[i, j]) * (wide_y[i] * wide_x[j] - own)
                rest = np.float64(d) - own
                if rest > MIN_WEIGHT:
                    loo[i, j] = np.float32((np.float64(n) - own * np.float64(y[i, j])) / rest)
                else:
                    loo[i, j] = np.nan
            if d > limit:
                out[i, j] = n / d
            else:
                short[i, j] = True
                count += 1
    return count
