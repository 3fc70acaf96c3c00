"""DIS's variational refinement on the GPU, for a batch of pairs (OpenCV's ``VariationalRefinement``).

The flow W of a pyramid level is refined by dW minimising the Brox et al. 2004 energy (T. Brox, A. Bruhn,
N. Papenberg, J. Weickert, "High accuracy optical flow estimation based on a theory for warping",
ECCV 2004), linearised once about I1 warped by W:

    E(dW) = sum delta Psi((Iz + Ix du + Iy dv)² / (|grad I|² + zeta²))
          + gamma Psi((Ixz + Ixx du + Ixy dv)² / (Ixx² + Ixy² + zeta²)
                      + (Iyz + Ixy du + Iyy dv)² / (Iyy² + Ixy² + zeta²))
          + alpha Psi(|grad (W + dW)|²),        Psi(s²) = sqrt(s² + epsilon²),

with I the mean of I0 and the warped I1, Iz their difference and every derivative the central difference
[-1, 0, 1] with the edges replicated, zeta = 0.1. Each fixed-point iteration freezes the robust weights
Psi'(.) at the current dW, which leaves a linear system per pixel (2x2 data block, smoothness coupling to
the four neighbours through forward-difference weights); ``sor_iterations`` red-black SOR sweeps (omega 1.6)
solve it approximately, red pixels ((i + j) even) first.

The system's sums run in OpenCV's order (red pixels: right, left, lower, upper neighbour; black pixels:
left, right, upper, lower), so the float32 results follow OpenCV's to rounding.

References
----------
T. Brox, A. Bruhn, N. Papenberg, J. Weickert, "High accuracy optical flow estimation based on a theory for
warping", ECCV 2004.
T. Kroeger, R. Timofte, D. Dai, L. Van Gool, "Fast optical flow using dense inverse search", ECCV 2016.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.launch import device, kernel, launch

ZERO = np.float32(0.0)
ONE = np.float32(1.0)
HALF = np.float32(0.5)
ZETA2 = np.float32(0.1) * np.float32(0.1)
OMEGA = np.float32(1.6)


class RefineBuffers:
    """Device buffers of one level's refinement for up to ``n_pairs`` pairs of (h, w) flows."""

    def __init__(self, n_pairs: int, h: int, w: int):
        self.T = cuda.device_array((n_pairs, 2, h, w), np.float32)
        self.D = cuda.device_array((n_pairs, 8, h, w), np.float32)
        self.A = cuda.device_array((n_pairs, 5, h, w), np.float32)
        self.Wt = cuda.device_array((n_pairs, 1, h, w), np.float32)
        self.dU = cuda.device_array((n_pairs, 2, h, w), np.float32)


