r"""The trajectory gather on the GPU: :func:`~flexvox_core.motion.mcnc.motion_compensated_nc`'s sums.

At every voxel within the spatial blur's reach of a gathered one, the samples of sub-frames t ± d are read at
x ± d·(u, v) (bilinear, 0 outside the picture) with the weights of Eq. 3 along the trajectory,

.. math::

    w_d = e^{d^2}, \qquad e = \exp\left(-\frac{1 + u^2 + v^2}{4 n c_1}\right),

each voxel reaching as far as its own weights stay above :data:`~flexvox_core.motion.gather_weights.CUTOFF`; the sums of
values and of weights are then blurred in space (σ = √(2 n c₂), reflecting borders), mixed per voxel with a
wide blur by the noise-aware weight g, and divided. Each sample the gather estimates also gets its
leave-one-out estimate (N − c·y) / (D − c). One thread per voxel; the CPU gathers a list of voxels per
sub-frame instead, with OpenCV's remap (which rounds positions to 1/32 px): the same sums up to that rounding.

References
----------
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Flexible voxels for motion-aware videography",
ECCV 2010 (the paper).
H. Knutsson, C.-F. Westin, "Normalized and differential convolution: methods for interpolation and filtering of
incomplete and uncertain data", CVPR 1993, pp. 515–523.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur, dilate, gaussian_taps
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.motion.gather_weights import CUTOFF, MIN_WEIGHT
from flexvox_core.reconstruct.diffusion import self_weights


@device
def bilinear_zero(plane, t, y, x, H, W):
    """Bilinear read of ``plane[t]`` at (y, x), pixels outside the picture 0 (``BORDER_CONSTANT``)."""
    fy = math.floor(y)
    fx = math.floor(x)
    y0 = int(fy)
    x0 = int(fx)
    ay = np.float32(y - fy)
    ax = np.float32(x - fx)
    one = np.float32(1)
    acc = np.float32(0)
    if 0 <= y0 < H:
        if 0 <= x0 < W:
            acc += (one - ay) * (one - ax) * plane[t, y0, x0]
        if 0 <= x0 + 1 < W:
            acc += (one - ay) * ax * plane[t, y0, x0 + 1]
    if 0 <= y0 + 1 < H:
        if 0 <= x0 < W:
            acc += ay * (one - ax) * plane[t, y0 + 1, x0]
        if 0 <= x0 + 1 < W:
            acc += ay * ax * plane[t, y0 + 1, x0 + 1]
    return acc


@device
def velocity(flow, t, y, x):
    """(u, v) of the voxel (t, y, x), NaN or infinity read as still (no flow measured there)."""
    u = flow[t, y, x, 0]
    v = flow[t, y, x, 1]
    if not (math.isfinite(u) and math.isfinite(v)):
        return np.float32(0), np.float32(0)
    return u, v


@kernel("void(float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, :, ::1], uint8[:, :, ::1], float32, int32, "
        "float32[:, :, ::1], float32[:, :, ::1])")
def _trajectory_sums(value, weight, flow, near, inv_4nc1, reach, num, den):
    """Unblurred sums along each trajectory of the voxels in ``near`` (0 elsewhere)."""
    i = cuda.grid(1)
    S, H, W = value.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if not near[t, y, x]:
        num[t, y, x] = 0
        den[t, y, x] = 0
        return
    u, v = velocity(flow, t, y, x)
    e = math.exp(-(np.float32(1) + u * u + v * v) * inv_4nc1)
    # The voxel's own reach: the largest d <= reach with e^(d²) >= CUTOFF.
    if e <= CUTOFF:
        r = 0
    elif e >= 1:
        r = reach
    else:
        r = min(reach, int(math.floor(math.sqrt(math.log(CUTOFF) / math.log(float(e))))))
    acc_n = value[t, y, x]
    acc_d = np.float32(weight[t, y, x])
    e = np.float32(e)
    e2 = e * e
    w = np.float32(1)
    step = e
    fx = np.float32(x)
    fy = np.float32(y)
    bx = np.float32(x)
    by = np.float32(y)
    for d in range(1, r + 1):
        w *= step
        step *= e2
        fx += u
        fy += v
        bx -= u
        by -= v
        if t + d < S:
            acc_n += w * bilinear_zero(value, t + d, fy, fx, H, W)
            acc_d += w * bilinear_zero(weight, t + d, fy, fx, H, W)
        if t - d >= 0:
            acc_n += w * bilinear_zero(value, t - d, by, bx, H, W)
            acc_d += w * bilinear_zero(weight, t - d, by, bx, H, W)
    num[t, y, x] = acc_n
    den[t, y, x] = acc_d


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], "
        "uint8, uint8[:, :, ::1], float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, ::1], float32[::1], "
        "float32[::1], float32[::1], float32[::1], uint8, float32[:, :, ::1], float32[:, :, ::1])")
def _finish(num, den, num_w, den_w, g, mixed, gather, value, mask, fallback, own_y, own_x, own_wy, own_wx,
            want_loo, loo, out):
    """At the gathered voxels: the mixture of the two blurs, N / D (the fallback where D is tiny) into ``out``,
    and the leave-one-out of the samples into ``loo`` (F, H, W); elsewhere ``out`` is left as it is, but for the
    samples, which every voxel keeps."""
    i = cuda.grid(1)
    S, H, W = num.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if not gather[t, y, x]:
        if mask[t, y, x]:  # the samples are kept everywhere
            out[t, y, x] = value[t, y, x]
        return
    n = num[t, y, x]
    d = den[t, y, x]
    own = own_y[y] * own_x[x]
    if mixed:
        gg = g[t, y, x]
        n += gg * (num_w[t, y, x] - n)
        d += gg * (den_w[t, y, x] - d)
        own += gg * (own_wy[y] * own_wx[x] - own)
    if mask[t, y, x]:
        out[t, y, x] = value[t, y, x]
        if want_loo:
            K = S // loo.shape[0]
            rest = d - own
            if rest > MIN_WEIGHT:
                loo[t // K, y, x] = (n - own * value[t, y, x]) / rest
            else:
                loo[t // K, y, x] = np.float32(math.nan)
    elif d > MIN_WEIGHT:
        out[t, y, x] = n / d
    else:
        out[t, y, x] = fallback[t, y, x]


def trajectory_gather(ws, sparse, mask, flow, gather, out, fallback, *, time: float, c1: float, c2: float,
                      reach: int, wide=None, wide_sigma: float = 0.0, loo=None) -> None:
    """The gather at the voxels ``gather`` (S, H, W) uint8 into ``out`` (the rest of ``out`` untouched),
    samples kept; ``loo`` (F, H, W) float32: the leave-one-out of each gathered sample written there.

    ``sparse`` (S, H, W) float32 samples (0 elsewhere), ``mask`` uint8, ``flow`` (S, H, W, 2) float32,
    ``fallback`` (S, H, W) float32 (where no sample is in reach), ``wide`` (S, H, W) float32 weights g of the
    wide kernel of σ ``wide_sigma`` (None: none). All device arrays.
    """
    S, H, W = sparse.shape
    n = S * H * W
    sig_space = math.sqrt(2 * time * c2)
    pad = int(math.ceil(max(sig_space, wide_sigma if wide is not None else 0.0) * 4)) + 1
    near = ws.get("gather.near", (S, H, W), np.uint8)
    dilate(ws, gather, near, pad, tag="gather.dilate")
    num = ws.get("gather.num", (S, H, W))
    den = ws.get("gather.den", (S, H, W))
    launch(_trajectory_sums, n, sparse, mask, flow, near, np.float32(1 / (4 * time * c1)), np.int32(reach), num,
           den)
    if wide is not None:
        taps_w = gaussian_taps(wide_sigma)
        num_w = ws.get("gather.num_w", (S, H, W))
        den_w = ws.get("gather.den_w", (S, H, W))
        blur(ws, num, num_w, taps_w, taps_w, tag="gather.blur")
        blur(ws, den, den_w, taps_w, taps_w, tag="gather.blur")
        own_w = [self_weights(taps_w.astype(np.float64), L) for L in (H, W)]
    else:
        num_w, den_w, own_w = num, den, [np.ones(H), np.ones(W)]
    if sig_space > 0.05:
        taps = gaussian_taps(sig_space)
        blur(ws, num, num, taps, taps, tag="gather.blur")
        blur(ws, den, den, taps, taps, tag="gather.blur")
        own = [self_weights(taps.astype(np.float64), L) for L in (H, W)]
    else:
        own = [np.ones(H), np.ones(W)]
    tables = [ws.put(f"gather.own{k}", np.asarray(a, np.float32)) for k, a in enumerate((*own, *own_w))]
    loo_d = loo if loo is not None else ws.get("gather.no_loo", (1, 1, 1))
    launch(_finish, n, num, den, num_w, den_w, wide if wide is not None else num, np.uint8(wide is not None),
           gather, sparse, mask, fallback, *tables, np.uint8(loo is not None), loo_d, out)
