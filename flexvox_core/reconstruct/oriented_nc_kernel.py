"""The sums of :func:`~flexvox_core.reconstruct.oriented_nc.oriented_nc` for one sub-frame, compiled (numba), float32.

For sub-frame s the samples are first blurred along time — each pixel's own samples weighed by
``weight[k, b]`` (its slot k, frame ``first`` + b), the table of
:func:`~flexvox_core.reconstruct.diffusion.time_weights` — into two planes, values and weights; then
each wanted voxel sums them under its kernel of the bank, chosen from the structure tensor there, with
reflecting borders. Every loop over pixels that can run as vector code does: the time blur along each row, the
kernels' choice along each row (:func:`bank_row`, without branches) and each voxel's sums over its kernel's 9 rows
of 16 contiguous columns (:func:`dense_bank`, :func:`_dense_sums`; tap lists within 4 px of an edge). The sums are
float32, in the order LLVM's vector code takes: within a few float32 units of the float64 sums they replaced
(``tests/flexvox_core/reconstruct/oriented_float64.py``; 4·10⁻⁷ at most on the 1-s balls clip, values up to 1).
Each voxel is written once from its own sums, so the bits do not depend on how sub-frames are spread over threads.
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
    (:mod:`flexvox_core.motion.gpu.oriented_nc`); :func:`bank_row` makes the same comparisons a row at a time."""
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


@numba.njit(nogil=True, cache=True)
def bank_row(j, y, x0, x1, low, high, tan1, out):
    """:func:`bank_of` at columns [x0, x1) of row y of the structure tensor ``j`` (3, H, W) float32, into ``out``
    (W,) int8: the same comparisons in float64, written without branches (selects), so LLVM makes the loop vector
    code; the sectors' choice costs nothing to mispredict."""
    for x in range(np.uint64(x0), np.uint64(x1)):
        jxx = np.float64(j[0, y, x])
        jxy = np.float64(j[1, y, x])
        jyy = np.float64(j[2, y, x])
        a = jxx - jyy
        b = 2.0 * jxy
        trace = jxx + jyy
        spread2 = a * a + b * b
        lo_t = low * trace
        hi_t = high * trace
        some = (trace > 0.0) & (spread2 > lo_t * lo_t)
        level = np.int8(9) if spread2 > hi_t * hi_t else np.int8(1)  # 1 + (level − 1) · 8
        ax = abs(a)
        by = abs(b)
        up = b > 0.0
        diag = (np.int8(1) if up else np.int8(7)) if a > 0.0 else (np.int8(3) if up else np.int8(5))
        angle = (np.int8(2) if up else np.int8(6)) if ax <= tan1 * by else diag
        angle = (np.int8(0) if a >= 0.0 else np.int8(4)) if by <= tan1 * ax else angle
        out[x] = level + angle if some else np.int8(0)


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


REACH = 4
"""How far (px) the dense rows of :func:`dense_bank` reach: 2·REACH + 1 rows."""
ROW = 16
"""Columns of a kernel's row in :func:`dense_bank` (its 2·REACH + 1 and zeros)."""


def dense_bank(bank: np.ndarray) -> np.ndarray:
    """``bank`` (B, n, n), n ≤ 2·:data:`REACH` + 1 odd, as float32 (2, B, 2·REACH + 1, :data:`ROW`): each kernel
    centred in 2·REACH + 1 rows of ROW columns, zeros around; [1] the same without the centre tap (a sample's
    leave-one-out sums its other taps)."""
    B, n, _ = bank.shape
    if n % 2 != 1 or n > 2 * REACH + 1:
        raise ValueError(f"kernels of {n}×{n} px do not fit the dense rows ({2 * REACH + 1} px, odd sizes)")
    out = np.zeros((2, B, 2 * REACH + 1, ROW), np.float32)
    at = REACH - n // 2
    out[:, :, at:at + n, at:at + n] = bank
    out[1, :, REACH, REACH] = 0
    return out


