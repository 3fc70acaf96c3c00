"""DIS optical flow on the GPU for a whole batch of image pairs per launch.

Dense Inverse Search (Kroeger, Timofte, Dai, Van Gool, "Fast Optical Flow using Dense Inverse Search",
ECCV 2016) as OpenCV's ``DISOpticalFlow`` (5.0) computes it, on every pair of a batch at once: per pyramid
level from coarse to fine, an inverse-compositional search of each patch (mean-normalised SSD, Gauss-Newton
steps), spatial propagation of the neighbours' flows, densification (each pixel's flow the average of the
covering patches' flows weighted by 1 / max(1, |I1(x + u) - I0(x)|)), variational refinement
(:mod:`flexvox_core.gpu.dis_refine`) and bilinear upsampling to the next level.

The patch search follows OpenCV's order exactly: the patch rows are cut into 8 stripes, and each stripe is
swept in raster order forward and then backward, every patch trying its own flow, its already-visited
left/right and upper/lower neighbours' and keeping the best before its Gauss-Newton steps. On the GPU one
thread holds one patch row and the rows of a stripe advance along anti-diagonals (patch (r, c) at step
r + c), with a block barrier per step: every patch sees the same neighbours as in the sequential sweep, so
the result is OpenCV's, with no approximation of the propagation.

:func:`dis_pairs` is the entry point; :class:`DisParams` holds the parameters (the "medium" preset by
default) and :class:`DisWorkspace` the device buffers, reused from call to call for the same sizes.
"""

from __future__ import annotations

import logging
import math
from collections import OrderedDict
from dataclasses import dataclass, fields

import numpy as np
from numba import cuda

from flexvox_core.gpu.device import simulator
from flexvox_core.gpu.dis_refine import RefineBuffers, refine_level, zero4
from flexvox_core.gpu.launch import BLOCK, SIM_BLOCK, device, kernel, launch

_logger = logging.getLogger(__name__)

BORDER = 16
"""OpenCV's replicated border around I1 (it bounds the clamp of the patch positions)."""
STRIPES = 8
"""Stripes of patch rows in the spatial propagation (OpenCV's fixed number)."""
EPS = np.float32(0.001)
INF = np.float32(1e10)
ZERO = np.float32(0.0)
ONE = np.float32(1.0)

PRESETS = {
    "ultrafast": dict(finest_scale=2, patch_stride=4, gradient_descent_iterations=12, variational_iterations=0),
    "fast": dict(finest_scale=2, patch_stride=4, gradient_descent_iterations=16, variational_iterations=5),
    "medium": dict(finest_scale=1, patch_stride=3, gradient_descent_iterations=25, variational_iterations=5),
}
"""OpenCV's presets (patch size 8 in all)."""


