r"""Motion-aware's local choice on the GPU: :meth:`flexvox_core.motion.stages.CpuStages.local_choice`.

Where the trajectory gather predicts the samples worse than oriented ``nc``
(:mod:`~flexvox_core.reconstruct.oriented_nc`), blend oriented nc in (:mod:`~flexvox_core.motion.local_choice`):

1. the still-voxel correction of the gather's leave-one-out ℓ (per frame f and pixel, over its gathered voxels
   without a sample: n of them, n_s slower than the speed limit, E their summed (v − y)²):
   :math:`\ell \leftarrow y + \sqrt{(E + (n - n_s)(\ell - y)^2) / \max(n, 1)}` where n_s > 0;
2. oriented nc of the samples at the gathered voxels, its kernel from the bank of 17 chosen per voxel from the
   structure tensor of the high-TR video, and each sample's leave-one-out estimate;
3. method a's (the gather's) weight per frame and pixel from the pooled leave-one-out errors
   (:mod:`~flexvox_core.motion.gpu.local_choice_weights`);
4. the blend :math:`v \leftarrow v + (1 - w_f)(o - v)` at the gathered voxels, o oriented nc's value there.

Oriented nc is a normalized convolution whose spatial kernel g follows the guide's edges:

.. math::

    o = \frac{\sum_q g_q\, \tilde v_q}{\sum_q g_q\, \tilde m_q}, \qquad
    \ell^{o} = \frac{\sum_{q \ne p} g_q \tilde v_q + g_p (\tilde v_p - c\,y)}
                    {\sum_{q \ne p} g_q \tilde m_q + g_p (\tilde m_p - c)},

with :math:`\tilde v, \tilde m` the samples and the sample mask blurred in time (each pixel's own samples
weighed by :func:`~flexvox_core.reconstruct.diffusion.time_weights`), g_p the weight of the taps that fold
onto the voxel itself and c the weight its own sample gives it in time. The leave-one-out sums leave the
sample's term out instead of subtracting it, so float32 sums keep their relative precision where the sample
outweighs the others. The kernel of each voxel comes from the structure tensor of its high-TR sub-frame
(:mod:`~flexvox_core.motion.gpu.oriented_nc`).

Every kernel runs over whole volumes (one thread per voxel, or per pixel of every frame). Reference: Pham,
van Vliet & Schutte, "Robust fusion of irregularly sampled data using adaptive normalized convolution", 2006.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import cuda

from flexvox_core.gpu.diffusion import time_pass
from flexvox_core.gpu.index import reflect, voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.motion.gpu.local_choice_weights import local_weights
from flexvox_core.motion.gpu.oriented_nc import structure_bank
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, gaussian_kernel, time_weights
from flexvox_core.reconstruct.oriented_nc import SIGMA, kernel_bank
from flexvox_core.reconstruct.oriented_nc_kernel import tap_lists

_REACH = kernel_bank().shape[1] // 2
"""How far (px) the bank's kernels reach."""
F3 = "float32[:, :, ::1]"
U3 = "uint8[:, :, ::1]"


@lru_cache(maxsize=1)
def bank_taps() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel bank as tap lists: offsets (B, T, 2) int32 (dy, dx), weights (B, T) float32, counts (B,)
    int32 (:func:`~flexvox_core.reconstruct.oriented_nc_kernel.tap_lists`)."""
    offsets, weights, counts = tap_lists(kernel_bank())
    return (np.ascontiguousarray(offsets, np.int32), np.ascontiguousarray(weights, np.float32),
            np.ascontiguousarray(counts, np.int32))


@lru_cache(maxsize=16)
def time_table(F: int, K: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Oriented nc's time weights (S, K, span) float32 for every frame present (the kernels multiply by
    ``present``), each sub-frame's first frame (S,) int32, and the weight floor."""
    gt = gaussian_kernel(SIGMA, np.float64)
    weight, first = time_weights(gt, K, F, None)
    return (np.ascontiguousarray(weight, np.float32), np.ascontiguousarray(first, np.int32),
            NC_MIN_WEIGHT * float(gt.max()))