@numba.njit(nogil=True, cache=True, fastmath={"contract", "reassoc", "nsz", "arcp"})
def _dense_sums(vflat, mflat, dense, o, kb, base, W):
    """The sums of kernel ``dense[o, kb]`` (2·REACH + 1 rows of ROW, :func:`dense_bank`) centred on flat index
    ``base`` of the planes (the voxel at least REACH px from every edge), float32. The columns outside, the rows
    inside (unrolled): LLVM makes the column loop vector loads and multiply-adds (``reassoc``: in its own order)."""
    num = np.float32(0)
    den = np.float32(0)
    w = np.uint64(W)
    p = np.uint64(base - REACH * W - REACH)
    for c in range(ROW):
        q = p + np.uint64(c)
        for r in range(2 * REACH + 1):
            g = dense[o, kb, r, c]
            num += g * vflat[q + np.uint64(r) * w]
            den += g * mflat[q + np.uint64(r) * w]
    return num, den


@numba.njit(nogil=True, cache=True)
def _time_blur(frames, order, weight, first, lo, hi, left, right, vt, mt):
    """Rows [lo, hi), columns [left, right) of the time-blurred planes ``vt``, ``mt`` (flat, float32): each pixel's
    samples weighed by ``weight[k, b]`` (its slot k; frames ``first`` + b in turn), and the weights summed. The
    weights are laid out along each of ``order``'s m rows first, so the loops over columns read contiguous memory
    (vector loads) with unsigned indices."""
    F, H, W = frames.shape
    m = order.shape[0]
    B = min(weight.shape[1], F - first)
    zero = np.float32(0)
    if B <= 0 or left >= right:
        return
    u0, u1 = np.uint64(left), np.uint64(right)
    along = np.empty((m, B, W), np.float32)
    for ym in range(m):
        for b in range(B):
            for x in range(left, right):
                along[ym, b, x] = weight[order[ym, x], b]
    for y in range(lo, hi):
        ws = along[y % m]
        v = vt[y * W:(y + 1) * W]
        t = mt[y * W:(y + 1) * W]
        w0 = ws[0]
        f0 = frames[first, y]
        for x in range(u0, u1):
            w = w0[x]
            v[x] = w * f0[x] if w != zero else zero  # a weight of 0 takes no value (inf · 0 would be NaN)
            t[x] = w
        for b in range(1, B):
            wb = ws[b]
            fb = frames[first + b, y]
            for x in range(u0, u1):
                w = wb[x]
                v[x] += w * fb[x] if w != zero else zero
                t[x] += w


@numba.njit(nogil=True, cache=True)
def oriented_plane(frames, order, weight, first, slot, frame, present, j, select, dense, offsets, weights, counts, h,
                   floor, y0, y1, x0, x1, vt, mt, out, fall, loo, low, high, tan1):
    """Rows [y0, y1) and columns [x0, x1) of sub-frame s (its ``slot`` = s mod K, ``frame`` = s div K): at each
    ``select``ed voxel, the kernel-weighted mean of the time-blurred samples into ``out`` (H, W) — the sample itself
    at the pixels of this slot in a ``present`` frame, whose leave-one-out estimate goes to ``loo[frame]`` —, and
    ``fall[y, x]`` (H, W) where the weights sum to at most ``floor`` (``fall`` is ``out``: left as it is). ``order``
    (m, W) repeats every m rows; ``weight`` (K, B) float32. At least :data:`REACH` px from the edges the kernels are
    the rows of :func:`dense_bank` (``dense``), nearer their tap lists (:func:`tap_lists`, reaching ``h`` px;
    ``weights`` float32) with reflecting borders. ``vt`` and ``mt`` (H·W + :data:`ROW`,) float32 are scratch planes
    for the time-blurred values and weights, every value in them finite (a dense row reads columns beyond its kernel
    at weight 0, and 0 · inf would be NaN);
    ``low``, ``high``, ``tan1``: the bank's rounding (:func:`bank_row`). The planes are read and written within h px
    of the block alone (``j`` within it).

    float32 sums: a sample's leave-one-out sums its other taps and its pixel's samples in the other frames (nothing
    subtracted), so it keeps float32's relative precision where the sample outweighs the rest."""
    F, H, W = frames.shape
    m = order.shape[0]
    B = weight.shape[1]
    # The rows and columns the kernels read (a reflection at the picture's edge stays within them).
    lo, hi = max(0, y0 - h), min(H, y1 + h)
    left, right = max(0, x0 - h), min(W, x1 + h)
    _time_blur(frames, order, weight, first, lo, hi, left, right, vt, mt)
    zero = np.float32(0)
    kbs = np.empty(W, np.int8)
    for y in range(y0, y1):
        ym = y % m
        inside_y = y - REACH >= 0 and y + REACH < H
        bank_row(j, y, x0, x1, low, high, tan1, kbs)
        for x in range(x0, x1):
            if not select[y, x]:
                continue
            kb = kbs[x]
            own = present and order[ym, x] == slot
            me = zero  # the weight of the taps that land on the voxel itself, left out of the sums for a sample
            if inside_y and x - REACH >= 0 and x + REACH < W:
                num, den = _dense_sums(vt, mt, dense, 1 if own else 0, kb, y * W + x, W)
                if own:
                    me = dense[0, kb, REACH, REACH]
            else:
                num = zero
                den = zero
                for t in range(counts[kb]):
                    g = weights[kb, t]
                    yy = _reflect(y + offsets[kb, t, 0], H)
                    xx = _reflect(x + offsets[kb, t, 1], W)
                    if own and yy == y and xx == x:
                        me += g
                    else:
                        num += g * vt[yy * W + xx]
                        den += g * mt[yy * W + xx]
            if own:
                out[y, x] = frames[frame, y, x]
                # The voxel's own time-blurred sums without its sample: its pixel's samples in the other frames.
                rest_v = zero
                rest_m = zero
                for b in range(B):
                    w = weight[slot, b]
                    if w != zero and first + b != frame and first + b < F:
                        rest_v += w * frames[first + b, y, x]
                        rest_m += w
                num += me * rest_v
                den += me * rest_m
                if den > floor:
                    loo[frame, y, x] = num / den
            elif den > floor:
                out[y, x] = num / den
            else:
                out[y, x] = fall[y, x]


