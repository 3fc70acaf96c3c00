"""Oriented nc in plain numpy, float64, a voxel at a time: the reference the compiled kernel is tested against.

Independent of the compiled path where it can be: each tap's weight comes from the kernel's formula
(``kernel_weights``), the direction from the arctangent and the anisotropy from the nearest level (the
compiled kernel compares with sector edges and thresholds), the borders fold with modulo arithmetic, and the
sample's own weight in time is nc's ``self_weights``. Shared: the structure tensor (compiled; :func:`structure_opencv`
is its reference).
"""

import math

import cv2
import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, gaussian_kernel, self_weights
from flexvox_core.reconstruct.oriented_nc import (
    ALPHA,
    ANGLES,
    LEVELS,
    SIGMA,
    check_inputs,
    kernel_bank,
    kernel_weights,
    structure,
)
from flexvox_core.slopes import slopes


def structure_opencv(guide: np.ndarray) -> np.ndarray:
    """:func:`~flexvox_core.reconstruct.oriented_nc.structure` by OpenCV's filters, a pass each (the compiled
    tensor's reference): the guide blurred and Sobel's derivatives (``slopes``), their products blurred by ρ."""
    from flexvox_core.reconstruct.oriented_nc import PRE_SIGMA, RHO

    gx, gy = slopes(guide, PRE_SIGMA)
    return np.stack([cv2.GaussianBlur(a * b, (0, 0), RHO, borderType=cv2.BORDER_REFLECT)
                     for a, b in ((gx, gx), (gx, gy), (gy, gy))])


def _fold(i: np.ndarray, n: int) -> np.ndarray:
    i = np.mod(i, 2 * n)
    return np.where(i >= n, 2 * n - 1 - i, i)


def _level_and_theta(jxx: float, jxy: float, jyy: float) -> tuple[float, float]:
    trace = jxx + jyy
    aniso = math.hypot(jxx - jyy, 2 * jxy) / trace if trace > 0 else 0.0
    level = LEVELS[int(np.argmin([abs(aniso - v) for v in LEVELS]))]
    if level == 0:  # the isotropic kernel, cut as nc's: a box along x and y
        return level, 0.0
    step = math.pi / ANGLES
    theta = (round(0.5 * math.atan2(2 * jxy, jxx - jyy) / step) % ANGLES) * step
    return level, theta


def oriented_nc_reference(frames, code, guide, *, where=None, fallback=None, missing=None):
    """:func:`flexvox_core.reconstruct.oriented_nc.oriented_nc`, the slow way (small inputs)."""
    f, c, g, where, missing = check_inputs(frames, code, guide, where, fallback, missing)
    F, H, W = f.shape
    K = c.shape[2]
    S = F * K
    order = tiled_order(c, H, W)
    present = np.ones(F, bool) if missing is None else ~missing
    vals = np.zeros((S, H, W))
    mask = np.zeros((S, H, W))
    for fr in np.flatnonzero(present):
        for k in range(K):
            sel = order == k
            vals[fr * K + k][sel] = f[fr][sel]
            mask[fr * K + k][sel] = 1.0
    gt = gaussian_kernel(SIGMA, np.float64)
    r = gt.size // 2
    vt = np.zeros_like(vals)
    mt = np.zeros_like(mask)
    for s in range(S):
        for d in range(-r, r + 1):
            t = int(_fold(np.array(s + d), S))
            vt[s] += gt[d + r] * vals[t]
            mt[s] += gt[d + r] * mask[t]
    own_t = self_weights(gt, S)
    h = kernel_bank().shape[1] // 2
    dy, dx = np.mgrid[-h:h + 1, -h:h + 1]
    floor = NC_MIN_WEIGHT * float(gt.max())
    video = np.full((S, H, W), np.nan) if fallback is None else np.array(fallback, np.float64)
    loo = np.full((F, H, W), np.nan)
    for s in range(S):
        jxx, jxy, jyy = structure(g[s]).astype(np.float64)
        fr = s // K
        for y in range(H):
            for x in range(W):
                if where is not None and not where[s, y, x]:
                    continue
                level, theta = _level_and_theta(jxx[y, x], jxy[y, x], jyy[y, x])
                ker = kernel_weights(dx, dy, SIGMA, ALPHA, level, theta)
                rows, cols = _fold(y + dy, H), _fold(x + dx, W)
                num = float((ker * vt[s][rows, cols]).sum())
                den = float((ker * mt[s][rows, cols]).sum())
                if order[y, x] == s % K and present[fr]:  # a sample: kept, and estimated from the others
                    video[s, y, x] = f[fr, y, x]
                    c_own = float(ker[(rows == y) & (cols == x)].sum()) * own_t[s]
                    if den - c_own > floor:
                        loo[fr, y, x] = (num - c_own * f[fr, y, x]) / (den - c_own)
                elif den > floor:
                    video[s, y, x] = num / den
    return video.astype(np.float32), loo.astype(np.float32)
