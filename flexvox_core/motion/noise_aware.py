r"""Motion-aware's noise-aware spatial smoothing: smooth across space where the picture is flat *compared
with the capture's own noise*, and keep edges and texture.

The trajectory gather blurs in space by Eq. 3's σ = √(2 n c₂) (0.7 px with the paper's tensor): enough to
keep fine texture, too little to average noise away where the picture is flat. Here the blur becomes a
per-voxel mixture of that kernel and a wide one (σ = half the code tile's pitch, √K / 2: 2 px at K = 16),

.. math::

    N = (1 - g)\,G_\sigma * n + g\,G_{wide} * n, \qquad D = (1 - g)\,G_\sigma * m + g\,G_{wide} * m,

with the weight of the wide kernel

.. math::

    g = \exp\!\left(-\frac{G_\rho * |\nabla (G_1 * I)|^2}{(\kappa\,\hat\sigma)^2}\right),

I the high-TR reconstruction's sub-frame, ρ = 1 px, κ = :data:`KAPPA` and :math:`\hat\sigma` the noise
(standard deviation) estimated from the capture itself (:func:`frame_noise`): where the smoothed gradient
is well below the noise the picture is flat and the wide kernel takes over; across an edge g falls to 0. A
positive mixture of two normalized convolutions is one, so the result stays a convex combination of the
samples (maximum principle) and the leave-one-out of the local choice extends to it.

The noise comes from **still pixels' successive samples**: an identity code samples each pixel once a
frame in the same slot, so where the scene is still two successive frames differ by noise alone, and
1.4826 · median |Δ| / √2 estimates its standard deviation (robust to the moving pixels the gate missed).
A noiseless capture gives 0 and the gather is exactly the paper's; so does a single-frame capture, which
has no successive samples. Photon noise depends on brightness; one figure per frame is its typical level.
``python bench/bench_motion_margin.py --noise [--no-noise-aware]`` measures what it adds (docs/benchmarks.md).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from flexvox_core.planes import Bands, band
from flexvox_core.slopes import slopes

KAPPA = 2.0
"""The smoothed gradient (per px) is compared with this many noise standard deviations."""
GRADIENT_SIGMA = 1.0
"""The high-TR sub-frame is blurred by this Gaussian (px) before its gradient is taken."""
RHO = 1.0
"""The squared gradient is averaged over this Gaussian (px)."""
MIN_PIXELS = 64
"""A frame's noise needs at least this many still pixel pairs; fewer: 0 (no noise-aware smoothing)."""
MAD_TO_SIGMA = 1.4826
"""Standard deviation of a normal distribution per median absolute deviation."""


def wide_sigma(K: int) -> float:
    """The wide kernel's standard deviation (px): half the pitch of a K-slot tile, √K / 2."""
    return math.sqrt(K) / 2


def frame_noise(frames: np.ndarray, still: np.ndarray | Bands, mask: np.ndarray | Bands, K: int) -> np.ndarray:
    """Noise standard deviation per frame (F,) float32, from the still pixels' successive samples.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The camera frames of an identity code (one sample per pixel and frame).
    still : ndarray (F·K, H, W) bool
        Voxels the motion gate found still (or a volume read a band of sub-frames at a time,
        :class:`~flexvox_core.planes.Bands`, as ``mask`` may be).
    mask : ndarray (F·K, H, W) bool, or a volume read by bands
        Where the samples are (a dropped frame's sub-frames hold none), read a frame's sub-frames at a time
        (:func:`~flexvox_core.planes.band`).
    K : int
        Slots of the code.

    Frame f pools the differences to its neighbours f − 1 and f + 1 at the pixels still at both
    samples; with fewer than :data:`MIN_PIXELS` of them its noise is 0.
    """
    F = np.shape(frames)[0]
    if tuple(still.shape) != tuple(mask.shape) or tuple(still.shape) != (F * K, *np.shape(frames)[1:]):
        raise ValueError(f"`still` {tuple(still.shape)} and `mask` {tuple(mask.shape)} must be (F·K, H, W) for {F} "
                         f"frames {np.shape(frames)[1:]} at K = {K}")
    # Whether each pixel's sample of each frame is still (a frame without samples: nowhere), a frame at a time.
    still_at = np.stack([(band(still, i * K, (i + 1) * K) & band(mask, i * K, (i + 1) * K)).any(axis=0)
                         for i in range(F)])
    return noise_from_still(frames, still_at)


def noise_from_still(frames: np.ndarray, still_at: np.ndarray) -> np.ndarray:
    """:func:`frame_noise` from ``still_at`` (F, H, W) bool: whether each pixel's sample of each frame is still."""
    f = np.asarray(frames, np.float32)
    F = f.shape[0]
    steps = []
    for i in range(F - 1):
        both = still_at[i] & still_at[i + 1]
        steps.append(np.abs(f[i + 1][both] - f[i][both]))
    out = np.zeros(F, np.float32)
    for i in range(F):
        near = [steps[j] for j in (i - 1, i) if 0 <= j < F - 1]
        diffs = np.concatenate(near) if near else np.zeros(0, np.float32)
        if diffs.size >= MIN_PIXELS:
            out[i] = MAD_TO_SIGMA * float(np.median(diffs)) / math.sqrt(2)
    return out


class SmoothWeights:
    """The wide kernel's weight g (H, W) float32 in [0, 1] for each sub-frame, computed when asked for
    (``weights[t]``; no volume is kept), or None for a sub-frame whose noise is 0.

    Parameters
    ----------
    guide : ndarray (S, H, W)
        The picture whose structure decides (motion-aware passes its high-TR reconstruction).
    noise : ndarray (S,)
        The noise standard deviation of each sub-frame (its frame's, :func:`frame_noise`).
    """

    def __init__(self, guide: np.ndarray, noise: np.ndarray):
        self.guide = guide
        self.noise = np.asarray(noise, np.float64)
        if self.noise.shape != (len(guide),) or not np.all(np.isfinite(self.noise) & (self.noise >= 0)):
            raise ValueError(f"`noise` must hold one finite number >= 0 per sub-frame ({len(guide)}); "
                             f"got shape {self.noise.shape}")

    def __len__(self) -> int:
        return len(self.guide)

    def __getitem__(self, t: int) -> np.ndarray | None:
        lam = KAPPA * self.noise[t]
        if lam <= 0:
            return None
        gx, gy = slopes(self.guide[t], GRADIENT_SIGMA)
        energy = cv2.GaussianBlur(gx * gx + gy * gy, (0, 0), RHO, borderType=cv2.BORDER_REFLECT)
        return np.exp(energy * np.float32(-1.0 / (lam * lam))).astype(np.float32, copy=False)
