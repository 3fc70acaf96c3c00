"""The refinement on the GPU: explicit steps of the monotone variable-tensor diffusion
(:func:`~flexvox_core.motion.vardiff.variable_tensor_diffusion`), one thread per voxel and step.

The step is :func:`~flexvox_core.motion.vardiff_kernel.vardiff_step` line for line, in float32 with the same
scalars (:func:`~flexvox_core.motion.vardiff.float32_step`): exact bilinear reads clamped at the border, each at
a whole pixel plus an offset (its cell exact), clipped Catmull-Rom reads for the ``sharp`` voxels, the
samples held. Steps alternate
between two volumes; each reads only the previous step, so the result does not depend on the launch order.

References
----------
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Flexible voxels for motion-aware videography",
ECCV 2010 (the paper).
J. Weickert, *Anisotropic Diffusion in Image Processing*, Teubner, Stuttgart, 1998.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.motion.vardiff import explicit_steps, float32_step


@device
def _cell(i, d, n):
    """The cell of the position i + d on an axis of n pixels (i a whole pixel, |d| ≤ n a float32 offset), clamped to
    the picture: its first pixel, exact, and the fraction, within 3e-8 (no float32 position i + d)."""
    k = int(math.floor(d))
    i0 = i + k
    if i0 < 0:
        return 0, np.float32(0)
    if i0 >= n - 1:
        return n - 1, np.float32(0)
    return i0, d - np.float32(k)


@device
def _clamped_bilinear(plane, t, y, x, H, W):
    """Bilinear read at the float32 position (y, x), clamped at the border (the gaps' read)."""
    y = min(max(y, np.float32(0)), np.float32(H - 1))
    x = min(max(x, np.float32(0)), np.float32(W - 1))
    y0 = int(y)
    x0 = int(x)
    y1 = min(y0 + 1, H - 1)
    x1 = min(x0 + 1, W - 1)
    ay = y - np.float32(y0)
    ax = x - np.float32(x0)
    one = np.float32(1)
    top = plane[t, y0, x0] * (one - ax) + plane[t, y0, x1] * ax
    bottom = plane[t, y1, x0] * (one - ax) + plane[t, y1, x1] * ax
    return top * (one - ay) + bottom * ay


@device
def _bilinear_at(plane, t, y, x, dy, dx, H, W):
    """Bilinear read at the whole pixel (y, x) plus the offset (dy, dx), clamped at the border."""
    y0, ay = _cell(y, dy, H)
    x0, ax = _cell(x, dx, W)
    y1 = min(y0 + 1, H - 1)
    x1 = min(x0 + 1, W - 1)
    one = np.float32(1)
    top = plane[t, y0, x0] * (one - ax) + plane[t, y0, x1] * ax
    bottom = plane[t, y1, x0] * (one - ax) + plane[t, y1, x1] * ax
    return top * (one - ay) + bottom * ay


@device
def _cubic_weight(t, k):
    """Catmull-Rom (Keys' cubic, a = −½) weight of the pixel at offset k − 1 for the fraction t."""
    t2 = t * t
    t3 = t2 * t
    h = np.float32(0.5)
    if k == 0:
        return -h * t3 + t2 - h * t
    if k == 1:
        return np.float32(1.5) * t3 - np.float32(2.5) * t2 + np.float32(1)
    if k == 2:
        return -np.float32(1.5) * t3 + np.float32(2) * t2 + h * t
    return h * t3 - h * t2


@device
def _bicubic_at(plane, t, y, x, dy, dx, H, W):
    y0, fy = _cell(y, dy, H)
    x0, fx = _cell(x, dx, W)
    value = np.float32(0)
    for j in range(4):
        yy = min(max(y0 + j - 1, 0), H - 1)
        row = np.float32(0)
        for k in range(4):
            xx = min(max(x0 + k - 1, 0), W - 1)
            row += _cubic_weight(fx, k) * plane[t, yy, xx]
        value += _cubic_weight(fy, j) * row
    yb, yc = y0, min(y0 + 1, H - 1)
    xb, xc = x0, min(x0 + 1, W - 1)
    p00, p01, p10, p11 = plane[t, yb, xb], plane[t, yb, xc], plane[t, yc, xb], plane[t, yc, xc]
    lo = min(min(p00, p01), min(p10, p11))
    hi = max(max(p00, p01), max(p10, p11))
    return min(max(value, lo), hi)


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, :, ::1], uint8[:, :, ::1], uint8[:, :, ::1], "
        "float32, float32, float32, float32, float32)")
