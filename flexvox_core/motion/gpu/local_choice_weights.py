r"""The local choice's per-pixel weights on the GPU: :func:`~flexvox_core.motion.local_choice.local_weights`.

For frame f and pixel p, with :math:`\ell_a, \ell_b` the two methods' leave-one-out estimates and y the sample,

.. math::

    e_m = [\ell_a, \ell_b \text{ finite}]\,(\ell_m - y)^2, \qquad
    w_a = \frac{(G_\sigma * e_b)^P}{(G_\sigma * e_a)^P + (G_\sigma * e_b)^P} \quad (1 \text{ where the sum}
    \le 10^{-30}),

G_σ OpenCV's Gaussian blur with reflecting borders (``BORDER_REFLECT``, the edge repeated), its kernel
``cv2.getGaussianKernel(round(8σ + 1) | 1, σ)``; the powers and the ratio in float64, as on the CPU. Above
:data:`~flexvox_core.motion.local_choice.COARSE_SIGMA` the blur runs on a grid ``step = ⌊σ/4⌋`` times coarser,
as :func:`~flexvox_core.motion.local_choice._pooled` does with OpenCV: ``cv2.resize`` with ``INTER_AREA`` down
to (⌈W/step⌉, ⌈H/step⌉) (each coarse cell the area-weighted mean of the pixels it covers, fractional at its
edges when the step does not divide the size: OpenCV's ``computeResizeAreaTab``), the blur of σ/step there,
and ``INTER_LINEAR`` back up (OpenCV's half-pixel centres: source x = (x + ½)·w/W − ½, clamped to the edge).
The resampling tables are computed on the host in float64 as OpenCV computes them, and uploaded.

One thread per pixel of every frame at once (or per coarse cell); float32 sums in OpenCV's order (rows first,
then columns; area cells row by row), so the pooled errors match OpenCV's to a few units in the last place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur, gaussian_taps, reflected, tap_sum
from flexvox_core.gpu.index import reflect, voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.gpu.resize import area_table, linear_table
from flexvox_core.motion import local_choice

F3 = "float32[:, :, ::1]"
COARSE_SIGMA = local_choice.COARSE_SIGMA
"""Above this pooling σ (px) the errors are pooled on the coarse grid (the CPU's)."""
POWER = local_choice.POWER
"""Exponent of the pooled errors (the CPU's)."""


def coarse_step(sigma: float) -> int:
    """The coarse grid's step for a pooling σ (0: pooled at full size)."""
    return 0 if sigma <= COARSE_SIGMA else int(sigma // 4)


@device
def _error(a, b, y, f, r, c):
    """(e_a, e_b) at one pixel: the squared leave-one-out errors where both are finite, else (0, 0)."""
    la = a[f, r, c]
    lb = b[f, r, c]
    if math.isfinite(la) and math.isfinite(lb):
        s = y[f, r, c]
        return (la - s) * (la - s), (lb - s) * (lb - s)
    return np.float32(0), np.float32(0)


@device
def _weight(pa, pb, power):
    """Method a's weight from the pooled errors (float64 powers and ratio; 1 where both are ~0)."""
    ea = 1.0
    eb = 1.0
    for _ in range(power):
        ea *= float(pa)
        eb *= float(pb)
    total = ea + eb
    if total > 1e-30:
        return np.float32(eb / total)
    return np.float32(1)


@device
def _error_a(loo, f, r, c, H, W):
    """e_a at (r, c) of frame f, c reflected: ``loo`` the pair (a, b) and the samples (a value
    :func:`~flexvox_core.gpu.filters.tap_sum` reads)."""
    ea, _ = _error(loo[0], loo[1], loo[2], f, r, reflect(c, W))
    return ea


@device
def _error_b(loo, f, r, c, H, W):
    """e_b at (r, c) of frame f, c reflected."""
    _, eb = _error(loo[0], loo[1], loo[2], f, r, reflect(c, W))
    return eb


@kernel(f"void({F3}, {F3}, {F3}, float32[::1], {F3}, {F3})")
def _errors_x(a, b, y, taps, ra, rb):
    """The errors of every frame blurred along x (reflecting)."""
    i = cuda.grid(1)
    F, H, W = ra.shape
    if i >= F * H * W:
        return
    f, r, c = voxel(i, H, W)
    ra[f, r, c] = tap_sum(_error_a, (a, b, y), f, r, c, H, W, taps, 2)
    rb[f, r, c] = tap_sum(_error_b, (a, b, y), f, r, c, H, W, taps, 2)


@kernel(f"void({F3}, {F3}, {F3}, int32[::1], int32[::1], float32[:, ::1], int32[::1], int32[::1], "
        f"float32[:, ::1], {F3}, {F3})")
def _area_errors(a, b, y, x0, xn, xw, y0, yn, yw, sa, sb):
    """The errors of every frame averaged over the coarse cells (OpenCV's INTER_AREA: row sums, then rows)."""
    i = cuda.grid(1)
    F, h, w = sa.shape
    if i >= F * h * w:
        return
    f, dy, dx = voxel(i, h, w)
    acc_a = np.float32(0)
    acc_b = np.float32(0)
    for j in range(yn[dy]):
        row_a = np.float32(0)
        row_b = np.float32(0)
        for k in range(xn[dx]):
            ea, eb = _error(a, b, y, f, y0[dy] + j, x0[dx] + k)
            row_a += ea * xw[dx, k]
            row_b += eb * xw[dx, k]
        acc_a += yw[dy, j] * row_a
        acc_b += yw[dy, j] * row_b
    sa[f, dy, dx] = acc_a
    sb[f, dy, dx] = acc_b


@kernel(f"void({F3}, {F3}, float32[::1], int32, {F3})")
def _blur_y2_weights(pa, pb, taps, power, out):
    """The column pass of the full-size pooling, and the weight from it."""
    i = cuda.grid(1)
    F, H, W = out.shape
    if i >= F * H * W:
        return
    f, r, c = voxel(i, H, W)
    sa = tap_sum(reflected, pa, f, r, c, H, W, taps, 1)
    sb = tap_sum(reflected, pb, f, r, c, H, W, taps, 1)
    out[f, r, c] = _weight(sa, sb, power)


@kernel(f"void({F3}, {F3}, int32[::1], float32[:, ::1], int32[::1], float32[:, ::1], int32, {F3})")
def _linear_weights(sa, sb, xl, xw, yl, yw, power, out):
    """The coarse pooled errors resized up (OpenCV's INTER_LINEAR: along x, then y), and the weight."""
    i = cuda.grid(1)
    F, H, W = out.shape
    if i >= F * H * W:
        return
    f, r, c = voxel(i, H, W)
    h, w = sa.shape[1], sa.shape[2]
    x0 = xl[c]
    x1 = min(x0 + 1, w - 1)
    r0 = yl[r]
    r1 = min(r0 + 1, h - 1)
    a0 = sa[f, r0, x0] * xw[c, 0] + sa[f, r0, x1] * xw[c, 1]
    a1 = sa[f, r1, x0] * xw[c, 0] + sa[f, r1, x1] * xw[c, 1]
    b0 = sb[f, r0, x0] * xw[c, 0] + sb[f, r0, x1] * xw[c, 1]
    b1 = sb[f, r1, x0] * xw[c, 0] + sb[f, r1, x1] * xw[c, 1]
    out[f, r, c] = _weight(a0 * yw[r, 0] + a1 * yw[r, 1], b0 * yw[r, 0] + b1 * yw[r, 1], power)


def local_weights(ws, loo_a, loo_b, samples, out, *, sigma: float, power: int = POWER) -> None:
    """Method a's weight per frame and pixel into ``out`` (F, H, W) float32 (device arrays), as
    :func:`flexvox_core.motion.local_choice.local_weights`.

    Parameters
    ----------
    ws : Workspace
    loo_a, loo_b : device array (F, H, W) float32
        Each method's leave-one-out estimate of every sample (NaN: none).
    samples : device array (F, H, W) float32
        The camera frames.
    out : device array (F, H, W) float32
    sigma : float
        Pooling standard deviation (px): the CPU's :func:`~flexvox_core.motion.local_choice.pooling_sigma`
        of the picture's size.
    power : int
        Exponent of the pooled errors.
    """
    F, H, W = out.shape
    for name, a in (("loo_a", loo_a), ("loo_b", loo_b), ("samples", samples)):
        if tuple(a.shape) != (F, H, W):
            raise ValueError(f"`{name}` must be (F, H, W) = {(F, H, W)} like `out`; got {tuple(a.shape)}")
    if not (math.isfinite(sigma) and sigma > 0) or isinstance(power, bool) or not isinstance(power, int) or power < 1:
        raise ValueError(f"`sigma` must be > 0 and `power` a whole number >= 1; got {sigma!r}, {power!r}")
    n = F * H * W
    step = coarse_step(sigma)
    if not step:
        taps = ws.put("choice.pool.taps", gaussian_taps(float(sigma)))
        ra = ws.get("choice.pool.ra", (F, H, W))
        rb = ws.get("choice.pool.rb", (F, H, W))
        launch(_errors_x, n, loo_a, loo_b, samples, taps, ra, rb)
        launch(_blur_y2_weights, n, ra, rb, taps, np.int32(power), out)
        return
    h, w = max(1, -(-H // step)), max(1, -(-W // step))
    x0, xn, xw = area_table(W, w)
    y0, yn, yw = area_table(H, h)
    sa = ws.get("choice.pool.sa", (F, h, w))
    sb = ws.get("choice.pool.sb", (F, h, w))
    ta = ws.get("choice.pool.ta", (F, h, w))
    tb = ws.get("choice.pool.tb", (F, h, w))
    launch(_area_errors, F * h * w, loo_a, loo_b, samples, ws.put("choice.pool.x0", x0),
           ws.put("choice.pool.xn", xn), ws.put("choice.pool.xw", xw), ws.put("choice.pool.y0", y0),
           ws.put("choice.pool.yn", yn), ws.put("choice.pool.yw", yw), sa, sb)
    taps = gaussian_taps(sigma / step)
    blur(ws, (sa, sb), (sa, sb), taps, taps, tag="choice.pool", scratch=(ta, tb))
    xl, xlw = linear_table(w, W)
    yl, ylw = linear_table(h, H)
    launch(_linear_weights, n, sa, sb, ws.put("choice.pool.xl", xl), ws.put("choice.pool.xlw", xlw),
           ws.put("choice.pool.yl", yl), ws.put("choice.pool.ylw", ylw), np.int32(power), out)
