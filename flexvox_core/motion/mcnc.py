r"""Motion-compensated normalized convolution: the one-pass form of Eq. 3 with the field of Eq. 4.

Normalized convolution (Knutsson & Westin 1993) blurs the sampled values and divides by the
blurred sampling mask. Here the blur follows each voxel's trajectory: to estimate I(x, t),
samples of sub-frame t + d are read at x + d·(u, v) (the flow at (x, t), a straight
trajectory), weighted by the Gaussian of Eq. 3 along λ,

.. math::

    w_d = \exp\left(-\frac{d^2 (1 + u^2 + v^2)}{4 n c_1}\right),

(the step d·(u, v, 1) has length d·|(u, v, 1)|), then blurred in space with variance
2 n c2 for the directions across λ (isotropic: exact for c2 = c3 and zero flow). Where
the blurred mask is too small to trust (no sample nearby), ``fallback`` fills in.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from flexvox_core.motion.tensors import DEFAULT_C, check_c

MIN_WEIGHT = 1e-6


def motion_compensated_nc(
    sparse,
    mask,
    flow,
    *,
    c=DEFAULT_C,
    time: float = 2.0,
    fallback=None,
    keep_samples: bool = True,
    max_reach: int | None = None,
) -> np.ndarray:
    """Reconstruct a video from samples along the flow's trajectories.

    Parameters
    ----------
    sparse : ndarray, shape (S, H, W)
        Sampled values at their voxels (0 elsewhere), see :func:`flexvox_core.forward.sparse_volume`.
    mask : ndarray of bool, shape (S, H, W)
    flow : ndarray, shape (S, H, W, 2)
    c : (c1, c2, c3)
    time : float
        Diffusion time n > 0 of Eq. 3.
    fallback : ndarray (S, H, W), optional
        Used where the weights are below :data:`MIN_WEIGHT` (default: the sparse value).
    keep_samples : bool
        Keep measured voxels exactly.
    max_reach : int, optional
        Largest |d| in sub-frames (default: the larger of 3 standard deviations of the static
        case and the sampling period K, at most S-1).
    """
    c1, c2, _ = check_c(c)
    vals = np.asarray(sparse, dtype=np.float32)
    m = np.asarray(mask, dtype=bool)
    f = np.asarray(flow, dtype=np.float32)
    if vals.ndim != 3 or m.shape != vals.shape or f.shape != (*vals.shape, 2):
        raise ValueError(f"`sparse` (S, H, W), `mask` and `flow` (S, H, W, 2) must match; got "
                         f"{vals.shape}, {m.shape}, {f.shape}")
    if not math.isfinite(time) or time <= 0:
        raise ValueError(f"`time` must be a finite number > 0; got {time!r}")
    S, H, W = vals.shape
    f = np.where(np.isfinite(f), f, 0).astype(np.float32)
    if max_reach is None:
        # Far enough for 3 standard deviations, and at least one sampling period (a pixel is
        # sampled once every K sub-frames), so a still pixel always reaches its own samples.
        per_pixel = int(m.sum(axis=0).min()) if S else 0
        period = S // per_pixel if per_pixel else S
        reach = max(math.ceil(3 * math.sqrt(2 * time * c1)), period)
    else:
        reach = int(max_reach)
    reach = max(0, min(reach, S - 1))
    sig_space = math.sqrt(2 * time * c2)
    both = np.stack([vals * m, m.astype(np.float32)], axis=-1)  # (S, H, W, 2): value·mask, mask
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    out = np.empty((S, H, W), np.float32)
    for t in range(S):
        u, v = f[t, ..., 0], f[t, ..., 1]
        # w_d = e^(d²) with e = exp(-(1 + u² + v²) / (4 n c1)): built by multiplication, since
        # d² is the sum of the first d odd numbers (no exp per offset).
        e = np.exp(-(1 + u * u + v * v) / np.float32(4 * time * c1)).astype(np.float32)
        e2 = e * e
        w = np.ones((H, W), np.float32)
        step = e.copy()
        acc = both[t].copy()  # d = 0, weight 1
        for d in range(1, reach + 1):
            w *= step
            step *= e2
            if float(w.max()) < MIN_WEIGHT * 1e-3:
                break  # every trajectory has left the Gaussian's reach
            for sd in (d, -d):
                if 0 <= t + sd < S:
                    src = cv2.remap(both[t + sd], gx + sd * u, gy + sd * v, cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=0)
                    acc += src * w[..., None]
        if sig_space > 0.05:
            acc = cv2.GaussianBlur(acc, (0, 0), sig_space, borderType=cv2.BORDER_REFLECT)
        num, den = acc[..., 0], acc[..., 1]
        ok = den > MIN_WEIGHT
        est = np.divide(num, den, out=np.zeros_like(num), where=ok)
        if fallback is not None:
            est = np.where(ok, est, np.asarray(fallback[t], np.float32))
        out[t] = est
    if keep_samples:
        out[m] = vals[m]
    return out
