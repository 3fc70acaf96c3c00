r"""Multiplexed captures reconstructed from their own forward model (GAP with flexvox's priors).

A multiplexed code opens each pixel in about half of the K slots, so a camera value is the sum
of (K+1)/2 voxels (:func:`flexvox_core.forward.capture`). Demultiplexing per tile
(:func:`flexvox_core.multiplex.demultiplex`) inverts that sum only where the scene is constant
over the tile; here the video is instead reconstructed from the sums themselves by generalized
alternating projection (:func:`flexvox_core.reconstruct.gaptv.gap`): the projection onto the
measurements alternates with a *denoiser* that is one of the priors identity codes use,

- the constant-tensor Gaussian of Eq. 3 (:func:`flexvox_core.reconstruct.diffusion.gaussian`,
  :func:`gap_gaussian`: constant-tensor diffusion as a denoiser);
- a motion-compensated Gaussian along optical flow
  (:func:`flexvox_core.motion.multiplexed.motion_aware_multiplexed`);
- TV (GAP-TV itself, :func:`flexvox_core.reconstruct.gaptv.gap_tv`, which takes any 0/1 code).

**Start.** θ⁽⁰⁾ is every pixel's measurement divided by the slots it is open in, held over the
frame's K sub-frames (:func:`mean_start`): exact for a scene that is still, so a constant scene
comes back exactly (every step keeps it: the residual is zero and the Gaussian keeps constants).

**Windows.** Camera frame f is reconstructed from frames ``[f − context, f + context]`` and only
its own K sub-frames are kept (:func:`by_windows`), so the prior reaches ``context`` frames into
time and a run in time chunks with that overlap equals the whole run, bit for bit (an iterated
prior over the whole clip would reach ``iterations`` times as far).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from flexvox_core.codes import validate_code
from flexvox_core.forward import tiled_code
from flexvox_core.reconstruct._common import check_dtype, check_frames
from flexvox_core.reconstruct.diffusion import gaussian, sigmas
from flexvox_core.reconstruct.gaptv import gap

_logger = logging.getLogger(__name__)

__all__ = ["CONTEXT", "ITERATIONS", "TENSOR", "TIME", "TIME_FRACTION", "by_windows", "check_any_code", "gap_gaussian",
           "gaussian_solver", "mean_start"]

TENSOR = (0.15, 0.15, 1.0)
"""The Gaussian denoiser's tensor (diffusion's default tensor)."""
TIME_FRACTION = 1 / 3
"""The diffusion method's time n becomes a Gaussian of time ``n · TIME_FRACTION`` per GAP iteration."""
TIME = 1.5 * TIME_FRACTION
"""The Gaussian denoiser's diffusion time per GAP iteration (diffusion's default time, n = 1.5, times
:data:`TIME_FRACTION`)."""
ITERATIONS = 20
"""GAP iterations per window."""
CONTEXT = 1
"""Camera frames on each side of the reconstructed one that its window holds."""

Solve = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``solve(y (Fw, H, W), masks (K, H, W)) -> (Fw, K, H, W)``: one window's reconstruction."""


def check_any_code(code, height: int, width: int) -> np.ndarray:
    """The per-slot masks ``(K, H, W)`` float of any 0/1 ``code`` that opens every pixel at least once."""
    masks = tiled_code(validate_code(code), height, width)
    if not masks.any(axis=0).all():
        raise ValueError("`code` leaves some tile pixel closed in every slot; nothing measures it")
    return masks


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"`{name}` must be a whole number >= {minimum}; got {value!r}")
    return int(value)


def mean_start(y: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """θ⁽⁰⁾ ``(F, K, H, W)``: each pixel's measurement over its open-slot count, in all K slots."""
    per_pixel = y / masks.sum(axis=0, dtype=y.dtype)
    return np.repeat(per_pixel[:, None], masks.shape[0], axis=1)


def by_windows(frames: np.ndarray, masks: np.ndarray, solve: Solve, context: int) -> np.ndarray:
    """Reconstruct each camera frame from its window of ``±context`` frames; ``(F·K, H, W)``."""
    F, H, W = frames.shape
    K = masks.shape[0]
    out = np.empty((F, K, H, W), frames.dtype)
    for f in range(F):
        lo, hi = max(0, f - context), min(F, f + context + 1)
        out[f] = solve(frames[lo:hi], masks)[f - lo]
    return out.reshape(F * K, H, W)


def gaussian_solver(tensor, time: float, iterations: int) -> Solve:
    """A window's GAP with the constant-tensor Gaussian as its denoiser, from :func:`mean_start`."""
    sigmas(tensor, time)  # the messages diffusion gives

    def solve(y: np.ndarray, masks: np.ndarray) -> np.ndarray:
        denoise = lambda v: gaussian(v, tensor, time)  # noqa: E731
        return gap(y, masks, denoise, iterations, start=mean_start(y, masks))

    return solve


def gap_gaussian(frames, code, *, tensor=TENSOR, time: float = TIME, iterations: int = ITERATIONS,
                 context: int = CONTEXT, dtype=np.float32) -> np.ndarray:
    """Reconstruct a capture with any 0/1 code by GAP with the constant-tensor Gaussian as denoiser.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        Camera frames on the 0–1 scale of one open slot (a multiplexed value is a sum of slots).
    code : ndarray, shape (m, n, K)
        Any 0/1 code (multiplexed or identity) opening every tile pixel at least once.
    tensor, time : the Gaussian of Eq. 3 applied at every iteration (σᵢ = √(2·time·cᵢ)).
    iterations : int
        GAP iterations per window (accelerated).
    context : int
        Camera frames on each side in each frame's window.
    dtype : float32 or float64

    Returns
    -------
    video : ndarray, shape (F·K, H, W), ``dtype`` (not clipped)

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import capture, multiplexed_code
    >>> code = multiplexed_code((1, 3)).code
    >>> out = gap_gaussian(capture(np.full((6, 4, 6), 0.5), code), code)
    >>> out.shape, bool(np.allclose(out, 0.5))
    ((6, 4, 6), True)
    """
    f = check_frames(frames).astype(check_dtype(dtype), copy=False)
    masks = check_any_code(code, *f.shape[1:])
    solve = gaussian_solver(tensor, time, _check_int("iterations", iterations, 0))
    video = by_windows(f, masks, solve, _check_int("context", context, 0))
    _logger.debug("gap_gaussian: %d frames, K = %d, %d iterations, context %d", f.shape[0], masks.shape[0],
                  iterations, context)
    return video
