"""The refinement's step as it was before it computed in float32 (a copy of ``flexvox_core/motion/vardiff_kernel.py``
at 674595b, uncached): float64 Python floats, each read at a float64 position. The ``refine-float64`` variant of
``bench/bench_motion_throughput.py`` (and of ``bench/bench_refinement.py``) patches it in; not the library's code."""
from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(inline="always", nogil=True, cache=False)
def _clamped_bilinear(plane, y, x):
    H, W = plane.shape
    y = min(max(y, 0.0), H - 1.0)
    x = min(max(x, 0.0), W - 1.0)
    y0 = int(y)  # y, x >= 0 here: truncation is the floor
    x0 = int(x)
    y1 = min(y0 + 1, H - 1)
    x1 = min(x0 + 1, W - 1)
    ay = y - y0
    ax = x - x0
    top = plane[y0, x0] * (1.0 - ax) + plane[y0, x1] * ax
    bottom = plane[y1, x0] * (1.0 - ax) + plane[y1, x1] * ax
    return top * (1.0 - ay) + bottom * ay


@numba.njit(inline="always", nogil=True, cache=False)
def _catmull_rom(t):
    """Weights of the pixels at offsets -1, 0, 1, 2 for the fraction t (Keys' cubic, a = -1/2)."""
    t2 = t * t
    t3 = t2 * t
    return -0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1.0, -1.5 * t3 + 2.0 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2


@numba.njit(inline="always", nogil=True, cache=False)
def _clamped_bicubic(plane, y, x):
    """Catmull-Rom read at (y, x), clamped at the border as :func:`_clamped_bilinear`, and clipped to the
    range of the four pixels that read takes: still a convex combination of them."""
    H, W = plane.shape
    y = min(max(y, 0.0), H - 1.0)
    x = min(max(x, 0.0), W - 1.0)
    y0 = int(y)
    x0 = int(x)
    wx0, wx1, wx2, wx3 = _catmull_rom(x - x0)
    wy0, wy1, wy2, wy3 = _catmull_rom(y - y0)
    xa, xb, xc, xd = max(x0 - 1, 0), x0, min(x0 + 1, W - 1), min(x0 + 2, W - 1)
    ya, yb, yc, yd = max(y0 - 1, 0), y0, min(y0 + 1, H - 1), min(y0 + 2, H - 1)
    value = 0.0
    for yy, wy in ((ya, wy0), (yb, wy1), (yc, wy2), (yd, wy3)):
        value += wy * (wx0 * plane[yy, xa] + wx1 * plane[yy, xb] + wx2 * plane[yy, xc] + wx3 * plane[yy, xd])
    p00, p01, p10, p11 = float(plane[yb, xb]), float(plane[yb, xc]), float(plane[yc, xb]), float(plane[yc, xc])
    lo = min(min(p00, p01), min(p10, p11))
    hi = max(max(p00, p01), max(p10, p11))
    return min(max(value, lo), hi)


@numba.njit(inline="always", nogil=True, cache=False)
def _bilinear(plane, y, x):
    """:func:`_clamped_bilinear`, its clamps skipped where the read's four taps are inside the picture (most reads):
    the same bits."""
    H, W = plane.shape
    if 0.0 <= y < H - 1.0 and 0.0 <= x < W - 1.0:
        y0 = int(y)
        x0 = int(x)
        ay = y - y0
        ax = x - x0
        r0 = plane[np.uint64(y0)]  # unsigned indices (all >= 0 here): no wraparound of negative ones
        r1 = plane[np.uint64(y0 + 1)]
        xb, xc = np.uint64(x0), np.uint64(x0 + 1)
        top = r0[xb] * (1.0 - ax) + r0[xc] * ax
        bottom = r1[xb] * (1.0 - ax) + r1[xc] * ax
        return top * (1.0 - ay) + bottom * ay
    return _clamped_bilinear(plane, y, x)


