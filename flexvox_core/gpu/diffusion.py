r"""Normalized convolution with a constant tensor on the GPU: :func:`~flexvox_core.reconstruct.diffuse`'s
``nc`` solver (the paper's Eq. 3 in one pass with missing voxels, Knutsson & Westin 1993).

.. math::

    \hat I = \frac{G * (M \cdot I_0)}{G * M}

with G the separable Gaussian of covariance 2·n·diag(cx, cy, ct), cut at 4 σ, reflecting ends (the edge
repeated, as OpenCV's ``BORDER_REFLECT``), applied along time first (each pixel's own samples, with the
weights :func:`~flexvox_core.reconstruct.diffusion.time_weights` computes on the host), then along x and y
(:func:`~flexvox_core.gpu.filters.blur` on the two volumes at once, OpenCV's order). The result is clipped to
the samples' range and keeps the samples. Voxels whose blurred mask is at or below
:data:`~flexvox_core.reconstruct.diffusion.NC_MIN_WEIGHT` of the kernel's peak (no sample in reach: rare, and
only with tiny kernels) are counted; the caller then computes the volume on the CPU, which gives them their
nearest sample.

References
----------
H. Knutsson, C.-F. Westin, "Normalized and differential convolution: methods for interpolation and filtering of
incomplete and uncertain data", CVPR 1993, pp. 515–523.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import kernel, launch
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, _peak, gaussian_kernel, sigmas, time_weights


@kernel("void(float32[:, :, ::1], int32[:, ::1], float32[:, :, ::1], int32[::1], uint8[::1], float32[:, :, ::1], "
        "float32[:, :, ::1])")
def time_pass(frames, order, weight, first, present, num, den):
    """The samples and their mask blurred along time: at voxel (s, y, x), Σ_b w·frames[first[s] + b, y, x] into
    ``num`` and Σ_b w into ``den``, w = ``weight[s, order[y, x], b]`` over the frames that hold samples
    (``present``): each pixel's own samples, weighed by its slot's time weights. Normalized convolution's time
    pass and oriented nc's (the local choice) both launch it."""
    i = cuda.grid(1)
    S, H, W = num.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    k = order[y, x]
    f0 = first[s]
    acc = np.float32(0)
    d = np.float32(0)
    for b in range(weight.shape[2]):
        w = weight[s, k, b]
        if w != 0 and present[f0 + b]:
            acc += w * frames[f0 + b, y, x]
            d += w
    num[s, y, x] = acc
    den[s, y, x] = d


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], int32[:, ::1], uint8[::1], float32, "
        "float32, float32, uint8, float32[:, :, ::1], int32[::1])")
def _finish(num, den, frames, order, present, floor, lo, hi, keep, out, low):
    i = cuda.grid(1)
    S, H, W = num.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    K = S // frames.shape[0]
    f = s // K
    d = den[s, y, x]
    if keep and present[f] and order[y, x] == s - f * K:
        out[s, y, x] = frames[f, y, x]
    elif d <= floor:
        out[s, y, x] = np.float32(math.nan)
        cuda.atomic.add(low, 0, 1)
    else:
        out[s, y, x] = min(max(num[s, y, x] / d, lo), hi)


class NcPlan:
    """The host-side part of one normalized convolution: kernels, time weights and the weight floor."""

    def __init__(self, F: int, K: int, tensor, time: float, present: np.ndarray | None):
        sx, sy, st = sigmas(tensor, time)
        self.gx, self.gy = gaussian_kernel(sx, np.float32), gaussian_kernel(sy, np.float32)
        gt = gaussian_kernel(st, np.float32)
        self.floor = float(NC_MIN_WEIGHT * _peak((self.gx, self.gy, gt)))
        g64 = np.ones(1) if gt is None else gaussian_kernel(st, np.float64)
        weight, first = time_weights(g64, K, F, present)
        self.weight = np.ascontiguousarray(weight, np.float32)
        self.first = np.ascontiguousarray(first, np.int32)


def nc(ws, frames_d, order_d, present_d, plan: NcPlan, lo: float, hi: float, out, *, keep_samples: bool = True,
       tag: str = "nc") -> int:
    """Normalized convolution of the capture ``frames_d`` (F, H, W) into ``out`` (S, H, W) float32 (device
    arrays). ``order_d`` (H, W) int32: each pixel's slot; ``present_d`` (F,) uint8: frames holding samples.
    Returns the count of voxels without a sample in reach (NaN in ``out``; 0 almost always)."""
    S, H, W = out.shape
    n = S * H * W
    num = ws.get(f"{tag}.num", (S, H, W))
    den = ws.get(f"{tag}.den", (S, H, W))
    weight = ws.put(f"{tag}.weight", plan.weight)
    first = ws.put(f"{tag}.first", plan.first)
    launch(time_pass, n, frames_d, order_d, weight, first, present_d, num, den)
    if plan.gx is not None or plan.gy is not None:
        scratch = (ws.get(f"{tag}.num2", (S, H, W)), ws.get(f"{tag}.den2", (S, H, W)))
        blur(ws, (num, den), (num, den), plan.gy, plan.gx, tag=tag, scratch=scratch)
    low = ws.put(f"{tag}.low", np.zeros(1, np.int32))
    launch(_finish, n, num, den, frames_d, order_d, present_d, np.float32(plan.floor), np.float32(lo),
           np.float32(hi), np.uint8(keep_samples), out, low)
    return int(low.copy_to_host()[0])


def diffuse_on_gpu(frames, code, *, tensor, time: float, missing=None) -> np.ndarray:
    """:func:`~flexvox_core.reconstruct.diffuse` (``nc`` solver, samples kept) on the GPU: the frames go up, the
    video comes down. Returns (F·K, H, W) float32, equal to the CPU's within float rounding."""
    from flexvox_core.forward import tiled_order
    from flexvox_core.gaps import as_missing, captured
    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.reconstruct._common import check_frames, check_identity_code
    from flexvox_core.reconstruct.diffusion import check_tensor, diffuse

    f = np.ascontiguousarray(check_frames(frames), np.float32)
    c = check_identity_code(code)
    check_tensor(tensor)
    F, H, W = f.shape
    K = c.shape[2]
    missing = as_missing(missing, F)
    present = np.ones(F, bool) if missing is None else ~missing
    kept = captured(f, missing)
    plan = NcPlan(F, K, tensor, time, None if missing is None else present)
    ws = Workspace()
    out = cuda.device_array((F * K, H, W), np.float32)
    low = nc(ws, cuda.to_device(f), cuda.to_device(np.ascontiguousarray(tiled_order(c, H, W), np.int32)),
             cuda.to_device(present.astype(np.uint8)), plan, float(kept.min()), float(kept.max()), out)
    if low:  # voxels with no sample in reach take their nearest sample: the CPU's path
        return diffuse(f, c, tensor=tensor, time=time, missing=missing)
    return out.copy_to_host()
