"""Image pyramid and resampling kernels of the GPU DIS (:mod:`flexvox_core.gpu.dis`), as OpenCV computes them.

Levels are INTER_AREA reductions of uint8 images (an exact integer factor k: the k x k block mean, rounded
half up for k = 2 and half to even otherwise; any other factor: fractional cell coverage, weights in float32
from tables computed in double, rounded half to even), image gradients the 3x3 Sobel operator with the
border reflected about the edge pixel (int16), and the patches' structure tensors exact integer sums. Flows
move between levels by INTER_LINEAR (half-pixel centres, coordinates in double, weights in float32).
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.launch import device, kernel, launch

ZERO = np.float32(0.0)
ONE = np.float32(1.0)

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


def reduce(src, dst, n: int) -> None:
    """dst[:n] (n, h, w) uint8 = INTER_AREA reduction of src[:n] (n, sh, sw)."""
    sh, sw = src.shape[1], src.shape[2]
    h, w = dst.shape[1], dst.shape[2]
    k = sh // h if (sh % h == 0 and sw % w == 0 and sh // h == sw // w) else 0
    launch(_area_down, n * h * w, src, dst, np.int32(n), np.int32(k), sh / h, sw / w)


def gradients(img, gx, gy, st, n: int, patch_size: int, patch_stride: int) -> None:
    """Sobel gradients gx, gy (n, h, w) int16 of img[:n] and the structure tensors st (n, 5, hs, ws)."""
    h, w = img.shape[1], img.shape[2]
    launch(_sobel, n * h * w, img, gx, gy, np.int32(n))
    launch(_tensor, n * st.shape[2] * st.shape[3], gx, gy, st, np.int32(n), np.int32(patch_size),
           np.int32(patch_stride))


def upsample(src, dst, npairs: int, factor: float) -> None:
    """dst[:npairs] (P, 2, h, w) = factor * INTER_LINEAR resize of src[:npairs] (P, 2, sh, sw)."""
    h, w = dst.shape[2], dst.shape[3]
    launch(_upsample, npairs * h * w, src, dst, np.int32(npairs), np.float32(factor), src.shape[2] / h,
           src.shape[3] / w)


def to_output(src, out, npairs: int, factor: float) -> None:
    """out (P, H, W, 2) = factor * INTER_LINEAR resize of src[:npairs] (P, 2, h, w), (dx, dy) interleaved."""
    H, W = out.shape[1], out.shape[2]
    launch(_to_output, npairs * H * W, src, out, np.int32(npairs), np.float32(factor), src.shape[2] / H,
           src.shape[3] / W)
