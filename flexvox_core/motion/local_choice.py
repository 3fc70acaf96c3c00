r"""Motion-aware's local choice: where its gather predicts the samples worse than oriented ``nc``, take ``nc``.

Eq. 4's tensor smooths only along the motion. Where the picture itself is smooth, or the flow is wrong, a
normalized convolution that reaches across space fills the voxels better (on the SCI clip Drop, isotropic
``nc``, tensor (1, 1, 1), n = 0.25, beats the trajectory gather alone: docs/benchmarks.md, ``flexvox bench``).
The candidate is **oriented nc** (:mod:`~flexvox_core.reconstruct.oriented_nc`): that isotropic ``nc`` with
its spatial kernel stretched along the edges of the high-TR reconstruction and squeezed across them
(structure-adaptive normalized convolution, Pham, van Vliet & Schutte 2006). The choice is made without the
truth, by **leave-one-out**: every sample is estimated by each method from all the *other* samples (for a
normalized convolution, :math:`(N - c\,y)/(D - c)`, c the weight the sample gives itself), and the squared errors,
smoothed in space within each frame by a Gaussian of a sixteenth of the picture's shorter side
(:func:`pooling_sigma`), weigh the two per pixel:

.. math::

    w_{ma} = \frac{\bar E_{nc}^{p}}{\bar E_{ma}^{p} + \bar E_{nc}^{p}}, \qquad p = 2,

applied to the voxels the short trajectory gather estimated (the *fast* voxels; still and slow voxels
keep their own estimates, whose leave-one-out is not the gather's). A convex blend of two results within
the samples' range stays within it, and both keep the samples. What the choice adds is the difference between
``flexvox bench``'s default motion-aware row and its ``gather-only`` row (docs/benchmarks.md, "flexvox bench").

A known bias: a sample's leave-one-out leaves its pixel without its own sample, which the gather leans on
most where a pixel is still and sampled once within the gather's reach (a single-frame capture of a still
subject): there the gather's error is overestimated and the candidate takes too much
(``bench/bench_choice_bias.py`` measures it on such captures, with and without each candidate).
:func:`still_voxel_loo` corrects it where the flow calls a voxel still: there the pixel's own sample *is*
the truth at its other voxels, and the gather is scored on its error at them (see there). The gather's
leave-one-out is kept everywhere else, and oriented nc's everywhere: its time Gaussian (σ = 0.71
sub-frames) reaches a pixel's own sample only one sub-frame away, so leaving it out costs nc little.
"""

from __future__ import annotations

import cv2
import numpy as np

from flexvox_core import planes
from flexvox_core.motion.subframes import flow_at
from flexvox_core.threads import for_each

SIGMA_SHARE = 1 / 16
"""Spatial standard deviation over which the leave-one-out errors are pooled, as a share of the picture's
shorter side: the same part of the scene at any resolution (6 px at 96×128, 30 px at 640×480). A fixed
width in pixels pools too narrowly on large pictures (``bench/bench_motion_throughput.py`` at 640×480)."""
MIN_SIGMA = 3.0
"""The pooling's standard deviation is never below this many pixels."""
POWER = 2
"""Exponent of the pooled errors in the weight (higher: closer to a hard choice)."""


def pooling_sigma(height: int, width: int) -> float:
    """The pooling's standard deviation (px) for a picture of this size (:data:`SIGMA_SHARE`, :data:`MIN_SIGMA`)."""
    return max(MIN_SIGMA, min(height, width) * SIGMA_SHARE)


def local_weights(loo_a: np.ndarray, loo_b: np.ndarray, samples: np.ndarray, *, sigma: float | None = None,
                  power: int = POWER) -> np.ndarray:
    """Weight of method a per frame and pixel (F, H, W) float32 in [0, 1] from the leave-one-out estimates.

    Parameters
    ----------
    loo_a, loo_b : ndarray (F, H, W)
        Each method's leave-one-out estimate of every pixel's sample (NaN: none).
    samples : ndarray (F, H, W)
        The samples (the camera frames of an identity code).
    sigma, power : float or None, int
        Pooling standard deviation (px; None: :func:`pooling_sigma`) and exponent.

    Where neither method has a pooled error (no pixel with both estimates within reach, or both exact),
    the weight is 1: method a stands.
    """
    a, b, y = (np.asarray(v, np.float32) for v in (loo_a, loo_b, samples))
    if a.shape != b.shape or a.shape != y.shape or a.ndim != 3:
        raise ValueError(f"`loo_a`, `loo_b` and `samples` must be (F, H, W) arrays of one shape; got "
                         f"{a.shape}, {b.shape}, {y.shape}")
    if sigma is None:
        sigma = pooling_sigma(*a.shape[1:])
    if not (np.isfinite(sigma) and sigma > 0) or isinstance(power, bool) or not isinstance(power, int) or power < 1:
        raise ValueError(f"`sigma` must be > 0 and `power` a whole number >= 1; got {sigma!r}, {power!r}")
    if power != 2:
        return local_weights_numpy(a, b, y, sigma=sigma, power=power)
    from flexvox_core.motion.local_choice_kernel import squared_errors, weight_of_a

    out = np.empty(a.shape, np.float32)

    def frame(f):  # a frame's weights read its own planes alone: the frames run side by side
        ea = np.empty(a.shape[1:], np.float32)
        eb = np.empty(a.shape[1:], np.float32)
        if squared_errors(a[f], b[f], y[f], ea, eb):
            weight_of_a(_pooled(ea, sigma), _pooled(eb, sigma), out[f])
        else:
            out[f].fill(1)

    for_each(frame, a.shape[0])
    return out