@dataclass(frozen=True)
class DisParams:
    """DIS's parameters, OpenCV's names and meanings. The defaults are OpenCV's "medium" preset with two
    fixed-point iterations of the refinement (what flexvox's CPU pipeline runs).

    patch_size, patch_stride : int
        Side of the square patches and the step between their top-left corners (pixels of a level).
    gradient_descent_iterations : int
        Gauss-Newton steps per patch, split evenly over the forward and backward sweep when
        ``use_spatial_propagation``.
    finest_scale : int
        The finest pyramid level searched (0: full size); the flow is upsampled from it.
    variational_iterations, sor_iterations : int
        Fixed-point iterations of the variational refinement (0: none) and red-black SOR sweeps in each
        (OpenCV fixes 5).
    alpha, delta, gamma, epsilon : float
        Smoothness, brightness-constancy and gradient-constancy weights, and the robust penalty's
        epsilon in sqrt(s² + epsilon²) (OpenCV's DIS default 0.01).
    use_mean_normalization, use_spatial_propagation : bool
        Patch distances with each patch's mean difference removed; neighbours' flows as candidates.
    """

    patch_size: int = 8
    patch_stride: int = 3
    gradient_descent_iterations: int = 25
    finest_scale: int = 1
    variational_iterations: int = 2
    sor_iterations: int = 5
    alpha: float = 20.0
    delta: float = 5.0
    gamma: float = 10.0
    epsilon: float = 0.01
    use_mean_normalization: bool = True
    use_spatial_propagation: bool = True

    def __post_init__(self):
        ints = {"patch_size": (2, 16), "patch_stride": (1, self.patch_size if _is_int(self.patch_size) else 16),
                "gradient_descent_iterations": (1, 1000), "finest_scale": (0, 10),
                "variational_iterations": (0, 1000), "sor_iterations": (0, 1000)}
        for name, (lo, hi) in ints.items():
            v = getattr(self, name)
            if not _is_int(v) or not lo <= v <= hi:
                raise ValueError(f"DisParams.{name} must be an integer from {lo} to {hi}; got {v!r}")
        for name in ("alpha", "delta", "gamma"):
            v = getattr(self, name)
            if not _is_real(v) or not math.isfinite(v) or v < 0:
                raise ValueError(f"DisParams.{name} must be a finite number >= 0; got {v!r}")
        if not _is_real(self.epsilon) or not math.isfinite(self.epsilon) or self.epsilon <= 0:
            raise ValueError(f"DisParams.epsilon must be a finite number > 0; got {self.epsilon!r}")
        for name in ("use_mean_normalization", "use_spatial_propagation"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"DisParams.{name} must be True or False; got {getattr(self, name)!r}")

    @classmethod
    def from_preset(cls, name: str, **overrides) -> DisParams:
        """OpenCV's preset ``name`` (ultrafast, fast, medium) with ``overrides`` (field names)."""
        if name not in PRESETS:
            raise ValueError(f"DIS preset must be one of {', '.join(PRESETS)}; got {name!r}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            raise ValueError(f"DisParams has no field {unknown[0]!r}; its fields: {', '.join(sorted(known))}")
        return cls(**{**PRESETS[name], **overrides})


def _is_int(v) -> bool:
    return isinstance(v, int | np.integer) and not isinstance(v, bool | np.bool_)


def _is_real(v) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)