def _step(vol, new, flow, mask, sharp, c1, c2, c3, dt, still2):
    i = cuda.grid(1)
    S, H, W = vol.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    cur = vol[t, y, x]
    if mask[t, y, x]:
        new[t, y, x] = cur
        return
    u = flow[t, y, x, 0]
    v = flow[t, y, x, 1]
    if not math.isfinite(u):
        u = np.float32(0)
    if not math.isfinite(v):
        v = np.float32(0)
    speed2 = u * u + v * v
    if speed2 < still2:  # still: no trajectory read
        u = np.float32(0)
        v = np.float32(0)
        speed2 = np.float32(0)
    two = np.float32(2)
    dy = min(max(v, -np.float32(H)), np.float32(H))  # an offset beyond the picture's size reads as its size
    dx = min(max(u, -np.float32(W)), np.float32(W))
    if u == 0 and v == 0:
        nxt = vol[t + 1, y, x] if t + 1 < S else cur
        prv = vol[t - 1, y, x] if t > 0 else cur
    elif sharp[t, y, x]:
        nxt = _bicubic_at(vol, t + 1, y, x, dy, dx, H, W) if t + 1 < S else cur
        prv = _bicubic_at(vol, t - 1, y, x, -dy, -dx, H, W) if t > 0 else cur
    else:
        nxt = _bilinear_at(vol, t + 1, y, x, dy, dx, H, W) if t + 1 < S else cur
        prv = _bilinear_at(vol, t - 1, y, x, -dy, -dx, H, W) if t > 0 else cur
    acc = (c1 - c3) / (np.float32(1) + speed2) * (nxt + prv - two * cur)
    b = c2 - c3
    if b > 0:
        speed = math.sqrt(speed2)
        if speed > np.float32(1e-6):
            px = v / speed
            py = -u / speed
        else:
            px = np.float32(0)
            py = np.float32(-1)
        acc += b * (_bilinear_at(vol, t, y, x, py, px, H, W)
                    + _bilinear_at(vol, t, y, x, -py, -px, H, W) - two * cur)
    if c3 > 0:
        up = vol[t + 1, y, x] if t + 1 < S else cur
        dn = vol[t - 1, y, x] if t > 0 else cur
        lap = up + dn - two * cur
        if x + 1 < W:
            lap += vol[t, y, x + 1] - cur
        if x > 0:
            lap += vol[t, y, x - 1] - cur
        if y + 1 < H:
            lap += vol[t, y + 1, x] - cur
        if y > 0:
            lap += vol[t, y - 1, x] - cur
        acc += c3 * lap
    new[t, y, x] = cur + dt * acc


def refine(ws, video, mask, flow, sharp, *, c, time: float, still_speed: float | None = None) -> None:
    """``video`` (S, H, W) float32 diffused for ``time`` under Eq. 4's tensors of ``flow`` with eigenvalues ``c``,
    in place; ``mask`` (uint8) voxels held, ``sharp`` (uint8) voxels read along the trajectory by clipped
    Catmull-Rom, voxels slower than ``still_speed`` taken as still (zero flow). Device arrays (views of a window's
    sub-frames will do)."""
    c1, c2, c3 = (float(v) for v in c)
    steps = explicit_steps(time, (c1, c2, c3))
    if not steps:
        return
    scalars = float32_step((c1, c2, c3), time / steps, 0 if still_speed is None else float(still_speed) ** 2)
    S, H, W = video.shape
    other = ws.get("refine.other", (S, H, W))
    src, dst = video, other
    for _ in range(steps):
        launch(_step, S * H * W, src, dst, flow, mask, sharp, *scalars)
        src, dst = dst, src
    if src is not video:
        video.copy_to_device(src)
