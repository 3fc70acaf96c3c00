"""The slopes of a picture: its per-pixel gradient after a Gaussian blur.

Motion-aware's noise-aware smoothing (:mod:`~flexvox_core.motion.noise_aware`) and oriented nc
(:mod:`~flexvox_core.reconstruct.oriented_nc`) both read a picture's structure from these.
"""

from __future__ import annotations

import cv2
import numpy as np


def cv_radius(sigma: float) -> int:
    """How far (px) OpenCV's Gaussian blur of float images reaches for this σ (its kernel size is
    round(8σ + 1), made odd)."""
    size = int(round(sigma * 8 + 1)) | 1
    return size // 2


def slopes(picture: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """(∂x, ∂y) of ``picture`` (H, W) blurred by ``sigma`` px, float32, per pixel (Sobel's 3×3 derivative,
    which is 8 times the slope, scaled back), with reflecting borders. They read :func:`cv_radius` + 1 px around
    each pixel."""
    p = cv2.GaussianBlur(np.asarray(picture, np.float32), (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    gx = cv2.Sobel(p, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(p, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REFLECT)
    return gx, gy
