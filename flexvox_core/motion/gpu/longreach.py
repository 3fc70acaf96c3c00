r"""The slow voxels' long-reach gather on the GPU: :func:`~flexvox_core.motion.longreach.long_reach_nc`.

Along each trajectory over ±``reach`` sub-frames, every sample s read at x + d·(u, v) (bilinear, 0 outside the
picture) weighs

.. math::

    w = \exp\left(-\frac{d^2}{2\sigma_t^2}\right) \exp\left(-\frac{(s - g)^2}{2h^2}\right),

g the guide at the voxel; the sums are blurred by a Gaussian of σ_s (3×3, zero borders) and divided. One thread
per voxel within the blur's reach of a selected one.

References
----------
C. Tomasi, R. Manduchi, "Bilateral filtering for gray and color images", ICCV 1998, pp. 839–846.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur, dilate, gaussian_taps
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import kernel, launch
from flexvox_core.motion.gpu.mcnc import bilinear_zero, velocity
from flexvox_core.motion.longreach import MIN_WEIGHT, LongReachPlan


@kernel("void(float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, :, ::1], float32[:, :, ::1], uint8[:, :, ::1], "
        "int32, float32, float32, float32[:, :, ::1], float32[:, :, ::1])")
def _range_weighted_sums(value, weight, flow, guide, act, reach, inv_2st2, scale, num, den):
    i = cuda.grid(1)
    S, H, W = value.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if not act[t, y, x]:
        num[t, y, x] = 0
        den[t, y, x] = 0
        return
    u, v = velocity(flow, t, y, x)
    g = guide[t, y, x]
    tiny = np.float32(1e-12)
    # d = 0: the voxel's own sample (if any).
    n0 = value[t, y, x]
    d0 = np.float32(weight[t, y, x])
    r = n0 / max(d0, tiny) - g
    w = math.exp(scale * r * r)
    acc_n = n0 * w
    acc_d = d0 * w
    fx = np.float32(x)
    fy = np.float32(y)
    bx = np.float32(x)
    by = np.float32(y)
    for d in range(1, reach + 1):
        fx += u
        fy += v
        bx -= u
        by -= v
        log_w = -np.float32(d * d) * inv_2st2
        if t + d < S:
            n1 = bilinear_zero(value, t + d, fy, fx, H, W)
            d1 = bilinear_zero(weight, t + d, fy, fx, H, W)
            r = n1 / max(d1, tiny) - g
            w = math.exp(scale * r * r + log_w)
            acc_n += n1 * w
            acc_d += d1 * w
        if t - d >= 0:
            n1 = bilinear_zero(value, t - d, by, bx, H, W)
            d1 = bilinear_zero(weight, t - d, by, bx, H, W)
            r = n1 / max(d1, tiny) - g
            w = math.exp(scale * r * r + log_w)
            acc_n += n1 * w
            acc_d += d1 * w
    num[t, y, x] = acc_n
    den[t, y, x] = acc_d


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, ::1], uint8[:, :, ::1], "
        "float32[:, :, ::1])")
def _finish(num, den, select, value, mask, out):
    i = cuda.grid(1)
    S, H, W = num.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if mask[t, y, x]:
        out[t, y, x] = value[t, y, x]
    elif select[t, y, x] and den[t, y, x] > MIN_WEIGHT:
        out[t, y, x] = num[t, y, x] / den[t, y, x]


def long_reach(ws, sparse, mask, flow, video, select, plan: LongReachPlan) -> None:
    """The range-weighted gather at the voxels ``select`` (S, H, W) uint8, guided by ``video`` and written into
    it; the samples are written back everywhere (``video`` = ``sparse`` at ``mask``). ``plan``: its reach, σ_t,
    σ_s and h, as the CPU's (:class:`~flexvox_core.motion.longreach.LongReachPlan`)."""
    S, H, W = sparse.shape
    n = S * H * W
    reach, sigma_t, sigma_s, h, radius = plan.reach, plan.sigma_t, plan.sigma_s, plan.h, plan.radius
    act = ws.get("longreach.act", (S, H, W), np.uint8)
    dilate(ws, select, act, radius, tag="longreach.dilate")
    num = ws.get("longreach.num", (S, H, W))
    den = ws.get("longreach.den", (S, H, W))
    launch(_range_weighted_sums, n, sparse, mask, flow, video, act, np.int32(reach),
           np.float32(1 / (2 * sigma_t * sigma_t)), np.float32(-0.5 / (h * h)), num, den)
    if radius:
        taps = gaussian_taps(sigma_s, 2 * radius + 1)
        blur(ws, num, num, taps, taps, reflect=False, tag="longreach.blur")
        blur(ws, den, den, taps, taps, reflect=False, tag="longreach.blur")
    launch(_finish, n, num, den, select, sparse, mask, video)
