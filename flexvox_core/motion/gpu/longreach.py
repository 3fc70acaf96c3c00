r"""The slow voxels' long-reach gather on the GPU: :func:`~flexvox_core.motion.longreach.long_reach`.

Along each trajectory over ±``reach`` sub-frames, every sample s read at x + d·(u, v) (bilinear, 0 outside the
picture; only the pixel of the cell that holds sub-frame t + d's slot is read, from the camera frames:
:mod:`~flexvox_core.motion.longreach_kernel`) weighs

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

from flexvox_core.gpu.filters import blur, dilate
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import kernel, launch
from flexvox_core.motion.gpu.mcnc import velocity
from flexvox_core.motion.longreach import MIN_WEIGHT, LongReachPlan


@kernel("void(float32[:, :, ::1], int32[:, ::1], uint8[:, :, ::1], uint8[::1], float32[:, :, :, ::1], "
        "float32[:, :, ::1], uint8[:, :, ::1], float32[::1], float32, float32[:, :, ::1], float32[:, :, ::1])")
def _range_weighted_sums(frames, order, corners, present, flow, guide, act, time_w, scale, num, den):
    i = cuda.grid(1)
    S, H, W = guide.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if not act[t, y, x]:
        num[t, y, x] = 0
        den[t, y, x] = 0
        return
    m = corners.shape[0]
    n = corners.shape[1]
    K = corners.shape[2]
    zero = np.float32(0)
    one = np.float32(1)
    u, v = velocity(flow, t, y, x)
    g = guide[t, y, x]
    acc_n = zero
    acc_d = zero
    f = t // K
    if present[f] and order[y, x] == t % K:  # d = 0: the voxel's own sample
        s = frames[f, y, x]
        r = s - g
        e = math.exp(scale * r * r) * time_w[0]
        acc_n += s * e
        acc_d += e
    for d in range(1, time_w.shape[0]):
        for side in range(2):
            sign = 1 - 2 * side
            tt = t + sign * d
            if tt < 0 or tt >= S:
                continue
            ff = tt // K
            if not present[ff]:
                continue
            step = np.float32(sign * d)
            py = np.float32(y) + step * v
            px = np.float32(x) + step * u
            if not (np.float32(-1) < py < np.float32(H) and np.float32(-1) < px < np.float32(W)):
                continue
            y0 = int(py + one) - 1  # the floor (py > -1), in float32 as the CPU's
            x0 = int(px + one) - 1
            bits = corners[(y0 + m) % m, (x0 + n) % n, tt % K]  # y0, x0 >= -1
            if bits == 0:
                continue
            ay = py - np.float32(y0)
            ax = px - np.float32(x0)
            n1 = zero
            d1 = zero
            for b in range(4):
                if bits & (1 << b):
                    yy = y0 + (b >> 1)
                    xx = x0 + (b & 1)
                    if 0 <= yy < H and 0 <= xx < W:
                        wy = ay if b >> 1 else one - ay
                        wx = ax if b & 1 else one - ax
                        w = wy * wx
                        n1 += w * frames[ff, yy, xx]
                        d1 += w
            if d1 > zero:
                r = n1 / d1 - g
                e = math.exp(scale * r * r) * time_w[d]
                acc_n += n1 * e
                acc_d += d1 * e
    num[t, y, x] = acc_n
    den[t, y, x] = acc_d


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, ::1], int32[:, ::1], "
        "uint8[::1], float32[:, :, ::1])")
def _finish(num, den, select, frames, order, present, out):
    i = cuda.grid(1)
    S, H, W = num.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    K = S // frames.shape[0]
    f = t // K
    if present[f] and order[y, x] == t % K:
        out[t, y, x] = frames[f, y, x]
    elif select[t, y, x] and den[t, y, x] > np.float32(MIN_WEIGHT):  # in float32, as the CPU compares
        out[t, y, x] = num[t, y, x] / den[t, y, x]


def long_reach(ws, frames, order, present, corners, flow, video, select, plan: LongReachPlan) -> None:
    """The range-weighted gather at the voxels ``select`` (S, H, W) uint8, guided by ``video`` and written into
    it; the samples are written back everywhere. ``frames`` (F, H, W) float32, ``order`` (H, W) int32 each pixel's
    slot, ``present`` (F,) uint8 the frames captured, on the device; ``corners`` the host's
    :func:`~flexvox_core.motion.longreach_kernel.corner_table` of the code. ``plan``: its reach, σ_t, σ_s and h,
    as the CPU's (:class:`~flexvox_core.motion.longreach.LongReachPlan`)."""
    S, H, W = video.shape
    n = S * H * W
    radius = plan.radius
    act = ws.get("longreach.act", (S, H, W), np.uint8)
    dilate(ws, select, act, radius, tag="longreach.dilate")
    num = ws.get("longreach.num", (S, H, W))
    den = ws.get("longreach.den", (S, H, W))
    corners_d = ws.put("longreach.corners", np.ascontiguousarray(corners, np.uint8))
    time_w = ws.put("longreach.time_w", plan.time_weights)
    launch(_range_weighted_sums, n, frames, order, corners_d, present, flow, video, act, time_w,
           np.float32(plan.range_scale), num, den)
    if radius:
        taps = plan.taps
        blur(ws, num, num, taps, taps, reflect=False, tag="longreach.blur")
        blur(ws, den, den, taps, taps, reflect=False, tag="longreach.blur")
    launch(_finish, n, num, den, select, frames, order, present, video)