@kernel("void(float32[:, :, :, ::1], int32)")
def _zero(a, n):
    """a[:n] = 0."""
    t = cuda.grid(1)
    c, h, w = a.shape[1], a.shape[2], a.shape[3]
    if t >= n * c * h * w:
        return
    q = t // (c * h * w)
    k = (t // (h * w)) % c
    a[q, k, (t // w) % h, t % w] = ZERO


def zero4(a, n: int) -> None:
    """Set the first ``n`` entries of a (n, c, h, w) float32 device array to 0."""
    launch(_zero, n * a.shape[1] * a.shape[2] * a.shape[3], a, np.int32(n))


@kernel("void(uint8[:, :, ::1], float32[:, :, :, ::1], int32[::1], int32[::1], float32[:, :, :, ::1], int32)")
def _warp(img, U, pa, pb, T, npairs):
    """T[q] = (I0 / 2 + I1w / 2, I1w - I0), I1w = I1 sampled bilinearly at x + U (each tap clamped)."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    n1 = pb[q]
    mx = np.float32(j) + U[q, 0, i, j]
    my = np.float32(i) + U[q, 1, i, j]
    fx0 = np.float32(math.floor(mx))
    fy0 = np.float32(math.floor(my))
    fx = mx - fx0
    fy = my - fy0
    x0 = int(fx0)
    y0 = int(fy0)
    xa = min(max(x0, 0), w - 1)
    xb = min(max(x0 + 1, 0), w - 1)
    ya = min(max(y0, 0), h - 1)
    yb = min(max(y0 + 1, 0), h - 1)
    top = (ONE - fx) * np.float32(img[n1, ya, xa]) + fx * np.float32(img[n1, ya, xb])
    bot = (ONE - fx) * np.float32(img[n1, yb, xa]) + fx * np.float32(img[n1, yb, xb])
    warped = (ONE - fy) * top + fy * bot
    i0 = np.float32(img[pa[q], i, j])
    T[q, 0, i, j] = i0 * HALF + warped * HALF
    T[q, 1, i, j] = warped - i0


@device
def _dx(T, q, ch, r, c, w):
    """T[q, ch, r, c + 1] - T[q, ch, r, c - 1], columns clamped to the image."""
    return T[q, ch, r, min(c + 1, w - 1)] - T[q, ch, r, max(c - 1, 0)]


@device
def _dy(T, q, ch, r, c, h):
    return T[q, ch, min(r + 1, h - 1), c] - T[q, ch, max(r - 1, 0), c]


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32)")
def _derivatives(T, D, npairs):
    """D[q] = (Ix, Iy, Iz, Ixx, Ixy, Iyy, Ixz, Iyz) from T[q] = (I, Iz): central differences [-1, 0, 1],
    edges replicated; the second derivatives are differences of the first (Ixy = d/dy Ix)."""
    t = cuda.grid(1)
    h, w = T.shape[2], T.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    jm, jp = max(j - 1, 0), min(j + 1, w - 1)
    im, ip = max(i - 1, 0), min(i + 1, h - 1)
    D[q, 0, i, j] = _dx(T, q, 0, i, j, w)
    D[q, 1, i, j] = _dy(T, q, 0, i, j, h)
    D[q, 2, i, j] = T[q, 1, i, j]
    D[q, 3, i, j] = _dx(T, q, 0, i, jp, w) - _dx(T, q, 0, i, jm, w)
    D[q, 4, i, j] = _dx(T, q, 0, ip, j, w) - _dx(T, q, 0, im, j, w)
    D[q, 5, i, j] = _dy(T, q, 0, ip, j, h) - _dy(T, q, 0, im, j, h)
    D[q, 6, i, j] = _dx(T, q, 1, i, j, w)
    D[q, 7, i, j] = _dy(T, q, 1, i, j, h)


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], int32, float32, float32)")
def _smoothness(U, dU, Wt, npairs, alpha2, eps2):
    """Wt[q] = (alpha / 2) / sqrt(|grad (U + dU)|² + epsilon²), forward differences, 0 past the right and
    bottom edges."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    cu = U[q, 0, i, j] + dU[q, 0, i, j]
    cv = U[q, 1, i, j] + dU[q, 1, i, j]
    ux = ZERO
    vx = ZERO
    uy = ZERO
    vy = ZERO
    if j < w - 1:
        ux = (U[q, 0, i, j + 1] + dU[q, 0, i, j + 1]) - cu
        vx = (U[q, 1, i, j + 1] + dU[q, 1, i, j + 1]) - cv
    if i < h - 1:
        uy = (U[q, 0, i + 1, j] + dU[q, 0, i + 1, j]) - cu
        vy = (U[q, 1, i + 1, j] + dU[q, 1, i + 1, j]) - cv
    Wt[q, 0, i, j] = alpha2 / np.float32(math.sqrt(ux * ux + vx * vx + uy * uy + vy * vy + eps2))


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], "
        "float32[:, :, :, ::1], int32, float32, float32, float32)")
def _system(D, U, dU, Wt, A, npairs, delta2, gamma2, eps2):
    """A[q] = (A11, A12, A22, b1, b2) of the fixed-point iteration's linear system at each pixel: the data
    terms with their robust weights at the current dU, plus the smoothness edges (weight to the diagonal,
    weight times the difference of U to the right-hand side)."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    ix, iy, iz = D[q, 0, i, j], D[q, 1, i, j], D[q, 2, i, j]
    ixx, ixy, iyy = D[q, 3, i, j], D[q, 4, i, j], D[q, 5, i, j]
    ixz, iyz = D[q, 6, i, j], D[q, 7, i, j]
    du = dU[q, 0, i, j]
    dv = dU[q, 1, i, j]
    dn = ix * ix + iy * iy + ZETA2
    ik = iz + ix * du + iy * dv
    wt = (delta2 / np.float32(math.sqrt(ik * ik / dn + eps2))) / dn
    a11 = wt * (ix * ix) + ZETA2
    a12 = wt * (ix * iy)
    a22 = wt * (iy * iy) + ZETA2
    b1 = -wt * (iz * ix)
    b2 = -wt * (iz * iy)
    dn = ixx * ixx + ixy * ixy + ZETA2
    dn2 = iyy * iyy + ixy * ixy + ZETA2
    ikx = ixz + ixx * du + ixy * dv
    iky = iyz + ixy * du + iyy * dv
    wt = gamma2 / np.float32(math.sqrt(ikx * ikx / dn + iky * iky / dn2 + eps2))
    a11 = a11 + wt * (ixx * ixx / dn + ixy * ixy / dn2)
    a12 = a12 + wt * (ixx * ixy / dn + ixy * iyy / dn2)
    a22 = a22 + wt * (ixy * ixy / dn + iyy * iyy / dn2)
    b1 = b1 + -wt * (ixx * ixz / dn + ixy * iyz / dn2)
    b2 = b2 + -wt * (ixy * ixz / dn + iyy * iyz / dn2)
    sw = Wt[q, 0, i, j]
    wu0 = U[q, 0, i, j]
    wv0 = U[q, 1, i, j]
    rr = j < w - 1
    ll = j > 0
    dd = i < h - 1
    uu = i > 0
    wl = Wt[q, 0, i, j - 1] if ll else ZERO
    wu = Wt[q, 0, i - 1, j] if uu else ZERO
    eru = sw * (U[q, 0, i, j + 1] - wu0) if rr else ZERO
    erv = sw * (U[q, 1, i, j + 1] - wv0) if rr else ZERO
    elu = wl * (wu0 - U[q, 0, i, j - 1]) if ll else ZERO
    elv = wl * (wv0 - U[q, 1, i, j - 1]) if ll else ZERO
    edu = sw * (U[q, 0, i + 1, j] - wu0) if dd else ZERO
    edv = sw * (U[q, 1, i + 1, j] - wv0) if dd else ZERO
    euu = wu * (wu0 - U[q, 0, i - 1, j]) if uu else ZERO
    euv = wu * (wv0 - U[q, 1, i - 1, j]) if uu else ZERO
    if (i + j) % 2 == 0:  # red: OpenCV adds right, left, lower, upper
        if rr:
            a11, a22, b1, b2 = a11 + sw, a22 + sw, b1 + eru, b2 + erv
        if ll:
            a11, a22, b1, b2 = a11 + wl, a22 + wl, b1 - elu, b2 - elv
        if dd:
            a11, a22, b1, b2 = a11 + sw, a22 + sw, b1 + edu, b2 + edv
        if uu:
            a11, a22, b1, b2 = a11 + wu, a22 + wu, b1 - euu, b2 - euv
    else:  # black: left, right, upper, lower
        if ll:
            a11, a22, b1, b2 = a11 + wl, a22 + wl, b1 - elu, b2 - elv
        if rr:
            a11, a22, b1, b2 = a11 + sw, a22 + sw, b1 + eru, b2 + erv
        if uu:
            a11, a22, b1, b2 = a11 + wu, a22 + wu, b1 - euu, b2 - euv
        if dd:
            a11, a22, b1, b2 = a11 + sw, a22 + sw, b1 + edu, b2 + edv
    A[q, 0, i, j] = a11
    A[q, 1, i, j] = a12
    A[q, 2, i, j] = a22
    A[q, 3, i, j] = b1
    A[q, 4, i, j] = b2


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], int32, int32)")
def _sor(A, Wt, dU, npairs, colour):
    """One SOR half-sweep over the pixels with (i + j) % 2 == colour (one thread each):
    du += omega ((sum_n w_n du_n + b1 - A12 dv) / A11 - du), then dv likewise with the new du."""
    t = cuda.grid(1)
    h, w = dU.shape[2], dU.shape[3]
    half = (w + 1) // 2
    if t >= npairs * h * half:
        return
    q = t // (h * half)
    i = (t // half) % h
    j = 2 * (t % half) + ((i + colour) & 1)
    if j >= w:
        return
    sw = Wt[q, 0, i, j]
    wl = ZERO
    wu = ZERO
    lu, lv, ru, rv, uu, uv, du_, dv_ = ZERO, ZERO, ZERO, ZERO, ZERO, ZERO, ZERO, ZERO
    if j > 0:
        wl = Wt[q, 0, i, j - 1]
        lu, lv = dU[q, 0, i, j - 1], dU[q, 1, i, j - 1]
    if j < w - 1:
        ru, rv = dU[q, 0, i, j + 1], dU[q, 1, i, j + 1]
    if i > 0:
        wu = Wt[q, 0, i - 1, j]
        uu, uv = dU[q, 0, i - 1, j], dU[q, 1, i - 1, j]
    if i < h - 1:
        du_, dv_ = dU[q, 0, i + 1, j], dU[q, 1, i + 1, j]
    su = wl * lu + sw * ru + wu * uu + sw * du_
    sv = wl * lv + sw * rv + wu * uv + sw * dv_
    du = dU[q, 0, i, j]
    dv = dU[q, 1, i, j]
    nu = du + OMEGA * ((su + A[q, 3, i, j] - dv * A[q, 1, i, j]) / A[q, 0, i, j] - du)
    nv = dv + OMEGA * ((sv + A[q, 4, i, j] - nu * A[q, 1, i, j]) / A[q, 2, i, j] - dv)
    dU[q, 0, i, j] = nu
    dU[q, 1, i, j] = nv


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32)")
def _add(U, dU, npairs):
    """U[:npairs] += dU[:npairs]."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * 2 * h * w:
        return
    q = t // (2 * h * w)
    k = (t // (h * w)) % 2
    i = (t // w) % h
    j = t % w
    U[q, k, i, j] = U[q, k, i, j] + dU[q, k, i, j]


def refine_level(img, U, pa, pb, npairs: int, buf: RefineBuffers, p) -> None:
    """Refine the flows U[:npairs] (npairs, 2, h, w) of one level in place: pair q from image pa[q] to pb[q]
    of ``img`` (n, h, w) uint8, with ``p``'s alpha, delta, gamma, epsilon, variational_iterations and
    sor_iterations."""
    h, w = U.shape[2], U.shape[3]
    n = npairs * h * w
    i32, f32 = np.int32, np.float32
    launch(_warp, n, img, U, pa, pb, buf.T, i32(npairs))
    launch(_derivatives, n, buf.T, buf.D, i32(npairs))
    zero4(buf.dU, npairs)
    alpha2, delta2, gamma2 = f32(p.alpha) / f32(2), f32(p.delta) / f32(2), f32(p.gamma) / f32(2)
    eps2 = f32(p.epsilon) * f32(p.epsilon)
    for _ in range(p.variational_iterations):
        launch(_smoothness, n, U, buf.dU, buf.Wt, i32(npairs), alpha2, eps2)
        launch(_system, n, buf.D, U, buf.dU, buf.Wt, buf.A, i32(npairs), delta2, gamma2, eps2)
        for _ in range(p.sor_iterations):
            for colour in (0, 1):
                launch(_sor, npairs * h * ((w + 1) // 2), buf.A, buf.Wt, buf.dU, i32(npairs), i32(colour))
    launch(_add, 2 * n, U, buf.dU, i32(npairs))