def local_weights_numpy(loo_a: np.ndarray, loo_b: np.ndarray, samples: np.ndarray, *, sigma: float,
                        power: int) -> np.ndarray:
    """:func:`local_weights` in numpy, a frame at a time on one thread, at any power (its compiled form's
    reference, which runs power 2; arguments checked there)."""
    a, b, y = (np.asarray(v, np.float32) for v in (loo_a, loo_b, samples))
    out = np.ones(a.shape, np.float32)
    for f in range(a.shape[0]):
        valid = np.isfinite(a[f]) & np.isfinite(b[f])
        if not valid.any():
            continue
        # The mean error over the valid pixels near each one is the blurred error over the blurred
        # count; the count cancels in the ratio, so only the errors are blurred.
        ea = _pooled(np.where(valid, (a[f] - y[f]) ** 2, 0).astype(np.float32), sigma).astype(np.float64) ** power
        eb = _pooled(np.where(valid, (b[f] - y[f]) ** 2, 0).astype(np.float32), sigma).astype(np.float64) ** power
        total = ea + eb
        ok = total > 1e-30
        out[f] = np.where(ok, eb / np.where(ok, total, 1.0), 1.0)
    return out


BAND = 32
"""The fewest sub-frames motion-aware's local choice makes oriented nc for at a time (whole frames; more with more
threads: two sub-frames a thread). Each band's call checks its inputs again, some milliseconds at 640×480."""

STILL_VOXEL_SPEED = 0.15
"""Below this flow speed (px per sub-frame; the motion gate's "trusted as moving" threshold) a gathered voxel
is scored by :func:`still_voxel_loo` against its pixel's own sample. Above it the flow may be real motion, so
the pixel's sample is no longer the truth at its other voxels; ``bench/bench_choice_bias.py`` and
``flexvox bench`` measure the choice at this threshold."""