def scales(H: int, W: int, p: DisParams) -> tuple[int, int]:
    """(finest, coarsest) pyramid scale for (H, W) images.

    OpenCV's rule: coarsest = min(int(log2(max(W, H) / (4 patch)) + 0.5), int(log2(min(W, H) // patch))),
    motions up to a quarter of the larger side and no level narrower than a patch. Where that is finer
    than ``finest_scale`` (small images) the levels run from the full size (0) to
    min(max(0, floor(log2(2 W / (5 patch)))), the patch bound) — OpenCV 5.0's levels there, measured for
    finest_scale 1 and 2 (older OpenCV reads past its buffers on such images).
    """
    psz = p.patch_size
    by_motion = int(math.log(max(W, H) / (4.0 * psz)) / math.log(2.0) + 0.5)
    by_patch = int(math.log(min(W, H) // psz) / math.log(2.0))
    coarsest = min(by_motion, by_patch)
    if coarsest >= p.finest_scale:
        return p.finest_scale, coarsest
    return 0, min(max(0, math.floor(math.log2(2.0 * W / (5.0 * psz)))), by_patch)


def level_shapes(H: int, W: int, p: DisParams) -> list[tuple[int, int]]:
    """(h, w) of the levels, finest first: H // 2**finest, then halved (floor) per level."""
    f, c = scales(H, W, p)
    out = [(H // 2**f, W // 2**f)]
    for _ in range(f, c):
        out.append((out[-1][0] // 2, out[-1][1] // 2))
    return out


def patch_grid(h: int, w: int, p: DisParams) -> tuple[int, int]:
    """(hs, ws): patches per column and per row of an (h, w) level."""
    return 1 + (h - p.patch_size) // p.patch_stride, 1 + (w - p.patch_size) // p.patch_stride


def _block() -> int:
    return SIM_BLOCK if simulator() else BLOCK


# ----------------------------------------------------------------------------------------------- pyramid


@device
def _area_span(d, scale, src):
    """First and last source index and the cell width of destination index ``d`` (INTER_AREA)."""
    f1 = d * scale
    f2 = f1 + scale
    cell = min(scale, src - f1)
    s1 = int(math.ceil(f1))
    s2 = min(int(math.floor(f2)), src - 1)
    s1 = min(s1, s2)
    lo = s1 - 1 if s1 - f1 > 1e-3 else s1
    hi = s2 if f2 - s2 > 1e-3 else s2 - 1
    return f1, f2, cell, s1, s2, lo, hi


@device
def _area_weight(s, f1, f2, cell, s1, s2):
    """Weight (float32) of source index ``s`` in a destination cell (OpenCV's area tables)."""
    if s < s1:
        return np.float32((s1 - f1) / cell)
    if s < s2:
        return np.float32(1.0 / cell)
    return np.float32(min(min(f2 - s2, 1.0), cell) / cell)


@device
def _round_half_even(x):
    r = int(math.floor(x))
    frac = x - np.float32(r)
    if frac > np.float32(0.5) or (frac == np.float32(0.5) and r % 2 == 1):
        r += 1
    return min(max(r, 0), 255)


@kernel("void(uint8[:, :, ::1], uint8[:, :, ::1], int32, int32, float64, float64)")
def _area_down(src, dst, n, k, sy, sx):
    """dst[m] = INTER_AREA resize of src[m], m < n; ``k`` > 0 an exact integer factor, else the general
    fractional cells of widths (sy, sx) source pixels."""
    t = cuda.grid(1)
    dh, dw = dst.shape[1], dst.shape[2]
    if t >= n * dh * dw:
        return
    m = t // (dh * dw)
    i = (t // dw) % dh
    j = t % dw
    if k > 0:
        s = 0
        for a in range(k):
            for b in range(k):
                s += np.int32(src[m, i * k + a, j * k + b])
        if k == 2:
            dst[m, i, j] = np.uint8((s + 2) >> 2)
        else:
            dst[m, i, j] = np.uint8(_round_half_even(np.float32(s) * np.float32(1.0 / (k * k))))
        return
    yf1, yf2, ycell, ys1, ys2, ylo, yhi = _area_span(i, sy, src.shape[1])
    xf1, xf2, xcell, xs1, xs2, xlo, xhi = _area_span(j, sx, src.shape[2])
    acc = ZERO
    for r in range(ylo, yhi + 1):
        beta = _area_weight(r, yf1, yf2, ycell, ys1, ys2)
        row = ZERO
        for c in range(xlo, xhi + 1):
            row = row + np.float32(src[m, r, c]) * _area_weight(c, xf1, xf2, xcell, xs1, xs2)
        acc = acc + beta * row
    dst[m, i, j] = np.uint8(_round_half_even(acc))


@kernel("void(uint8[:, :, ::1], int16[:, :, ::1], int16[:, :, ::1], int32)")
def _sobel(img, gx, gy, n):
    """3x3 Sobel derivatives of img[m], m < n, border reflected about the edge pixel (BORDER_REFLECT_101)."""
    t = cuda.grid(1)
    h, w = img.shape[1], img.shape[2]
    if t >= n * h * w:
        return
    m = t // (h * w)
    i = (t // w) % h
    j = t % w
    im = i - 1 if i > 0 else 1
    ip = i + 1 if i < h - 1 else h - 2
    jm = j - 1 if j > 0 else 1
    jp = j + 1 if j < w - 1 else w - 2
    a00, a01, a02 = np.int32(img[m, im, jm]), np.int32(img[m, im, j]), np.int32(img[m, im, jp])
    a10, a12 = np.int32(img[m, i, jm]), np.int32(img[m, i, jp])
    a20, a21, a22 = np.int32(img[m, ip, jm]), np.int32(img[m, ip, j]), np.int32(img[m, ip, jp])
    gx[m, i, j] = np.int16((a02 - a00) + 2 * (a12 - a10) + (a22 - a20))
    gy[m, i, j] = np.int16((a20 - a00) + 2 * (a21 - a01) + (a22 - a02))


@kernel("void(int16[:, :, ::1], int16[:, :, ::1], float32[:, :, :, ::1], int32, int32, int32)")
def _tensor(gx, gy, st, n, psz, pstride):
    """st[m, :, r, c] = sums over patch (r, c) of Ix², Iy², IxIy, Ix, Iy (exact integer sums)."""
    t = cuda.grid(1)
    hs, ws = st.shape[2], st.shape[3]
    if t >= n * hs * ws:
        return
    m = t // (hs * ws)
    r = (t // ws) % hs
    c = t % ws
    sxx = 0
    syy = 0
    sxy = 0
    sx = 0
    sy = 0
    for a in range(psz):
        for b in range(psz):
            x = np.int32(gx[m, r * pstride + a, c * pstride + b])
            y = np.int32(gy[m, r * pstride + a, c * pstride + b])
            sxx += x * x
            syy += y * y
            sxy += x * y
            sx += x
            sy += y
    st[m, 0, r, c] = np.float32(sxx)
    st[m, 1, r, c] = np.float32(syy)
    st[m, 2, r, c] = np.float32(sxy)
    st[m, 3, r, c] = np.float32(sx)
    st[m, 4, r, c] = np.float32(sy)


# ----------------------------------------------------------------------------------------------- patch search


@device
def _cost(img, gx, gy, n0, n1, ti, tj, ux, uy, psz, mean_norm, grad, xs, ys):
    """(SSD, dUx, dUy) of the patch at (ti, tj) of image n0 against image n1 moved by (ux, uy): the
    (mean-normalised) SSD and, with ``grad``, the Gauss-Newton right-hand side sum(d * grad I0)."""
    h, w = img.shape[1], img.shape[2]
    y = min(max(np.float32(ti) + uy + np.float32(BORDER), np.float32(BORDER - psz + 1)), np.float32(BORDER + h - 1))
    x = min(max(np.float32(tj) + ux + np.float32(BORDER), np.float32(BORDER - psz + 1)), np.float32(BORDER + w - 1))
    fy = np.float32(math.floor(y))
    fx = np.float32(math.floor(x))
    w11 = (y - fy) * (x - fx)
    w10 = (y - fy) * (fx + ONE - x)
    w01 = (fy + ONE - y) * (x - fx)
    w00 = (fy + ONE - y) * (fx + ONE - x)
    r0 = int(fy) - BORDER
    c0 = int(fx) - BORDER
    sd = ZERO
    sdd = ZERO
    sgx = ZERO
    sgy = ZERO
    for a in range(psz):
        ra = min(max(r0 + a, 0), h - 1)
        rb = min(max(r0 + a + 1, 0), h - 1)
        for b in range(psz):
            ca = min(max(c0 + b, 0), w - 1)
            cb = min(max(c0 + b + 1, 0), w - 1)
            d = (w00 * np.float32(img[n1, ra, ca]) + w01 * np.float32(img[n1, ra, cb])
                 + w10 * np.float32(img[n1, rb, ca]) + w11 * np.float32(img[n1, rb, cb])
                 - np.float32(img[n0, ti + a, tj + b]))
            sdd = sdd + d * d
            sd = sd + d
            if grad:
                sgx = sgx + d * np.float32(gx[n0, ti + a, tj + b])
                sgy = sgy + d * np.float32(gy[n0, ti + a, tj + b])
    if mean_norm:
        n = np.float32(psz * psz)
        return sdd - sd * sd / n, sgx - sd * xs / n, sgy - sd * ys / n
    return sdd, sgx, sgy


@device
def _visit(img, gx, gy, st, S, n0, n1, q, r, c, dr, dc, side, up, psz, pstride, inner, mean_norm, prop):
    """Search patch (r, c) of pair q: the best of its flow and its neighbours' (c - dc), (r - dr) where
    ``side``/``up``, then ``inner`` Gauss-Newton steps; the step is kept if it moved less than a patch."""
    ti = r * pstride
    tj = c * pstride
    sx = S[q, 0, r, c]
    sy = S[q, 1, r, c]
    if prop:
        best, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, sx, sy, psz, mean_norm, False, ZERO, ZERO)
        if side:
            cx = S[q, 0, r, c - dc]
            cy = S[q, 1, r, c - dc]
            cur, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, cx, cy, psz, mean_norm, False, ZERO, ZERO)
            if cur < best:
                best = cur
                sx = cx
                sy = cy
        if up:
            cx = S[q, 0, r - dr, c]
            cy = S[q, 1, r - dr, c]
            cur, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, cx, cy, psz, mean_norm, False, ZERO, ZERO)
            if cur < best:
                best = cur
                sx = cx
                sy = cy
    xx = st[n0, 0, r, c]
    yy = st[n0, 1, r, c]
    xy = st[n0, 2, r, c]
    det = xx * yy - xy * xy
    if abs(det) < EPS:
        det = EPS
    i11 = yy / det
    i12 = -xy / det
    i22 = xx / det
    xs = st[n0, 3, r, c]
    ys = st[n0, 4, r, c]
    ux = sx
    uy = sy
    prev = INF
    for _ in range(inner):
        ssd, dux, duy = _cost(img, gx, gy, n0, n1, ti, tj, ux, uy, psz, mean_norm, True, xs, ys)
        ux = ux - (i11 * dux + i12 * duy)
        uy = uy - (i12 * dux + i22 * duy)
        if ssd >= prev:
            break
        prev = ssd
    ex = ux - sx
    ey = uy - sy
    if np.float32(math.sqrt(ex * ex + ey * ey)) <= np.float32(psz):
        S[q, 0, r, c] = ux
        S[q, 1, r, c] = uy
    else:
        S[q, 0, r, c] = sx
        S[q, 1, r, c] = sy


@kernel("void(uint8[:, :, ::1], int16[:, :, ::1], int16[:, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], "
        "float32[:, :, :, ::1], int32[::1], int32[::1], int32, int32, int32, int32, int32, int32, int32)")
def _search(img, gx, gy, st, U, S, pa, pb, npairs, psz, pstride, inner, stripe_rows, mean_norm, prop):
    """Sparse flow S (P, 2, hs, ws) of one level from the dense flow U (P, 2, h, w) (its value at each
    patch centre to start from). One thread per patch row; a block holds whole stripes of
    ``stripe_rows`` rows, which sweep anti-diagonals with a barrier per step. Every thread of every block
    runs the same number of steps and barriers."""
    hs, ws = S.shape[2], S.shape[3]
    per_block = cuda.blockDim.x // stripe_rows
    k = cuda.threadIdx.x // stripe_rows
    lr = cuda.threadIdx.x - k * stripe_rows
    nstripes = (hs + stripe_rows - 1) // stripe_rows
    stripe = cuda.blockIdx.x * per_block + k
    q = stripe // nstripes
    s = stripe - q * nstripes
    r = s * stripe_rows + lr
    active = k < per_block and q < npairs and r < hs
    nrows = min(stripe_rows, hs - s * stripe_rows)
    n0 = 0
    n1 = 0
    if active:
        n0 = pa[q]
        n1 = pb[q]
        ci = r * pstride + psz // 2
        for c in range(ws):
            S[q, 0, r, c] = U[q, 0, ci, c * pstride + psz // 2]
            S[q, 1, r, c] = U[q, 1, ci, c * pstride + psz // 2]
    cuda.syncthreads()
    passes = 2 if prop else 1
    for ps in range(passes):
        fwd = ps % 2 == 0
        for step in range(ws + stripe_rows - 1):
            if active:
                order = lr if fwd else nrows - 1 - lr
                c = step - order
                if c >= 0 and c < ws:
                    d = 1 if fwd else -1
                    _visit(img, gx, gy, st, S, n0, n1, q, r, c if fwd else ws - 1 - c, d, d, c > 0, order > 0,
                           psz, pstride, inner, mean_norm, prop)
            cuda.syncthreads()


@kernel("void(uint8[:, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], int32[::1], int32[::1], int32, "
        "int32, int32)")
def _densify(img, S, U, pa, pb, npairs, psz, pstride):
    """U[q, :, i, j] = sum_k c_k S_k / sum_k c_k over the patches k covering (i, j) (the last patch past
    the last one), c_k = 1 / max(1, |I1(x + S_k) - I0(x)|), I1 bilinear and clamped inside the image."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    hs, ws = S.shape[2], S.shape[3]
    n0 = pa[q]
    n1 = pb[q]
    ihi = min(i // pstride, hs - 1)
    jhi = min(j // pstride, ws - 1)
    a = i - psz + 1
    ilo = min(0 if a <= 0 else (a + pstride - 1) // pstride, ihi)
    a = j - psz + 1
    jlo = min(0 if a <= 0 else (a + pstride - 1) // pstride, jhi)
    i0 = np.float32(img[n0, i, j])
    nx = ZERO
    ny = ZERO
    den = ZERO
    for r in range(ilo, ihi + 1):
        for c in range(jlo, jhi + 1):
            sx = S[q, 0, r, c]
            sy = S[q, 1, r, c]
            jm = min(max(np.float32(j) + sx, ZERO), np.float32(w) - ONE - EPS)
            im = min(max(np.float32(i) + sy, ZERO), np.float32(h) - ONE - EPS)
            jl = int(jm)
            il = int(im)
            fj = jm - np.float32(jl)
            fi = im - np.float32(il)
            gj = np.float32(jl + 1) - jm
            gi = np.float32(il + 1) - im
            diff = (fj * fi * np.float32(img[n1, il + 1, jl + 1]) + gj * fi * np.float32(img[n1, il + 1, jl])
                    + fj * gi * np.float32(img[n1, il, jl + 1]) + gj * gi * np.float32(img[n1, il, jl]) - i0)
            coef = ONE / max(ONE, abs(diff))
            nx = nx + coef * sx
            ny = ny + coef * sy
            den = den + coef
    U[q, 0, i, j] = nx / den
    U[q, 1, i, j] = ny / den


# ----------------------------------------------------------------------------------------------- resampling


@device
def _linear_tap(d, scale, src):
    """(first index, second index, weight of the second) of destination index ``d`` (INTER_LINEAR)."""
    f = (d + 0.5) * scale - 0.5
    s = int(math.floor(f))
    f -= s
    if s < 0:
        f = 0.0
        s = 0
    if s >= src - 1:
        f = 0.0
        s = src - 1
    return s, min(s + 1, src - 1), np.float32(f)


@device
def _bilinear(U, q, ch, y0, y1, fy, x0, x1, fx):
    top = U[q, ch, y0, x0] * (ONE - fx) + U[q, ch, y0, x1] * fx
    bot = U[q, ch, y1, x0] * (ONE - fx) + U[q, ch, y1, x1] * fx
    return top * (ONE - fy) + bot * fy


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32, float32, float64, float64)")
def _upsample(src, dst, npairs, factor, sy, sx):
    """dst[q] = factor * bilinear resize of src[q] (OpenCV's INTER_LINEAR, half-pixel centres)."""
    t = cuda.grid(1)
    h, w = dst.shape[2], dst.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    y0, y1, fy = _linear_tap(i, sy, src.shape[2])
    x0, x1, fx = _linear_tap(j, sx, src.shape[3])
    for ch in range(2):
        dst[q, ch, i, j] = _bilinear(src, q, ch, y0, y1, fy, x0, x1, fx) * factor


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32, float32, float64, float64)")
def _to_output(src, out, npairs, factor, sy, sx):
    """out[q, i, j, :] = factor * bilinear resize of src[q] (planes to interleaved (dx, dy))."""
    t = cuda.grid(1)
    h, w = out.shape[1], out.shape[2]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    y0, y1, fy = _linear_tap(i, sy, src.shape[2])
    x0, x1, fx = _linear_tap(j, sx, src.shape[3])
    for ch in range(2):
        out[q, i, j, ch] = _bilinear(src, q, ch, y0, y1, fy, x0, x1, fx) * factor


# ----------------------------------------------------------------------------------------------- host side


class DisWorkspace:
    """Device buffers of :func:`dis_pairs` for up to ``n_images`` images and ``n_pairs`` pairs of (H, W)
    images with parameters ``params``: per level the pyramid images, their gradients and structure tensors,
    the dense and sparse flows and the refinement's buffers. Reused by every call that fits."""

    def __init__(self, n_images: int, n_pairs: int, H: int, W: int, params: DisParams):
        self.n_images, self.n_pairs, self.H, self.W, self.params = n_images, n_pairs, H, W, params
        self.shapes = level_shapes(H, W, params)
        finest, _ = scales(H, W, params)
        self.levels = []
        for lev, (h, w) in enumerate(self.shapes):
            hs, ws = patch_grid(h, w, params)
            own = lev > 0 or finest > 0
            self.levels.append({
                "img": cuda.device_array((n_images, h, w), np.uint8) if own else None,
                "gx": cuda.device_array((n_images, h, w), np.int16),
                "gy": cuda.device_array((n_images, h, w), np.int16),
                "st": cuda.device_array((n_images, 5, hs, ws), np.float32),
                "U": cuda.device_array((n_pairs, 2, h, w), np.float32),
                "S": cuda.device_array((n_pairs, 2, hs, ws), np.float32),
                "refine": RefineBuffers(n_pairs, h, w) if params.variational_iterations > 0 else None,
            })
        _logger.debug("DIS workspace: %d images, %d pairs, %dx%d, levels %s", n_images, n_pairs, W, H, self.shapes)

    def fits(self, n_images: int, n_pairs: int, H: int, W: int, params: DisParams) -> bool:
        return (n_images <= self.n_images and n_pairs <= self.n_pairs and (H, W) == (self.H, self.W)
                and params == self.params)


_WORKSPACES: OrderedDict = OrderedDict()
_KEEP = 4


def workspace_for(n_images: int, n_pairs: int, H: int, W: int, params: DisParams) -> DisWorkspace:
    """A cached :class:`DisWorkspace` that fits (the last four are kept, the least recently used dropped)."""
    for key, ws in _WORKSPACES.items():
        if ws.fits(n_images, n_pairs, H, W, params):
            _WORKSPACES.move_to_end(key)
            return ws
    ws = DisWorkspace(n_images, n_pairs, H, W, params)
    _WORKSPACES[(n_images, n_pairs, H, W, params)] = ws
    while len(_WORKSPACES) > _KEEP:
        _WORKSPACES.popitem(last=False)
    return ws


def clear_workspaces() -> None:
    """Drop the cached workspaces (their device memory is freed when nothing else holds them)."""
    _WORKSPACES.clear()


def _index_array(name: str, v, n_images: int) -> np.ndarray:
    host = v.copy_to_host() if hasattr(v, "copy_to_host") else np.asarray(v)
    if host.ndim != 1 or host.size == 0 or not (np.issubdtype(host.dtype, np.integer)):
        raise ValueError(f"dis_pairs: {name} must be a non-empty 1-D integer array; got dtype {host.dtype}, "
                         f"shape {host.shape}")
    if host.min() < 0 or host.max() >= n_images:
        raise ValueError(f"dis_pairs: {name} must index the {n_images} images (0 to {n_images - 1}); got values "
                         f"from {host.min()} to {host.max()}")
    return np.ascontiguousarray(host, np.int32)


def dis_pairs(images, a, b, params: DisParams | None = None, *, out=None, workspace: DisWorkspace | None = None):
    """DIS flow from ``images[a[q]]`` to ``images[b[q]]`` for every pair q at once.

    Parameters
    ----------
    images : device array (N, H, W) uint8, C-contiguous
        The images (a host array is uploaded). Each side at least ``params.patch_size``.
    a, b : array (P,) of int
        Image indices of the pairs (host or device).
    params : DisParams
        Defaults to :class:`DisParams`'s ("medium", two refinement iterations).
    out : device array (P, H, W, 2) float32, optional
        Where to write the flow.
    workspace : DisWorkspace, optional
        Buffers to use; by default a cached one for these sizes.

    Returns
    -------
    device array (P, H, W, 2) float32
        The flow in pixels, (dx, dy): I1(x + u) ≈ I0(x).
    """
    p = DisParams() if params is None else params
    if not isinstance(p, DisParams):
        raise TypeError(f"dis_pairs: params must be a DisParams; got {type(p).__name__}")
    if not hasattr(images, "copy_to_host"):
        host = np.asarray(images)
        if host.dtype != np.uint8 or host.ndim != 3:
            raise ValueError(f"dis_pairs: images must be (N, H, W) uint8; got dtype {host.dtype}, shape {host.shape}")
        images = cuda.to_device(np.ascontiguousarray(host))
    if images.dtype != np.uint8 or images.ndim != 3 or not images.is_c_contiguous():
        raise ValueError(f"dis_pairs: images must be a C-contiguous (N, H, W) uint8 array; got dtype "
                         f"{images.dtype}, shape {images.shape}")
    N, H, W = images.shape
    if min(H, W) < p.patch_size:
        raise ValueError(f"dis_pairs: each image side must be at least patch_size {p.patch_size}; got {H}x{W}")
    ha, hb = _index_array("a", a, N), _index_array("b", b, N)
    if ha.shape != hb.shape:
        raise ValueError(f"dis_pairs: a and b must have the same length; got {ha.size} and {hb.size}")
    P = ha.size
    if out is None:
        out = cuda.device_array((P, H, W, 2), np.float32)
    elif out.shape != (P, H, W, 2) or out.dtype != np.float32 or not out.is_c_contiguous():
        raise ValueError(f"dis_pairs: out must be a C-contiguous ({P}, {H}, {W}, 2) float32 array; got dtype "
                         f"{out.dtype}, shape {out.shape}")
    ws = workspace if workspace is not None else workspace_for(N, P, H, W, p)
    if not ws.fits(N, P, H, W, p):
        raise ValueError(f"dis_pairs: the workspace holds {ws.n_images} images, {ws.n_pairs} pairs of "
                         f"{ws.H}x{ws.W}; got {N} images, {P} pairs of {H}x{W} (or other params)")
    block = _block()
    for h, w in ws.shapes:
        hs, _ = patch_grid(h, w, p)
        if math.ceil(hs / STRIPES) > block:
            raise ValueError(f"dis_pairs: {H}x{W} images give {math.ceil(hs / STRIPES)} patch rows per stripe; at "
                             f"most {block} (threads per block) fit")
    da, db = cuda.to_device(ha), cuda.to_device(hb)
    i32, f32 = np.int32, np.float32
    # pyramid, gradients and structure tensors of every image
    finest, _ = scales(H, W, p)
    src = images
    levels = []
    for lev, ((h, w), L) in enumerate(zip(ws.shapes, ws.levels, strict=True)):
        img = L["img"] if L["img"] is not None else images
        if lev > 0 or finest > 0:
            sh, sw = src.shape[1], src.shape[2]
            k = sh // h if (sh % h == 0 and sw % w == 0 and sh // h == sw // w) else 0
            launch(_area_down, N * h * w, src, img, i32(N), i32(k), sh / h, sw / w)
        launch(_sobel, N * h * w, img, L["gx"], L["gy"], i32(N))
        hs, ws_ = patch_grid(h, w, p)
        launch(_tensor, N * hs * ws_, L["gx"], L["gy"], L["st"], i32(N), i32(p.patch_size), i32(p.patch_stride))
        levels.append(img)
        src = img
    # coarse to fine
    prop = p.use_spatial_propagation
    inner = int(math.floor(p.gradient_descent_iterations / (2.0 if prop else 1.0)))
    zero4(ws.levels[-1]["U"], P)
    for lev in range(len(ws.shapes) - 1, -1, -1):
        (h, w), L, img = ws.shapes[lev], ws.levels[lev], levels[lev]
        hs, _ = patch_grid(h, w, p)
        rows = math.ceil(hs / STRIPES)
        stripes = P * math.ceil(hs / rows)
        count = math.ceil(stripes / (block // rows)) * block
        launch(_search, count, img, L["gx"], L["gy"], L["st"], L["U"], L["S"], da, db, i32(P), i32(p.patch_size),
               i32(p.patch_stride), i32(inner), i32(rows), i32(p.use_mean_normalization), i32(prop))
        launch(_densify, P * h * w, img, L["S"], L["U"], da, db, i32(P), i32(p.patch_size), i32(p.patch_stride))
        if p.variational_iterations > 0:
            refine_level(img, L["U"], da, db, P, L["refine"], p)
        if lev > 0:
            nh, nw = ws.shapes[lev - 1]
            launch(_upsample, P * nh * nw, L["U"], ws.levels[lev - 1]["U"], i32(P), f32(2.0), h / nh, w / nw)
    h, w = ws.shapes[0]
    launch(_to_output, P * H * W, ws.levels[0]["U"], out, i32(P), f32(2**finest), h / H, w / W)
    return out