@numba.njit(inline="always", nogil=True, cache=False)
def _bicubic(plane, y, x):
    """:func:`_clamped_bicubic`, its clamps skipped where the read's sixteen taps are inside the picture: the same
    bits (the same sums in the same order)."""
    H, W = plane.shape
    if 1.0 <= y < H - 2.0 and 1.0 <= x < W - 2.0:
        y0 = int(y)
        x0 = int(x)
        wx0, wx1, wx2, wx3 = _catmull_rom(x - x0)
        wy0, wy1, wy2, wy3 = _catmull_rom(y - y0)
        ra = plane[np.uint64(y0 - 1)]  # unsigned indices (all >= 0 here): no wraparound of negative ones
        rb = plane[np.uint64(y0)]
        rc = plane[np.uint64(y0 + 1)]
        rd = plane[np.uint64(y0 + 2)]
        xa, xb, xc, xd = np.uint64(x0 - 1), np.uint64(x0), np.uint64(x0 + 1), np.uint64(x0 + 2)
        value = 0.0
        value += wy0 * (wx0 * ra[xa] + wx1 * ra[xb] + wx2 * ra[xc] + wx3 * ra[xd])
        value += wy1 * (wx0 * rb[xa] + wx1 * rb[xb] + wx2 * rb[xc] + wx3 * rb[xd])
        value += wy2 * (wx0 * rc[xa] + wx1 * rc[xb] + wx2 * rc[xc] + wx3 * rc[xd])
        value += wy3 * (wx0 * rd[xa] + wx1 * rd[xb] + wx2 * rd[xc] + wx3 * rd[xd])
        p00, p01, p10, p11 = float(rb[xb]), float(rb[xc]), float(rc[xb]), float(rc[xc])
        lo = min(min(p00, p01), min(p10, p11))
        hi = max(max(p00, p01), max(p10, p11))
        return min(max(value, lo), hi)
    return _clamped_bicubic(plane, y, x)


@numba.njit(parallel=True, nogil=True, cache=False)
def vardiff_step(vol, new, flow, mask, keep_samples, c1, c2, c3, dt, sharp, use_sharp, t0, t1, still2=0.0):
    """``new[t0:t1]`` = one explicit step of ``vol`` (S, H, W) float32 under the Eq. 4 tensors of ``flow``
    (S, H, W, 2) at sub-frames ``t0`` to ``t1`` (the rest of ``new`` is not written); voxels in ``mask`` stay
    as they are when ``keep_samples``. With ``use_sharp``, the voxels in ``sharp`` (S, H, W) read their
    trajectory neighbours by :func:`_clamped_bicubic`. Sub-frames 0 and S − 1 are the ends of time (the
    neighbour beyond them is the voxel itself): a band of a longer volume is stepped exactly where its
    neighbours were, one sub-frame in from each end that is not the longer volume's. A voxel whose speed² u² + v²
    is below ``still2`` is still: its flow is taken as zero."""
    S, H, W = vol.shape
    b = c2 - c3
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
            cur = float(here[y, x])
            if keep_samples and fixed[y, x]:
                dst[y, x] = here[y, x]
                continue
            u = float(vel[y, x, 0])
            v = float(vel[y, x, 1])
            if not math.isfinite(u):  # no flow measured there: still
                u = 0.0
            if not math.isfinite(v):
                v = 0.0
            speed2 = u * u + v * v
            if speed2 < still2:  # still: no trajectory read (the flow made at a smaller scale is seldom exactly 0)
                u = 0.0
                v = 0.0
                speed2 = 0.0
            # Along λ: the neighbouring sub-frames, read at x ± (u, v); at zero flow (most
            # voxels: the gated flow of still regions) the bilinear read is the pixel itself.
            if u == 0.0 and v == 0.0:
                nxt = float(after[y, x]) if t + 1 < S else cur
                prv = float(before[y, x]) if t > 0 else cur
            elif use_sharp and sharp[t, y, x]:
                nxt = _bicubic(after, y + v, x + u) if t + 1 < S else cur
                prv = _bicubic(before, y - v, x - u) if t > 0 else cur
            else:
                nxt = _bilinear(after, y + v, x + u) if t + 1 < S else cur
                prv = _bilinear(before, y - v, x - u) if t > 0 else cur
            acc = (c1 - c3) / (1.0 + speed2) * (nxt + prv - 2.0 * cur)
            if b > 0:
                # Along ψ, within the sub-frame: ψ = (v, −u)/|(u, v)|, or (0, −1) where still.
                speed = math.sqrt(speed2)
                if speed > 1e-6:
                    px = v / speed
                    py = -u / speed
                else:
                    px = 0.0
                    py = -1.0
                acc += b * (_bilinear(here, y + py, x + px) + _bilinear(here, y - py, x - px) - 2.0 * cur)
            if c3 > 0:
                up = float(after[y, x]) if t + 1 < S else cur
                dn = float(before[y, x]) if t > 0 else cur
                lap = up + dn - 2.0 * cur
                if x + 1 < W:
                    lap += float(here[y, x + 1]) - cur
                if x > 0:
                    lap += float(here[y, x - 1]) - cur
                if y + 1 < H:
                    lap += float(here[y + 1, x]) - cur
                if y > 0:
                    lap += float(here[y - 1, x]) - cur
                acc += c3 * lap
            dst[y, x] = cur + dt * acc


def _compiled_with_slp_vectorizer(dispatcher):
    """``dispatcher`` compiling (or loading from its cache) with LLVM's SLP vectorizer on, which numba leaves off
    (``NUMBA_SLP_VECTORIZE``; read at each compilation): it packs a bicubic read's independent products and
    float32-to-float64 conversions into vector instructions. It does not reorder the sums, so the same bits."""
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