def still_voxel_loo(loo: np.ndarray, video: np.ndarray, samples: np.ndarray, gathered: np.ndarray | planes.Bands,
                    mask: np.ndarray | planes.Bands, flow: np.ndarray | planes.Bands, K: int, *,
                    speed: float = STILL_VOXEL_SPEED) -> None:
    r"""Correct the gather's leave-one-out ``loo`` (F, H, W), in place, for the pixels it leans on.

    The choice needs each method's error at a pixel's gathered voxels, and a sample's leave-one-out takes
    away the sample the gather leans on most there when the pixel is still: at zero flow its trajectory
    runs through the pixel, and the refinement diffuses the kept sample along it. Where the flow at a
    gathered voxel is below ``speed`` the pixel is taken as still, so its sample y is the truth there and
    the gather's error is observed, not estimated: (v − y)², v the gather's value. Per frame and pixel,
    the error is the mean over its gathered voxels without a sample, (v − y)² at those slower than
    ``speed`` and the leave-one-out's (ℓ − y)² at the others; ``loo`` becomes y + √error, whose squared
    distance to the sample is that error (:func:`local_weights` is unchanged). Pixels without such a slow
    voxel keep their leave-one-out exactly.

    Where the pixel is in fact still the observed error is exact (noise included it is
    (1 − s)²(E_rest + σ²), s the sample's share of v, against the truth's s²σ² + (1 − s)²E_rest:
    conservative while s < ½). Where it moves and the flow misses it, v − y misses the change; the
    threshold keeps that to the voxels the motion gate would not trust as moving anyway.

    Parameters
    ----------
    loo : ndarray (F, H, W) float32
        The gather's leave-one-out (NaN: none), corrected in place.
    video : ndarray (F·K, H, W)
        The gather's result (after the refinement), samples kept.
    samples : ndarray (F, H, W)
        The camera frames of the identity code.
    gathered, mask : ndarray (F·K, H, W) bool, or volumes read by bands
        The voxels the gather estimated, and the sample voxels (read a frame's sub-frames at a time,
        :func:`~flexvox_core.planes.band`).
    flow : ndarray (F·K, H, W, 2), or a volume read by bands
        The flow the gather followed.
    K : int
        Sub-frames per frame.
    """
    F, H, W = loo.shape
    limit = np.float32(speed) ** 2
    flat = loo.reshape(F, -1)

    def frame(f):  # a frame's sub-frames correct its own row alone: the frames run side by side, the same bits
        count = np.zeros(H * W, np.float32)  # gathered voxels without a sample, per pixel
        slow = np.zeros(H * W, np.float32)  # of them slower than `speed`
        seen = np.zeros(H * W, np.float32)  # their summed (v - y)²
        s0, s1 = f * K, (f + 1) * K
        chosen, sampled = planes.band(gathered, s0, s1), planes.band(mask, s0, s1)
        motion = None
        for i in range(K):
            idx = np.flatnonzero(chosen[i] & ~sampled[i])
            if not len(idx):
                continue
            count[idx] += 1
            if motion is None:  # the frame's flow, read once it is needed
                motion = planes.band(flow, s0, s1)
            u, v = flow_at(motion[i], idx)
            idx = idx[u * u + v * v < limit]
            if len(idx):
                slow[idx] += 1
                seen[idx] += (video[s0 + i].reshape(-1)[idx] - samples[f].reshape(-1)[idx]) ** 2
        row = flat[f]
        use = (slow > 0) & np.isfinite(row)
        if not use.any():
            return
        y = np.asarray(samples[f], np.float32).reshape(-1)
        err = (seen + (count - slow) * (row - y) ** 2) / np.maximum(count, 1)
        np.copyto(row, y + np.sqrt(err, dtype=np.float32), where=use)

    for_each(frame, F)


COARSE_SIGMA = 8.0
"""Above this pooling σ (px) the errors are pooled on a grid ⌊σ/4⌋ times coarser (area-averaged, blurred,
resized back): a Gaussian that wide is smooth on that grid, and its full-size kernel costs ~0.4 s per VGA clip."""


def _pooled(plane: np.ndarray, sigma: float) -> np.ndarray:
    """``plane`` blurred by a Gaussian of ``sigma`` px (reflecting borders), on a coarser grid when wide."""
    if sigma <= COARSE_SIGMA:
        return cv2.GaussianBlur(plane, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    h, w = plane.shape
    step = int(sigma // 4)
    small = cv2.resize(plane, (max(1, -(-w // step)), max(1, -(-h // step))), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / step, borderType=cv2.BORDER_REFLECT)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def _check_blend(video: np.ndarray, other: np.ndarray, weights: np.ndarray, where: np.ndarray, K: int) -> None:
    S = video.shape[0]
    if other.shape != video.shape or where.shape != video.shape or weights.shape[0] * K != S:
        raise ValueError(f"`video` {video.shape}, `other` {other.shape}, `where` {where.shape} and `weights` "
                         f"{weights.shape} at K = {K} do not match")


def blend(video: np.ndarray, other: np.ndarray, weights: np.ndarray, where: np.ndarray, K: int) -> None:
    """``video ← w·video + (1 − w)·other`` at the voxels ``where`` (S, H, W), in place; ``weights`` (F, H, W)
    holds frame f's weight for its K sub-frames. Compiled, a sub-frame per task on every core
    (:func:`~flexvox_core.motion.local_choice_kernel.blend_plane`): :func:`blend_numpy`'s bits."""
    from flexvox_core.motion.local_choice_kernel import blend_plane

    _check_blend(video, other, weights, where, K)

    def one(s):
        blend_plane(video[s], other[s], weights[s // K], np.asarray(where[s], bool))

    for_each(one, video.shape[0])


def blend_numpy(video: np.ndarray, other: np.ndarray, weights: np.ndarray, where: np.ndarray, K: int) -> None:
    """:func:`blend` in numpy, a sub-frame at a time on one thread (the compiled form's reference)."""
    _check_blend(video, other, weights, where, K)
    S = video.shape[0]
    for s in range(S):
        if not where[s].any():
            continue
        # video + (1 − w)·(other − video): where both hold the same value (a sample) it stays that value exactly.
        mixed = video[s] + (1 - weights[s // K]) * (other[s] - video[s])
        np.copyto(video[s], mixed, where=where[s])
