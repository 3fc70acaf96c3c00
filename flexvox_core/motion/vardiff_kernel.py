"""One explicit step of the variable-tensor diffusion, compiled (numba), one pass per voxel.

The paper's §4 step 3: Eq. 2 with, at each voxel, the tensor of Eq. 4 oriented along the motion.

Written with OpenCV and numpy, each step cost four remaps and some twenty element-wise passes over
full-size temporaries per sub-frame, on one core. Here each voxel reads its neighbours, forms its
tensor's weights from its own flow and writes its update in one pass, the rows spread over
the cores. Each voxel's update depends only on the previous step, so the output bits do not depend
on the number of threads.

The step computes in float32 (the GPU twin's arithmetic): the volume's values, the flow and the scalars
(:func:`~flexvox_core.motion.vardiff.float32_step` gives them, ``dt`` within 2 dt trace T ≤ 1 − 2⁻²⁰, so the
rounding of the step's sums keeps each result within the range of the values it combines), with FMA contraction
(:data:`STEP_OPTIONS`). A read is taken at a whole pixel plus the flow's float32 offset, its cell exact and its
fraction within 3e-8 (:func:`_cell`): no float32 position x + u, whose rounding (6e-5 px at x = 640) can move a
Catmull-Rom read's clip
to the neighbouring cell. Against the float64 reference the step agrees to a few float32 ulps of the values.

Bilinear reads are exact (OpenCV rounds the fractional position to 1/32 px) and clamp at the
border (a neighbour outside the picture is the nearest edge pixel, OpenCV's ``BORDER_REPLICATE``).
A read whose taps all lie inside the picture (:func:`_bilinear`, :func:`_bicubic`) skips the clamps, which
change nothing there: the same arithmetic in the same order as the clamped read (the last bit may differ where FMA
contraction pairs its products and sums otherwise); there its indices are unsigned, so numba adds no wraparound of
negative indices (a compare and a select per index). :func:`vardiff_step` is compiled with LLVM's SLP vectorizer on
(:func:`_compiled_with_slp_vectorizer`): in float32 with FMA contraction, some 7 % less time a bilinear pair of reads
and 5 % more a bicubic pair (in float64 it took 20 % off a bicubic read): about even on the refinement's voxels.
``tests/flexvox_core/motion/vardiff_reference.py`` is the same step in plain
numpy and scipy, which the tests compare this against.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np

F0 = np.float32(0.0)
F1 = np.float32(1.0)
F2 = np.float32(2.0)
FH = np.float32(0.5)
F15 = np.float32(1.5)
F25 = np.float32(2.5)
FE6 = np.float32(1e-6)


@numba.njit(inline="always", nogil=True, cache=True)
def _cell(i, d):
    """The cell of the position i + d (i a whole pixel, d a float32 offset no larger than the picture): its first
    pixel i + ⌊d⌋, exact, and the fraction d − ⌊d⌋, within 3e-8 (no float32 position i + d, whose rounding grows
    with i)."""
    f = np.floor(d)
    return i + int(f), d - f


@numba.njit(inline="always", nogil=True, cache=True)
def _clamp_cell(i0, a, n):
    """The cell ``(i0, a)`` clamped to the picture's n pixels: a position before the first pixel is the first, one
    past the last the last (OpenCV's ``BORDER_REPLICATE``)."""
    if i0 < 0:
        return 0, F0
    if i0 >= n - 1:
        return n - 1, F0
    return i0, a


@numba.njit(inline="always", nogil=True, cache=True)
def _clamped_bilinear(plane, y, x, dy, dx):
    """Bilinear read at (y + dy, x + dx), clamped at the border."""
    H, W = plane.shape
    y0, ay = _cell(y, dy)
    x0, ax = _cell(x, dx)
    y0, ay = _clamp_cell(y0, ay, H)
    x0, ax = _clamp_cell(x0, ax, W)
    y1 = min(y0 + 1, H - 1)
    x1 = min(x0 + 1, W - 1)
    top = plane[y0, x0] * (F1 - ax) + plane[y0, x1] * ax
    bottom = plane[y1, x0] * (F1 - ax) + plane[y1, x1] * ax
    return top * (F1 - ay) + bottom * ay


@numba.njit(inline="always", nogil=True, cache=True)
def _catmull_rom(t):
    """Weights of the pixels at offsets -1, 0, 1, 2 for the fraction t (Keys' cubic, a = -1/2)."""
    t2 = t * t
    t3 = t2 * t
    return -FH * t3 + t2 - FH * t, F15 * t3 - F25 * t2 + F1, -F15 * t3 + F2 * t2 + FH * t, FH * t3 - FH * t2


@numba.njit(inline="always", nogil=True, cache=True)
def _clamped_bicubic(plane, y, x, dy, dx):
    """Catmull-Rom read at (y + dy, x + dx), clamped at the border as :func:`_clamped_bilinear`, and clipped to the
    range of the four pixels that read takes: still a convex combination of them."""
    H, W = plane.shape
    y0, ty = _cell(y, dy)
    x0, tx = _cell(x, dx)
    y0, ty = _clamp_cell(y0, ty, H)
    x0, tx = _clamp_cell(x0, tx, W)
    wx0, wx1, wx2, wx3 = _catmull_rom(tx)
    wy0, wy1, wy2, wy3 = _catmull_rom(ty)
    xa, xb, xc, xd = max(x0 - 1, 0), x0, min(x0 + 1, W - 1), min(x0 + 2, W - 1)
    ya, yb, yc, yd = max(y0 - 1, 0), y0, min(y0 + 1, H - 1), min(y0 + 2, H - 1)
    value = F0
    for yy, wy in ((ya, wy0), (yb, wy1), (yc, wy2), (yd, wy3)):
        value += wy * (wx0 * plane[yy, xa] + wx1 * plane[yy, xb] + wx2 * plane[yy, xc] + wx3 * plane[yy, xd])
    p00, p01, p10, p11 = plane[yb, xb], plane[yb, xc], plane[yc, xb], plane[yc, xc]
    lo = min(min(p00, p01), min(p10, p11))
    hi = max(max(p00, p01), max(p10, p11))
    return min(max(value, lo), hi)


@numba.njit(inline="always", nogil=True, cache=True)
def _bilinear(plane, y, x, dy, dx):
    """:func:`_clamped_bilinear`, its clamps skipped where the read's four taps are inside the picture (most reads):
    the same arithmetic."""
    H, W = plane.shape
    y0, ay = _cell(y, dy)
    x0, ax = _cell(x, dx)
    if 0 <= y0 < H - 1 and 0 <= x0 < W - 1:
        r0 = plane[np.uint64(y0)]  # unsigned indices (all >= 0 here): no wraparound of negative ones
        r1 = plane[np.uint64(y0 + 1)]
        xb, xc = np.uint64(x0), np.uint64(x0 + 1)
        top = r0[xb] * (F1 - ax) + r0[xc] * ax
        bottom = r1[xb] * (F1 - ax) + r1[xc] * ax
        return top * (F1 - ay) + bottom * ay
    return _clamped_bilinear(plane, y, x, dy, dx)


@numba.njit(inline="always", nogil=True, cache=True)
def _bicubic(plane, y, x, dy, dx):
    """:func:`_clamped_bicubic`, its clamps skipped where the read's sixteen taps are inside the picture: the same
    sums in the same order."""
    H, W = plane.shape
    y0, ty = _cell(y, dy)
    x0, tx = _cell(x, dx)
    if 1 <= y0 < H - 2 and 1 <= x0 < W - 2:
        wx0, wx1, wx2, wx3 = _catmull_rom(tx)
        wy0, wy1, wy2, wy3 = _catmull_rom(ty)
        ra = plane[np.uint64(y0 - 1)]  # unsigned indices (all >= 0 here): no wraparound of negative ones
        rb = plane[np.uint64(y0)]
        rc = plane[np.uint64(y0 + 1)]
        rd = plane[np.uint64(y0 + 2)]
        xa, xb, xc, xd = np.uint64(x0 - 1), np.uint64(x0), np.uint64(x0 + 1), np.uint64(x0 + 2)
        value = F0
        value += wy0 * (wx0 * ra[xa] + wx1 * ra[xb] + wx2 * ra[xc] + wx3 * ra[xd])
        value += wy1 * (wx0 * rb[xa] + wx1 * rb[xb] + wx2 * rb[xc] + wx3 * rb[xd])
        value += wy2 * (wx0 * rc[xa] + wx1 * rc[xb] + wx2 * rc[xc] + wx3 * rc[xd])
        value += wy3 * (wx0 * rd[xa] + wx1 * rd[xb] + wx2 * rd[xc] + wx3 * rd[xd])
        p00, p01, p10, p11 = rb[xb], rb[xc], rc[xb], rc[xc]
        lo = min(min(p00, p01), min(p10, p11))
        hi = max(max(p00, p01), max(p10, p11))
        return min(max(value, lo), hi)
    return _clamped_bicubic(plane, y, x, dy, dx)


STEP_OPTIONS: dict[str, Any] = {"parallel": True, "nogil": True, "fastmath": {"contract"}}
"""How :func:`vardiff_step` is compiled (besides its cache and the SLP vectorizer): rows over the threads, and FMA
contraction (a product and a sum in one rounding: some 20 % less time a bicubic read)."""


@numba.njit(cache=True, **STEP_OPTIONS)
def vardiff_step(vol, new, flow, mask, keep_samples, c1, c2, c3, dt, sharp, use_sharp, t0, t1, still2=0.0):
    """``new[t0:t1]`` = one explicit step of ``vol`` (S, H, W) float32 under the Eq. 4 tensors of ``flow``
    (S, H, W, 2) at sub-frames ``t0`` to ``t1`` (the rest of ``new`` is not written); voxels in ``mask`` stay
    as they are when ``keep_samples``. With ``use_sharp``, the voxels in ``sharp`` (S, H, W) read their
    trajectory neighbours by :func:`_clamped_bicubic`. Sub-frames 0 and S − 1 are the ends of time (the
    neighbour beyond them is the voxel itself): a band of a longer volume is stepped exactly where its
    neighbours were, one sub-frame in from each end that is not the longer volume's. A voxel whose speed² u² + v²
    is below ``still2`` is still: its flow is taken as zero. The scalars ``c1``, ``c2``, ``c3``, ``dt`` and
    ``still2`` are taken as float32 (:func:`~flexvox_core.motion.vardiff.float32_step` rounds ``dt`` within its
    bound)."""
    S, H, W = vol.shape
    a, b, k3 = np.float32(c1) - np.float32(c3), np.float32(c2) - np.float32(c3), np.float32(c3)  # float32 throughout
    step, still = np.float32(dt), np.float32(still2)
    reach_y, reach_x = np.float32(H), np.float32(W)  # an offset beyond the picture's size reads as its size
    for row in numba.prange(max(t1 - t0, 0) * H):  # rows, not sub-frames: a band of a few sub-frames fills the cores
        t = t0 + row // H
        y = row % H
        here = vol[t]  # the planes read
        after = vol[min(t + 1, S - 1)]
        before = vol[max(t - 1, 0)]
        vel = flow[t]
        fixed = mask[t]
        dst = new[t]
        for x in range(W):
            cur = here[y, x]
            if keep_samples and fixed[y, x]:
                dst[y, x] = here[y, x]
                continue
            u = vel[y, x, 0]
            v = vel[y, x, 1]
            if not math.isfinite(u):  # no flow measured there: still
                u = F0
            if not math.isfinite(v):
                v = F0
            speed2 = u * u + v * v
            if speed2 < still:  # still: no trajectory read (the flow made at a smaller scale is seldom exactly 0)
                u = F0
                v = F0
                speed2 = F0
            # Along λ: the neighbouring sub-frames, read at x ± (u, v); at zero flow (most
            # voxels: the gated flow of still regions) the bilinear read is the pixel itself.
            if u == F0 and v == F0:
                nxt = after[y, x] if t + 1 < S else cur
                prv = before[y, x] if t > 0 else cur
            else:
                # An offset beyond the picture's size reads as its size (the reads clamp there anyway).
                dy = min(max(v, -reach_y), reach_y)
                dx = min(max(u, -reach_x), reach_x)
                if use_sharp and sharp[t, y, x]:
                    nxt = _bicubic(after, y, x, dy, dx) if t + 1 < S else cur
                    prv = _bicubic(before, y, x, -dy, -dx) if t > 0 else cur
                else:
                    nxt = _bilinear(after, y, x, dy, dx) if t + 1 < S else cur
                    prv = _bilinear(before, y, x, -dy, -dx) if t > 0 else cur
            acc = a / (F1 + speed2) * (nxt + prv - F2 * cur)
            if b > 0:
                # Along ψ, within the sub-frame: ψ = (v, −u)/|(u, v)|, or (0, −1) where still.
                speed = np.float32(math.sqrt(speed2))
                if speed > FE6:
                    px = v / speed
                    py = -u / speed
                else:
                    px = F0
                    py = -F1
                acc += b * (_bilinear(here, y, x, py, px) + _bilinear(here, y, x, -py, -px) - F2 * cur)
            if k3 > 0:
                up = after[y, x] if t + 1 < S else cur
                dn = before[y, x] if t > 0 else cur
                lap = up + dn - F2 * cur
                if x + 1 < W:
                    lap += here[y, x + 1] - cur
                if x > 0:
                    lap += here[y, x - 1] - cur
                if y + 1 < H:
                    lap += here[y + 1, x] - cur
                if y > 0:
                    lap += here[y - 1, x] - cur
                acc += k3 * lap
            dst[y, x] = cur + step * acc


def _compiled_with_slp_vectorizer(dispatcher):
    """``dispatcher`` compiling (or loading from its cache) with LLVM's SLP vectorizer on, which numba leaves off
    (``NUMBA_SLP_VECTORIZE``; read at each compilation): it packs a bicubic read's independent products and
    loads into vector instructions. It does not reorder the sums."""
    compile_one = dispatcher.compile
    if not hasattr(numba.config, "SLP_VECTORIZE"):  # a numba without the setting: compiled as numba does
        return dispatcher

    def compile_with_slp(sig):
        kept = numba.config.SLP_VECTORIZE
        numba.config.SLP_VECTORIZE = 1
        try:
            return compile_one(sig)
        finally:
            numba.config.SLP_VECTORIZE = kept

    dispatcher.compile = compile_with_slp
    return dispatcher


vardiff_step = _compiled_with_slp_vectorizer(vardiff_step)