# ------------------------------------------------------------------------------------------- leave-one-out


@kernel("void(float32[::1], int32[::1])")
def _any_finite(a, flag):
    """flag[0] = 1 if any element is finite (every writer writes the same 1: no atomic needed)."""
    i = cuda.grid(1)
    if i < a.shape[0] and math.isfinite(a[i]) and flag[0] == 0:
        flag[0] = 1


def any_finite(ws, a) -> bool:
    """Whether the float32 device array ``a`` holds a finite value (one int copied back)."""
    flag = ws.put("choice.flag", np.zeros(1, np.int32))
    v = a.reshape(a.size)
    launch(_any_finite, v.shape[0], v, flag)
    return bool(flag.copy_to_host()[0])


@kernel(f"void({F3}, {F3}, {F3}, {U3}, {U3}, float32[:, :, :, ::1], float32)")
def _still_voxel_loo(loo, video, frames, gathered, mask, flow, limit):
    i = cuda.grid(1)
    F, H, W = loo.shape
    if i >= F * H * W:
        return
    f, y, x = voxel(i, H, W)
    K = video.shape[0] // F
    s = frames[f, y, x]
    count = np.float32(0)
    slow = np.float32(0)
    seen = np.float32(0)
    for t in range(f * K, (f + 1) * K):
        if gathered[t, y, x] and not mask[t, y, x]:
            count += np.float32(1)
            u = flow[t, y, x, 0]
            v = flow[t, y, x, 1]
            if u * u + v * v < limit:
                slow += np.float32(1)
                d = video[t, y, x] - s
                seen += d * d
    old = loo[f, y, x]
    if slow > 0 and math.isfinite(old):
        d = old - s
        err = (seen + (count - slow) * (d * d)) / max(count, np.float32(1))
        loo[f, y, x] = s + math.sqrt(err)


def still_voxel_loo(loo, video, frames, gathered, mask, flow, *, speed: float) -> None:
    """The gather's leave-one-out ``loo`` (F, H, W) corrected in place where the flow calls gathered voxels
    still (slower than ``speed`` px per sub-frame), as :func:`flexvox_core.motion.local_choice.still_voxel_loo`
    (device arrays: ``video`` (S, H, W) float32, ``gathered`` and ``mask`` (S, H, W) uint8, ``flow``
    (S, H, W, 2) float32)."""
    launch(_still_voxel_loo, loo.size, loo, video, frames, gathered, mask, flow,
           np.float32(np.float32(speed) ** 2))


# ------------------------------------------------------------------------------------------- oriented nc


@device
def _spatial(vt, mt, s, y, x, kb, offsets, taps, counts, own):
    """(num, den, self) of the bank's kernel ``kb`` at voxel (s, y, x) over the time-blurred planes; with
    ``own`` the taps that fold onto the voxel itself are left out of num and den and summed into self."""
    H, W = vt.shape[1], vt.shape[2]
    num = np.float32(0)
    den = np.float32(0)
    me = np.float32(0)
    n = counts[kb]
    if y >= _REACH and y + _REACH < H and x >= _REACH and x + _REACH < W:  # no tap folds
        for t in range(n):
            dy = offsets[kb, t, 0]
            dx = offsets[kb, t, 1]
            g = taps[kb, t]
            if own and dy == 0 and dx == 0:
                me += g
            else:
                num += g * vt[s, y + dy, x + dx]
                den += g * mt[s, y + dy, x + dx]
    else:
        for t in range(n):
            yy = reflect(y + offsets[kb, t, 0], H)
            xx = reflect(x + offsets[kb, t, 1], W)
            g = taps[kb, t]
            if own and yy == y and xx == x:
                me += g
            else:
                num += g * vt[s, yy, xx]
                den += g * mt[s, yy, xx]
    return num, den, me


@kernel(f"void({F3}, {F3}, {F3}, int32[:, ::1], uint8[::1], {U3}, {U3}, {F3}, int32[::1], int32[:, :, ::1], "
        f"float32[:, ::1], int32[::1], float32, {F3})")
