"""The trajectory gather's last steps on a box in plain numpy (the code before
:func:`flexvox_core.motion.mcnc_kernel.divide_box` took them over): the leave-one-out at the box's samples and
N / D with the fallback where the weight is too small."""

import cv2
import numpy as np

from flexvox_core.motion.gather_weights import MIN_WEIGHT
from flexvox_core.reconstruct.diffusion import self_weights


def own_weights_at(sigma, h, w, ys, xs):
    """Weight (float64) each pixel (``ys``, ``xs``) of an (h, w) box gives itself in cv2.GaussianBlur with ``sigma``
    (px) and reflecting borders; 1 without a blur (σ <= 0.05, as the gather skips it)."""
    if sigma <= 0.05:
        return np.ones(len(ys))
    g = cv2.getGaussianKernel(int(round(sigma * 8 + 1)) | 1, sigma, cv2.CV_64F).ravel()
    return self_weights(g, h)[ys] * self_weights(g, w)[xs]


def leave_one_out(dst, planes, sampled, y, sig_space, wide=None, wide_sigma=0.0):
    """(N − c·y) / (D − c) at the ``sampled`` voxels of a box into ``dst`` (NaN where D − c <= MIN_WEIGHT)."""
    ys, xs = np.nonzero(sampled)
    if not len(ys):
        return
    h, w = sampled.shape
    own = own_weights_at(sig_space, h, w, ys, xs)
    if wide is not None:
        own = own + wide[ys, xs].astype(np.float64) * (own_weights_at(wide_sigma, h, w, ys, xs) - own)
    rest = planes[1][sampled] - own
    est = (planes[0][sampled] - own * y[sampled]) / np.where(rest > MIN_WEIGHT, rest, 1.0)
    dst[sampled] = np.where(rest > MIN_WEIGHT, est, np.nan)


def finish(planes, inside, sampled, y, sig_space, wide, wide_sigma, fallback, loo, out):
    """The leave-one-out (``loo`` (h, w), or None) and N / D, the ``fallback`` (h, w) where D <= MIN_WEIGHT, into
    ``out`` (h, w) at the voxels ``inside``: ``planes`` (N, D) blurred already."""
    if loo is not None:
        leave_one_out(loo, planes, inside & sampled, y, sig_space, wide, wide_sigma)
    ok = planes[1] > MIN_WEIGHT
    est = np.divide(planes[0], planes[1], out=np.zeros_like(planes[0]), where=ok)
    region = np.float32(0) if fallback is None else np.asarray(fallback, np.float32)
    np.copyto(out, np.where(ok, est, region), where=inside)
