"""The long-reach gather in plain numpy, float64: the reference the tests compare
:func:`flexvox_core.motion.longreach.long_reach` (compiled, reading one pixel per read) with.

Every read is a full bilinear read (four pixels, 0 outside the picture) of the sample plane and of its 0/1 mask,
built here from the frames, the code and the dropped frames; the sums are blurred by the plan's taps with zero
borders and divided at the selected voxels.
"""

import numpy as np
from scipy.ndimage import correlate

from flexvox_core.forward import sample_mask, sparse_volume
from flexvox_core.gaps import interpolated_subframes
from flexvox_core.motion.longreach import MIN_WEIGHT, LongReachPlan


def bilinear_zero(plane: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Bilinear reads (float64) of ``plane`` at (y, x), 0 outside the picture."""
    H, W = plane.shape
    y0, x0 = np.floor(y), np.floor(x)
    ay, ax = y - y0, x - x0
    acc = np.zeros(y.shape)
    for dy, wy in ((0, 1 - ay), (1, ay)):
        for dx, wx in ((0, 1 - ax), (1, ax)):
            yy, xx = y0 + dy, x0 + dx
            inside = (yy >= 0) & (yy < H) & (xx >= 0) & (xx < W)
            yi = np.where(inside, yy, 0).astype(int)
            xi = np.where(inside, xx, 0).astype(int)
            acc += np.where(inside, wy * wx * plane[yi, xi], 0.0)
    return acc


def long_reach_reference(frames, code, flow, guide, select, plan: LongReachPlan, missing=None,
                         write_samples=False) -> np.ndarray:
    frames = np.asarray(frames, np.float64)
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    value = sparse_volume(frames, code)
    mask = sample_mask((S, H, W), code).astype(np.float64)
    if missing is not None:
        gap = interpolated_subframes(missing, K)
        value[gap] = 0
        mask[gap] = 0
    flow = np.asarray(flow, np.float64)
    still = ~np.isfinite(flow).all(axis=-1)
    u = np.where(still, 0.0, flow[..., 0])
    v = np.where(still, 0.0, flow[..., 1])
    guide = np.asarray(guide, np.float64)
    out = guide.copy()
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    taps = plan.taps.astype(np.float64)
    kernel2 = np.outer(taps, taps)
    for t in range(S):
        acc_n = np.zeros((H, W))
        acc_d = np.zeros((H, W))
        for d in range(-plan.reach, plan.reach + 1):
            if not 0 <= t + d < S:
                continue
            num = bilinear_zero(value[t + d], yy + d * v[t], xx + d * u[t])
            den = bilinear_zero(mask[t + d], yy + d * v[t], xx + d * u[t])
            s = np.where(den > 0, num / np.where(den > 0, den, 1), 0)
            e = np.exp(plan.range_scale * (s - guide[t]) ** 2 - d * d / (2 * plan.sigma_t**2))
            acc_n += np.where(den > 0, num * e, 0)
            acc_d += np.where(den > 0, den * e, 0)
        acc_n = correlate(acc_n, kernel2, mode="constant")
        acc_d = correlate(acc_d, kernel2, mode="constant")
        keep = select[t] & (acc_d > MIN_WEIGHT)
        out[t][keep] = acc_n[keep] / acc_d[keep]
    if write_samples:
        m = mask > 0
        out[m] = value[m]
    return out
