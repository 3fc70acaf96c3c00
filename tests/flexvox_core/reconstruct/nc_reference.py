"""Normalized convolution the straightforward way, in float64: the reference the tests (and bench.bench_nc)
compare :func:`flexvox_core.reconstruct.diffuse`'s ``nc`` with."""

import numpy as np

from flexvox_core.reconstruct._common import check_frames, check_identity_code
from flexvox_core.reconstruct.diffusion import (
    DEFAULT_TENSOR,
    DEFAULT_TIME,
    NC_MIN_WEIGHT,
    TRUNCATE,
    _nearest_fill,
    _peak,
    _put_samples,
    _sample_mask,
    _sample_volume,
    gaussian_kernel,
    sigmas,
)


def nc_naive(frames, code, *, tensor=DEFAULT_TENSOR, time: float = DEFAULT_TIME,
             keep_samples: bool = True) -> np.ndarray:
    """Normalized convolution with ``scipy.ndimage.gaussian_filter`` in float64 (a baseline).

    The straightforward implementation of ``diffuse(..., solver="nc")``: the same kernels,
    boundaries and fall-back, on dense float64 volumes, for checking and benchmarking.

    Returns
    -------
    video : ndarray, shape (F·K, H, W), float64
    """
    from scipy.ndimage import gaussian_filter

    f = check_frames(frames)
    c = check_identity_code(code)
    sig = sigmas(tensor, time)
    vals, order = _sample_volume(f, c, np.float64)
    mask = _sample_mask(order, *f.shape[:1], c.shape[2])
    sigma = (sig[2], sig[1], sig[0])
    num = gaussian_filter(vals, sigma, mode="reflect", truncate=TRUNCATE)
    den = gaussian_filter(mask.astype(np.float64), sigma, mode="reflect", truncate=TRUNCATE)
    peak = _peak(gaussian_kernel(s, np.float64) for s in sig)
    low = den <= NC_MIN_WEIGHT * peak
    out = np.divide(num, den, out=np.zeros_like(num), where=~low)
    samples = f.astype(np.float64)
    if low.any():
        _put_samples(out, samples, order)
        _nearest_fill(out, mask, low, sig)
    np.clip(out, samples.min(), samples.max(), out=out)
    if keep_samples:
        _put_samples(out, samples, order)
    return out