@numba.njit(nogil=True, cache=True)
def band_spans(wanted, words, rows, out):
    """For each band of ``rows`` rows of ``wanted`` (H, W) bool, its first and last rows holding a wanted voxel and
    the first and last columns holding one within them (ends excluded) into ``out`` (⌈H / rows⌉, 4) int64 as
    (y0, y1, x0, x1); y0 = −1 where the band holds none. ``words`` (H, W // 8) uint64: the same rows' first
    8·(W // 8) columns read 8 at a time (``wanted.view`` of them). A row is read from each end to its first wanted
    voxel, a word at a time (in full where it holds none)."""
    H, W = wanted.shape
    n = words.shape[1]
    for b in range(out.shape[0]):
        y0, y1, x0, x1 = -1, 0, W, 0
        for y in range(b * rows, min(H, (b + 1) * rows)):
            row = wanted[y]
            k = 0
            while k < n and words[y, k] == 0:
                k += 1
            lo = 8 * k
            while lo < W and not row[lo]:
                lo += 1
            if lo == W:
                continue
            hi = W - 1
            while hi >= 8 * n and not row[hi]:
                hi -= 1
            if hi < 8 * n:
                k = n - 1
                while words[y, k] == 0:
                    k -= 1
                hi = 8 * k + 7
                while not row[hi]:
                    hi -= 1
            if y0 < 0:
                y0 = y
            y1 = y + 1
            x0 = min(x0, lo)
            x1 = max(x1, hi + 1)
        out[b, 0] = y0
        out[b, 1] = y1
        out[b, 2] = x0
        out[b, 3] = x1


@numba.njit(inline="always", nogil=True, cache=True)
def _reflect_ends(row, r, n):
    """The r values on each side of ``row[r:r + n]`` (n + 2r long) reflected from it (the edge repeated)."""
    for i in range(r):
        row[i] = row[r + _reflect(i - r, n)]
        row[r + n + i] = row[r + _reflect(n + i, n)]


@numba.njit(inline="always", nogil=True, cache=True)
def _blur_7(rows, k, y, h, out):
    """``out`` ← the 7 taps ``k`` down the column of ``rows`` (h, w) at row y (reflected)."""
    r0, r1, r2, r3 = rows[_reflect(y - 3, h)], rows[_reflect(y - 2, h)], rows[_reflect(y - 1, h)], rows[y]
    r4, r5, r6 = rows[_reflect(y + 1, h)], rows[_reflect(y + 2, h)], rows[_reflect(y + 3, h)]
    for x in range(out.shape[0]):
        out[x] = (k[0] * r0[x] + k[1] * r1[x] + k[2] * r2[x] + k[3] * r3[x] + k[4] * r4[x] + k[5] * r5[x]
                  + k[6] * r6[x])


