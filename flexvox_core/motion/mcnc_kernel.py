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

from flexvox_core.motion.gather_weights import CUTOFF, MIN_WEIGHT


@numba.njit(inline="always", nogil=True, cache=True)
def _read(frames: Any, row_hit: Any, col_hit: Any, f: int, k: int, py: Any, px: Any, H: int, W: int
          ) -> tuple[Any, Any]:
    """Bilinear read at (py, px) of slot ``k``'s samples in frame ``f``, and of their mask. ``row_hit[k, y + 1]``
    (y from −1 to H) is 1 where row y holds slot k's samples, ``col_hit[k, x + 1]`` likewise, 0 outside the
    picture: a corner holds a sample where both are 1 (an identity code's slot: one pixel of each tile).
    Branch-free but for one test: a cell wholly in the picture is read as it is, another's four corners clamped
    into the picture (and onto the tables' 0 outside it); the corners are weighted by the tables."""
    y0 = int(py)  # the floor (py, px are finite): 20 % faster than math.floor here
    y0 -= py < y0
    x0 = int(px)
    x0 -= px < x0
    ay = np.float32(py - np.float32(y0))
    ax = np.float32(px - np.float32(x0))
    one = np.float32(1)
    if 0 <= y0 and y0 < H - 1 and 0 <= x0 and x0 < W - 1:  # the whole cell in the picture: no clamping
        wya = (one - ay) * row_hit[k, y0 + 1]
        wyb = ay * row_hit[k, y0 + 2]
        wxa = (one - ax) * col_hit[k, x0 + 1]
        wxb = ax * col_hit[k, x0 + 2]
        val = (wya * (wxa * frames[f, y0, x0] + wxb * frames[f, y0, x0 + 1])
               + wyb * (wxa * frames[f, y0 + 1, x0] + wxb * frames[f, y0 + 1, x0 + 1]))
        return val, (wya + wyb) * (wxa + wxb)
    ya = min(max(y0, -1), H)  # -1 and H: outside the picture, the tables' 0
    yb = min(max(y0 + 1, -1), H)
    xa = min(max(x0, -1), W)
    xb = min(max(x0 + 1, -1), W)
    wya = (one - ay) * row_hit[k, ya + 1]
    wyb = ay * row_hit[k, yb + 1]
    wxa = (one - ax) * col_hit[k, xa + 1]
    wxb = ax * col_hit[k, xb + 1]
    ia = min(max(ya, 0), H - 1)
    ib = min(max(yb, 0), H - 1)
    ja = min(max(xa, 0), W - 1)
    jb = min(max(xb, 0), W - 1)
    val = (wya * (wxa * frames[f, ia, ja] + wxb * frames[f, ia, jb])
           + wyb * (wxa * frames[f, ib, ja] + wxb * frames[f, ib, jb]))
    return val, (wya + wyb) * (wxa + wxb)


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
    """
    K = row_hit.shape[0]
    H = frames.shape[1]
    W = frames.shape[2]
    h, w = near.shape
    one = np.float32(1)
    f_t = t // K
    k_t = t - f_t * K
    own = present[f_t]
    for i in range(h):
        y = y0 + i
        own_row = own and row_hit[k_t, y + 1] > 0
        for j in range(w):
            if not near[i, j]:
                num[i, j] = 0
                den[i, j] = 0
                continue
            x = x0 + j
            u = flow_t[y, x, 0]
            v = flow_t[y, x, 1]
            if not (math.isfinite(u) and math.isfinite(v)):
                u = np.float32(0)
                v = np.float32(0)
            e = np.float32(math.exp(-(one + u * u + v * v) * inv_4nc1))
            if len(thresholds):
                r = 0
                for d in range(1, reach + 1):  # own_reach(e, reach), branch-free
                    r += e >= thresholds[d]
            else:
                r = own_reach(e, reach)
            acc_n = np.float32(0)
            acc_d = np.float32(0)
            if own_row and col_hit[k_t, x + 1] > 0:
                acc_n = frames[f_t, y, x]
                acc_d = one
            e2 = e * e
            wd = one
            step = e
            fx = np.float32(x)
            fy = np.float32(y)
            bx = np.float32(x)
            by = np.float32(y)
            # The frame and slot of sub-frames t + d and t - d, stepped along with d (no division per read).
            ff = bf = f_t
            fk = bk = k_t
            for d in range(1, r + 1):
                wd *= step
                step *= e2
                fx += u
                fy += v
                bx -= u
                by -= v
                fk += 1
                if fk == K:
                    fk = 0
                    ff += 1
                bk -= 1
                if bk < 0:
                    bk = K - 1
                    bf -= 1
                if t + d < S and present[ff]:
                    a, b = _read(frames, row_hit, col_hit, ff, fk, fy, fx, H, W)
                    acc_n += wd * a
                    acc_d += wd * b
                if t - d >= 0 and present[bf]:
                    a, b = _read(frames, row_hit, col_hit, bf, bk, by, bx, H, W)
                    acc_n += wd * a
                    acc_d += wd * b
            num[i, j] = acc_n
            den[i, j] = acc_d


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
