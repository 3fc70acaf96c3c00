r"""Oriented normalized convolution: isotropic ``nc`` whose spatial kernel follows the picture's edges.

Structure-adaptive normalized convolution (Pham, van Vliet & Schutte, "Robust fusion of irregularly
sampled data using adaptive normalized convolution", 2006). Isotropic normalized convolution with a
Gaussian of σ = 0.71 px and sub-frames (tensor (1, 1, 1), n = 0.25) fills a voxel from the samples
around it in every direction, across an edge as readily as along it. Here the spatial Gaussian at each
voxel is stretched along the local edge and squeezed across it:

.. math::

    \sigma_u = \sigma\,\frac{\alpha}{\alpha + A}, \qquad \sigma_v = \sigma\,\frac{\alpha + A}{\alpha},

u the direction of the gradient, v along the edge, A = (λ₁ − λ₂)/(λ₁ + λ₂) ∈ [0, 1] the anisotropy of the
structure tensor J = G_ρ * (∇(G_σp * I) ∇(G_σp * I)ᵀ) of a **guide** picture I (motion-aware passes its
high-TR reconstruction: a first estimate, sharp in time), α = 2. Where the guide has no dominant
direction (A ≈ 0) this is isotropic ``nc`` exactly. The time Gaussian is nc's, with reflecting ends.

The kernels come from a bank: A is rounded to 0, ½ or 1 and the direction to one of 8 (22.5° apart),
17 kernels cut at 4 σ. Measured as motion-aware's local-choice candidate in place of isotropic ``nc``
(docs/reconstruction.md, "The local choice"): Drop 37.13 → 37.99 dB, Runner 33.05 → 33.22, the built-in
scenes +0.01 at K = 8 and K = 16, no capture worse by more than 0.05 dB. The guide sets the direction
only; it is not averaged in: the estimate is a normalized convolution of the samples, within their range,
and keeps them.

The sums run in a compiled kernel (:mod:`~flexvox_core.reconstruct.oriented_nc_kernel`), one sub-frame
per call, at the voxels asked for; :func:`oriented_nc_reference` is the plain numpy form the tests
compare it against.
"""

from __future__ import annotations

import math
import threading

import cv2
import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.gaps import as_missing
from flexvox_core.reconstruct._common import check_frames, check_identity_code
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, TRUNCATE, _kernel, _time_weights
from flexvox_core.threads import for_each

SIGMA = math.sqrt(0.5)
"""Spatial and temporal standard deviation of the isotropic kernel (px, sub-frames): nc's at n = 0.25."""
ALPHA = 2.0
"""How far the kernel stretches: at A = 1 it is 1.5 σ along the edge and σ/1.5 across it. Measured
(prototype, the same captures as the figures above): α = 1 gained 0.06 dB more on Drop but lost 0.10 dB
on the still scene at K = 8; α = 3 gained less everywhere (Drop +0.68)."""
LEVELS = (0.0, 0.5, 1.0)
"""Anisotropy levels of the kernel bank (A is rounded to the nearest)."""
ANGLES = 8
"""Directions of the kernel bank, over 180°."""
PRE_SIGMA = 0.7
"""The guide is blurred by this (px) before its gradient is taken."""
RHO = 1.0
"""The gradient products are averaged over this (px): the structure tensor's scale."""
_PAD = 10
"""Rows of guide around the wanted ones that the structure tensor reads (3 + 1 + 4 px, rounded up)."""


def kernel_bank(sigma: float = SIGMA, alpha: float = ALPHA) -> np.ndarray:
    """The spatial kernels (1 + 8·2, 2h + 1, 2h + 1) float32: index 0 isotropic, then for each anisotropy level
    above 0 the 8 directions of the gradient (0°, 22.5°, … from the x axis). Each is 1 in its centre and cut,
    as nc cuts its Gaussians, at ``TRUNCATE`` standard deviations along its own axes (rounded as nc's
    radius): the isotropic one is nc's spatial kernel up to a constant factor."""
    big = int(math.ceil(TRUNCATE * sigma * (alpha + LEVELS[-1]) / alpha)) + 2
    y, x = np.mgrid[-big:big + 1, -big:big + 1].astype(np.float64)
    out = []
    for level in LEVELS:
        su, sv = sigma * alpha / (alpha + level), sigma * (alpha + level) / alpha
        for k in range(ANGLES if level > 0 else 1):
            theta = k * math.pi / ANGLES
            u = x * math.cos(theta) + y * math.sin(theta)
            v = -x * math.sin(theta) + y * math.cos(theta)
            g = np.exp(-0.5 * ((u / su) ** 2 + (v / sv) ** 2))
            eps = 1e-9  # a tap on the box's edge stays in, whatever the rounding of the rotation
            g[(np.abs(u) > int(TRUNCATE * su + 0.5) + eps) | (np.abs(v) > int(TRUNCATE * sv + 0.5) + eps)] = 0
            out.append(g)
    bank = np.asarray(out)
    used = np.flatnonzero(bank.any(axis=(0, 1)))
    half = int(max(abs(used[0] - big), abs(used[-1] - big)))
    return np.ascontiguousarray(bank[:, big - half:big + half + 1, big - half:big + half + 1], np.float32)