@numba.njit(inline="always", nogil=True, cache=True)
def _blur_9(rows, k, y, h, out):
    """``out`` ← the 9 taps ``k`` down the column of ``rows`` (h, w) at row y (reflected)."""
    r0, r1, r2 = rows[_reflect(y - 4, h)], rows[_reflect(y - 3, h)], rows[_reflect(y - 2, h)]
    r3, r4, r5 = rows[_reflect(y - 1, h)], rows[y], rows[_reflect(y + 1, h)]
    r6, r7, r8 = rows[_reflect(y + 2, h)], rows[_reflect(y + 3, h)], rows[_reflect(y + 4, h)]
    for x in range(out.shape[0]):
        out[x] = (k[0] * r0[x] + k[1] * r1[x] + k[2] * r2[x] + k[3] * r3[x] + k[4] * r4[x] + k[5] * r5[x]
                  + k[6] * r6[x] + k[7] * r7[x] + k[8] * r8[x])


@numba.njit(nogil=True, cache=True, fastmath={"contract"})
def structure_block(g, kp, kq, j, b0, a0):
    """The structure tensor (J_xx, J_xy, J_yy) of the picture ``g`` (h, w) float32 C-contiguous into
    ``j[:, b0:b0 + h, a0:a0 + w]`` (j (3, H, W) float32 C-contiguous): ``g`` blurred by the 7 float32 taps ``kp``,
    Sobel's 3×3 derivatives scaled by ⅛, their products blurred by the 9 taps ``kq``, each filter separable with
    reflecting borders (the edge repeated) at ``g``'s own edges: the filters of
    :func:`~flexvox_core.reconstruct.oriented_nc.structure` (OpenCV's), in float32 with multiply-adds. Each pixel's
    arithmetic is the same wherever the vector loops end, so a block with margins gives the whole picture's values
    inside them. Every loop over a row's columns is vector code."""
    h, w = g.shape
    if kp.shape[0] != 7 or kq.shape[0] != 9:
        raise ValueError("structure_block is written for 7 taps, then 9")
    eighth = np.float32(0.125)
    two = np.float32(2)
    row = np.empty(w + 8, np.float32)
    t = np.empty((h, w), np.float32)
    for y in range(h):  # the pre-blur along x
        row[3:3 + w] = g[y]
        _reflect_ends(row, 3, w)
        out = t[y]
        for x in range(w):
            out[x] = (kp[0] * row[x] + kp[1] * row[x + 1] + kp[2] * row[x + 2] + kp[3] * row[x + 3]
                      + kp[4] * row[x + 4] + kp[5] * row[x + 5] + kp[6] * row[x + 6])
    p = np.empty((h, w), np.float32)
    for y in range(h):  # and along y
        _blur_7(t, kp, y, h, p[y])
    u = np.empty((3, h, w), np.float32)
    ps = np.empty(w + 2, np.float32)
    pd = np.empty(w + 2, np.float32)
    pxx = np.empty(w + 8, np.float32)
    pxy = np.empty(w + 8, np.float32)
    pyy = np.empty(w + 8, np.float32)
    for y in range(h):  # Sobel's derivatives, their products, the products' blur along x
        above = p[_reflect(y - 1, h)]
        here = p[y]
        below = p[_reflect(y + 1, h)]
        for x in range(w):
            ps[x + 1] = above[x] + two * here[x] + below[x]
            pd[x + 1] = below[x] - above[x]
        _reflect_ends(ps, 1, w)
        _reflect_ends(pd, 1, w)
        for x in range(w):
            gx = (ps[x + 2] - ps[x]) * eighth
            gy = (pd[x] + two * pd[x + 1] + pd[x + 2]) * eighth
            pxx[x + 4] = gx * gx
            pxy[x + 4] = gx * gy
            pyy[x + 4] = gy * gy
        _reflect_ends(pxx, 4, w)
        _reflect_ends(pxy, 4, w)
        _reflect_ends(pyy, 4, w)
        for k, row in enumerate((pxx, pxy, pyy)):
            out = u[k, y]
            for x in range(w):
                out[x] = (kq[0] * row[x] + kq[1] * row[x + 1] + kq[2] * row[x + 2] + kq[3] * row[x + 3]
                          + kq[4] * row[x + 4] + kq[5] * row[x + 5] + kq[6] * row[x + 6] + kq[7] * row[x + 7]
                          + kq[8] * row[x + 8])
    for k in range(3):  # the products' blur along y
        for y in range(h):
            _blur_9(u[k], kq, y, h, j[k, b0 + y, a0:a0 + w])