def _oriented_loo(vt, mt, frames, order, present, gathered, bank, weight, first, offsets, taps, counts, floor,
                  loo):
    """Oriented nc's leave-one-out estimate of every sample whose voxel is gathered (NaN elsewhere)."""
    i = cuda.grid(1)
    F, H, W = loo.shape
    if i >= F * H * W:
        return
    f, y, x = voxel(i, H, W)
    K = vt.shape[0] // F
    k = order[y, x]
    s = f * K + k
    out = np.float32(math.nan)
    if present[f] and gathered[s, y, x]:
        num, den, me = _spatial(vt, mt, s, y, x, bank[s, y, x], offsets, taps, counts, True)
        # The voxel's own time-blurred sums without its sample: its pixel's samples in the other frames.
        f0 = first[s]
        rest_v = np.float32(0)
        rest_m = np.float32(0)
        for b in range(weight.shape[2]):
            w = weight[s, k, b]
            if w != 0 and f0 + b != f and present[f0 + b]:
                rest_v += w * frames[f0 + b, y, x]
                rest_m += w
        num += me * rest_v
        den += me * rest_m
        if den > floor:
            out = num / den
    loo[f, y, x] = out


@kernel(f"void({F3}, {F3}, {F3}, {F3}, int32[:, ::1], uint8[::1], {U3}, {U3}, int32[:, :, ::1], float32[:, ::1], "
        f"int32[::1], float32, {F3})")
def _oriented_blend(video, vt, mt, frames, order, present, gathered, bank, offsets, taps, counts, floor, weights):
    """video ← video + (1 − w)·(oriented nc − video) at the gathered voxels (the sample at a sample's voxel;
    unchanged where no sample is in reach)."""
    i = cuda.grid(1)
    S, H, W = video.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    if not gathered[s, y, x]:
        return
    F = frames.shape[0]
    K = S // F
    f = s // K
    if present[f] and order[y, x] == s - f * K:
        other = frames[f, y, x]
    else:
        num, den, _ = _spatial(vt, mt, s, y, x, bank[s, y, x], offsets, taps, counts, False)
        if not den > floor:
            return
        other = num / den
    v = video[s, y, x]
    video[s, y, x] = v + (np.float32(1) - weights[f, y, x]) * (other - v)


class OrientedPlan:
    """Oriented nc's tables on the device for a clip of F frames of K sub-frames (``choice.*`` buffers)."""

    def __init__(self, ws, F: int, K: int):
        weight, first, floor = time_table(F, K)
        offsets, taps, counts = bank_taps()
        self.weight = ws.put("choice.time.weight", weight)
        self.first = ws.put("choice.time.first", first)
        self.floor = np.float32(floor)
        self.offsets = ws.put("choice.bank.offsets", offsets)
        self.taps = ws.put("choice.bank.taps", taps)
        self.counts = ws.put("choice.bank.counts", counts)


def time_blur(ws, frames, order, present, plan: OrientedPlan, S: int):
    """(ṽ, m̃): the samples and their mask blurred in time, (S, H, W) float32 (``choice.vol1``, ``choice.vol0``)."""
    _, H, W = frames.shape
    vt = ws.get("choice.vol1", (S, H, W))
    mt = ws.get("choice.vol0", (S, H, W))
    launch(time_pass, S * H * W, frames, order, plan.weight, plan.first, present, vt, mt)
    return vt, mt


def oriented_loo(vt, mt, frames, order, present, gathered, bank, plan: OrientedPlan, out) -> None:
    """Oriented nc's leave-one-out estimate (F, H, W) float32 into ``out`` of each sample whose voxel is
    gathered; NaN elsewhere, where no other sample is in reach, and in dropped frames."""
    launch(_oriented_loo, out.size, vt, mt, frames, order, present, gathered, bank, plan.weight, plan.first,
           plan.offsets, plan.taps, plan.counts, plan.floor, out)


def oriented_blend(video, vt, mt, frames, order, present, gathered, bank, plan: OrientedPlan, weights) -> None:
    """``video`` ← w·video + (1 − w)·(oriented nc) at the gathered voxels, w = ``weights`` (F, H, W) of the
    voxel's frame (:func:`flexvox_core.motion.local_choice.blend`)."""
    launch(_oriented_blend, video.size, video, vt, mt, frames, order, present, gathered, bank, plan.offsets,
           plan.taps, plan.counts, plan.floor, weights)