def structure(guide: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The structure tensor's entries (3, H, W) float32 — J_xx, J_xy, J_yy — of one guide picture (H, W),
    into ``out`` if given."""
    p = cv2.GaussianBlur(np.asarray(guide, np.float32), (0, 0), PRE_SIGMA, borderType=cv2.BORDER_REFLECT)
    gx = cv2.Sobel(p, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(p, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    if out is None:
        out = np.empty((3, *p.shape), np.float32)
    for i, (a, b) in enumerate(((gx, gx), (gx, gy), (gy, gy))):
        cv2.multiply(a, b, dst=p)
        cv2.GaussianBlur(p, (0, 0), RHO, dst=out[i], borderType=cv2.BORDER_REFLECT)
    return out


def bank_index(jxx, jxy, jyy) -> np.ndarray:
    """The kernel (index into :func:`kernel_bank`) for structure-tensor entries (arrays of one shape).

    The anisotropy A = √((J_xx − J_yy)² + 4 J_xy²) / (J_xx + J_yy) rounds to the nearest of :data:`LEVELS`
    (0 at no gradient); the gradient's direction θ = ½ atan2(2 J_xy, J_xx − J_yy) to the nearest multiple of
    22.5°, found by comparing the doubled angle with the sectors' edges (no arctangent: the compiled kernel
    makes the same comparisons)."""
    jxx, jxy, jyy = (np.asarray(v, np.float64) for v in (jxx, jxy, jyy))
    a, b, trace = jxx - jyy, 2 * jxy, jxx + jyy
    spread2 = a * a + b * b
    low, high = (LEVELS[0] + LEVELS[1]) / 2, (LEVELS[1] + LEVELS[2]) / 2
    level = np.where(spread2 <= (high * trace) ** 2, 1, 2)
    level = np.where(~(trace > 0) | (spread2 <= (low * trace) ** 2), 0, level)
    tan1 = math.tan(math.pi / 8)
    ax, by = np.abs(a), np.abs(b)
    angle = np.select([by <= tan1 * ax, ax <= tan1 * by, a > 0],
                      [np.where(a >= 0, 0, 4), np.where(b > 0, 2, 6), np.where(b > 0, 1, 7)],
                      np.where(b > 0, 3, 5))
    return np.where(level == 0, 0, 1 + (level - 1) * ANGLES + angle)


def _checked(frames, code, guide, where, fallback, missing):
    f = check_frames(frames)
    c = check_identity_code(code)
    F, H, W = f.shape
    S = F * c.shape[2]
    g = np.asarray(guide, np.float32)
    if g.shape != (S, H, W):
        raise ValueError(f"`guide` must be the (S, H, W) = {(S, H, W)} video whose edges orient the kernel; "
                         f"got {g.shape}")
    if where is not None:
        where = np.asarray(where, bool)
        if where.shape != (S, H, W):
            raise ValueError(f"`where` must be a bool (S, H, W) = {(S, H, W)} array; got {where.shape}")
    if fallback is not None and np.shape(fallback) != (S, H, W):
        raise ValueError(f"`fallback` must be an (S, H, W) = {(S, H, W)} array; got {np.shape(fallback)}")
    return f, c, g, where, as_missing(missing, F)


def oriented_nc(frames, code, guide, *, where=None, fallback=None, missing=None) -> tuple[np.ndarray, np.ndarray]:
    """The oriented normalized convolution of an identity-code capture, and each sample's leave-one-out estimate.

    Parameters
    ----------
    frames : ndarray (F, H, W)
    code : ndarray (m, n, K), identity code
    guide : ndarray (F·K, H, W)
        The picture whose structure orients the kernel at each voxel.
    where : ndarray (F·K, H, W) bool, optional
        The voxels to estimate (default: all); elsewhere the result is ``fallback``.
    fallback : ndarray (F·K, H, W), optional
        The values outside ``where`` and where no sample is in reach (default: NaN).
    missing : ndarray (F,) bool, optional
        Dropped frames: they hold no samples.

    Returns
    -------
    video : ndarray (F·K, H, W) float32
        Samples kept exactly; each estimate is a weighted mean of samples, so within their range.
    loo : ndarray (F, H, W) float32
        At each sample whose voxel is in ``where``, its leave-one-out estimate (N − c·y)/(D − c), c the weight
        it gives itself (as :func:`~flexvox_core.reconstruct.diffusion.nc_leave_one_out`); NaN elsewhere,
        where no other sample is in reach, and in missing frames.
    """
    from flexvox_core.reconstruct.oriented_nc_kernel import oriented_plane, tap_lists

    f, c, g, where, missing = _checked(frames, code, guide, where, fallback, missing)
    F, H, W = f.shape
    K = c.shape[2]
    S = F * K
    present = None if missing is None else ~missing
    gt = _kernel(SIGMA, np.float64)
    weight, first = _time_weights(gt, K, F, present)
    floor = NC_MIN_WEIGHT * float(gt.max())
    bank = kernel_bank()
    offsets, weights, counts = tap_lists(bank)
    m = c.shape[0]
    order = tiled_order(c, min(H, m), W).astype(np.int64)  # repeats every m rows
    samples = np.ascontiguousarray(f, dtype=np.float32)
    video = np.full((S, H, W), np.nan, np.float32) if fallback is None else np.array(fallback, np.float32)
    loo = np.full((F, H, W), np.nan, np.float32)
    present_f = np.ones(F, bool) if present is None else present
    everywhere = np.ones((H, W), bool)
    scratch = threading.local()  # planes each thread reuses: fresh memory costs page faults every time

    def one(s):
        wanted = everywhere if where is None else where[s]
        rows = np.flatnonzero(wanted.any(axis=1))
        if not len(rows):
            return
        y0, y1 = int(rows[0]), int(rows[-1]) + 1
        if not hasattr(scratch, "j"):
            scratch.j = np.zeros((3, H, W), np.float32)
            scratch.vt = np.empty((H, W))
            scratch.mt = np.empty((H, W))
        b0, b1 = max(0, y0 - _PAD), min(H, y1 + _PAD)
        structure(g[s, b0:b1], out=scratch.j[:, b0:b1])
        oriented_plane(samples, order, weight[s], int(first[s]), s % K, s // K, bool(present_f[s // K]),
                       scratch.j, wanted, offsets, weights, counts, bank.shape[1] // 2, floor, y0, y1,
                       scratch.vt, scratch.mt, video[s], loo)

    for_each(one, S)
    return video, loo


def oriented_nc_reference(frames, code, guide, *, where=None, fallback=None, missing=None
                          ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`oriented_nc` in plain numpy, float64, a voxel at a time (small inputs: the tests' reference)."""
    f, c, g, where, missing = _checked(frames, code, guide, where, fallback, missing)
    F, H, W = f.shape
    K = c.shape[2]
    S = F * K
    order = tiled_order(c, H, W)
    present = np.ones(F, bool) if missing is None else ~missing
    # The sparse volume and its mask, blurred along time with reflecting ends (scipy's "reflect").
    vals = np.zeros((S, H, W))
    mask = np.zeros((S, H, W))
    for fr in range(F):
        if present[fr]:
            for k in range(K):
                sel = order == k
                vals[fr * K + k][sel] = f[fr][sel]
                mask[fr * K + k][sel] = 1.0
    gt = _kernel(SIGMA, np.float64)
    r = gt.size // 2
    vt = np.zeros_like(vals)
    mt = np.zeros_like(mask)
    for s in range(S):
        for d in range(-r, r + 1):
            t = s + d
            t = -t - 1 if t < 0 else (2 * S - t - 1 if t >= S else t)
            vt[s] += gt[d + r] * vals[t]
            mt[s] += gt[d + r] * mask[t]
    bank = kernel_bank().astype(np.float64)
    h = bank.shape[1] // 2
    floor = NC_MIN_WEIGHT * float(gt.max())
    video = np.full((S, H, W), np.nan) if fallback is None else np.array(fallback, np.float64)
    loo = np.full((F, H, W), np.nan)
    ys = np.arange(-h, h + 1)

    def reflect(i, n):
        i = np.where(i < 0, -i - 1, i)
        return np.where(i >= n, 2 * n - i - 1, i)

    for s in range(S):
        jxx, jxy, jyy = structure(g[s])
        idx = bank_index(jxx, jxy, jyy)
        fr = s // K
        for y in range(H):
            for x in range(W):
                if where is not None and not where[s, y, x]:
                    continue
                ker = bank[idx[y, x]]
                rows, cols = reflect(y + ys, H), reflect(x + ys, W)
                num = float((ker * vt[s][np.ix_(rows, cols)]).sum())
                den = float((ker * mt[s][np.ix_(rows, cols)]).sum())
                if order[y, x] == s % K and present[fr]:  # a sample: kept, and estimated from the others
                    video[s, y, x] = f[fr, y, x]
                    # The weight it gives itself: every tap that lands on it (more than the centre at a border).
                    own_space = float((ker * np.logical_and.outer(rows == y, cols == x)).sum())
                    c_own = own_space * _own_time_weight(gt, s, S)
                    rest = den - c_own
                    if rest > floor:
                        loo[fr, y, x] = (num - c_own * f[fr, y, x]) / rest
                elif den > floor:
                    video[s, y, x] = num / den
    return video.astype(np.float32), loo.astype(np.float32)


def _own_time_weight(gt: np.ndarray, s: int, S: int) -> float:
    """Weight sub-frame s gives itself in the reflecting time blur ``gt`` (more near an end)."""
    r = gt.size // 2
    total = 0.0
    for d in range(-r, r + 1):
        t = s + d
        t = -t - 1 if t < 0 else (2 * S - t - 1 if t >= S else t)
        if t == s:
            total += gt[d + r]
    return total