# ------------------------------------------------------------------------------------------- the stage


def _check(video, loo, gathered, mask, flow, frames, order, present, high_tr, K: int) -> None:
    F, H, W = loo.shape
    S = F * K
    want = {"video": ((S, H, W), np.float32), "loo": ((F, H, W), np.float32), "gathered": ((S, H, W), np.uint8),
            "mask": ((S, H, W), np.uint8), "flow": ((S, H, W, 2), np.float32), "frames": ((F, H, W), np.float32),
            "order": ((H, W), np.int32), "present": ((F,), np.uint8), "high_tr": ((S, H, W), np.float32)}
    got = {"video": video, "loo": loo, "gathered": gathered, "mask": mask, "flow": flow, "frames": frames,
           "order": order, "present": present, "high_tr": high_tr}
    for name, (shape, dtype) in want.items():
        a = got[name]
        if tuple(a.shape) != shape or np.dtype(a.dtype) != dtype:
            raise ValueError(f"`{name}` must be {np.dtype(dtype).name} {shape} (F = {F} frames, K = {K}); got "
                             f"{np.dtype(a.dtype).name} {tuple(a.shape)}")


def local_choice(ws, video, loo, gathered, mask, flow, frames, order, present, high_tr, K: int, *,
                 score_still_voxels: bool, still_speed: float, sigma: float) -> bool:
    """Motion-aware's local choice, in place on ``video`` (device arrays throughout).

    Parameters
    ----------
    ws : Workspace
        Device buffers (``choice.*``), reused across calls.
    video : device array (S, H, W) float32
        The gather's result after the refinement (samples kept); blended in place.
    loo : device array (F, H, W) float32
        The gather's leave-one-out estimate of each sample (NaN: none); corrected in place when
        ``score_still_voxels``.
    gathered, mask : device array (S, H, W) uint8
        The voxels the trajectory gather estimated, and the sample voxels (none in a dropped frame).
    flow : device array (S, H, W, 2) float32
    frames : device array (F, H, W) float32
    order : device array (H, W) int32
        Each pixel's slot.
    present : device array (F,) uint8
        0 for a dropped frame.
    high_tr : device array (S, H, W) float32
        The high-TR video: its edges orient oriented nc's kernels (finite values).
    K : int
        Sub-frames per frame.
    score_still_voxels : bool
        Correct the gather's leave-one-out at voxels slower than ``still_speed`` (the CPU does unless the slow
        class holds every gathered voxel above that speed).
    still_speed : float
        Below this flow speed (px per sub-frame) a gathered voxel counts as still: the CPU's
        :data:`~flexvox_core.motion.local_choice.STILL_VOXEL_SPEED`.
    sigma : float
        The pooling's standard deviation (px): the CPU's :func:`~flexvox_core.motion.local_choice.pooling_sigma`
        (H, W).

    Returns
    -------
    bool
        False when ``loo`` has no finite value (nothing done), as the CPU returns at once.
    """
    _check(video, loo, gathered, mask, flow, frames, order, present, high_tr, K)
    if not any_finite(ws, loo):
        return False
    F, H, W = loo.shape
    S = F * K
    if score_still_voxels:
        still_voxel_loo(loo, video, frames, gathered, mask, flow, speed=still_speed)
    bank = ws.get("choice.bank", (S, H, W), np.uint8)
    structure_bank(ws, high_tr, bank)
    plan = OrientedPlan(ws, F, K)
    vt, mt = time_blur(ws, frames, order, present, plan, S)
    other_loo = ws.get("choice.other_loo", (F, H, W))
    oriented_loo(vt, mt, frames, order, present, gathered, bank, plan, other_loo)
    weights = ws.get("choice.weights", (F, H, W))
    local_weights(ws, loo, other_loo, frames, weights, sigma=sigma)
    oriented_blend(video, vt, mt, frames, order, present, gathered, bank, plan, weights)
    return True
