"""Velocity of slow motion measured over a long baseline: flow across K sub-frames of the K-average.

Flow between *successive* sub-frames of a high-TR reconstruction is noisy for slow motion: each
sub-frame interpolates a different set of pixels ("swimming"), which shows up as spurious
motion of 0.1-0.4 px per sub-frame. The moving average over K sub-frames holds every sampling
phase once, so it does not swim, and a displacement measured across K of its sub-frames is K
times larger than a per-sub-frame one while the error of the flow stays about the same. On the
built-in ``pan`` scene (0.16 px per sub-frame) the endpoint error falls from 0.31 to 0.015 px per
sub-frame. Fast motion is blurred away in the average: there, successive-sub-frame flow wins
(:func:`flexvox_core.motion.pipeline.gated_flow` picks per pixel).

Slow motion changes slowly, so the long-baseline flow is measured every ``stride`` sub-frames
and interpolated linearly in time between them.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from flexvox_core.flow.backends import backend_params, make_backend
from flexvox_core.flow.estimate import FlowField, check_video, downscale, run_pairs, to_full_size, to_uint8_planes
from flexvox_core.threads import for_each, workers

_logger = logging.getLogger(__name__)


def kaverage_velocity(video, K: int, *, backend: str = "dis", scale: float = 0.5, stride: int | None = None,
                      **backend_params_) -> FlowField:
    """Velocity (px per sub-frame) of every voxel from flow across ``K`` sub-frames of the K-average.

    Parameters
    ----------
    video : ndarray (S, H, W), S >= 2, finite
    K : int
        Sampling period in sub-frames (the code's slot count), >= 1.
    backend, scale, **backend_params_
        As :func:`flexvox_core.flow.estimate_flow`.
    stride : int, optional
        Sub-frames between measurements (default :func:`default_stride`); linear in time between.
    """
    v = check_video(video).astype(np.float32, copy=False)
    if isinstance(K, bool) or not isinstance(K, int | np.integer) or K < 1:
        raise ValueError(f"`K` must be a whole number >= 1; got {K!r}")
    stride = default_stride(K) if stride is None else stride
    if isinstance(stride, bool) or not isinstance(stride, int | np.integer) or stride < 1:
        raise ValueError(f"`stride` must be a whole number >= 1; got {stride!r}")
    if not 0 < scale <= 1:
        raise ValueError(f"`scale` must be in (0, 1]; got {scale}")
    flow_fn = make_backend(backend, **backend_params_)
    t0 = time.perf_counter()
    vel, span = kaverage_flow(downscale(v, scale), K, flow_fn, stride)
    vel, vconf = to_full_size(vel, np.ones(vel.shape[:3], np.float32), v.shape[1:])
    seconds = time.perf_counter() - t0
    params = {**backend_params(flow_fn), "scale": scale, "baseline": span, "stride": stride}
    _logger.info("K-average flow %s on %d sub-frames: %.2f s", backend, v.shape[0], seconds)
    return FlowField(vel, vconf, params, seconds)


def default_stride(K: int) -> int:
    """Sub-frames between long-baseline measurements by default: a quarter of the period."""
    return max(1, K // 4)


def kaverage(video: np.ndarray, K: int) -> np.ndarray:
    """Moving average over K sub-frames (every sampling phase once), edges held (:func:`box_in_time`)."""
    return box_in_time(video, K) if K > 1 else video


def box_in_time(video: np.ndarray, size: int) -> np.ndarray:
    """``scipy.ndimage.uniform_filter1d(video, size, axis=0, mode="nearest")`` of a video (S, H, ...), the same
    bits. float32: compiled (:func:`~flexvox_core.flow.box_kernel.box_columns`, SciPy's running box over the pixels
    of a band of columns at once), a band per task on every core; another dtype: SciPy's own, a band of rows per
    task (SciPy releases the GIL)."""
    out = np.empty(video.shape, video.dtype)
    if video.dtype == np.float32 and video.ndim >= 2 and video.size and size >= 1:
        from flexvox_core.flow.box_kernel import box_columns

        src = np.ascontiguousarray(video).reshape(len(video), -1)
        flat = out.reshape(len(video), -1)
        N = src.shape[1]
        n = max(1, min(-(-N // BOX_COLUMNS), 4 * workers()))  # bands of at least BOX_COLUMNS columns
        cuts = [N * i // n for i in range(n + 1)]

        def band(i: int) -> None:
            box_columns(src, size, cuts[i], cuts[i + 1], flat)

        for_each(band, n)
        return out
    return box_in_time_scipy(video, size, out)


def box_in_time_scipy(video: np.ndarray, size: int, out: np.ndarray | None = None) -> np.ndarray:
    """:func:`box_in_time` by SciPy's ``uniform_filter1d`` itself, a band of rows per task on every core (SciPy
    releases the GIL), into ``out`` when given: :func:`box_in_time`'s for dtypes other than float32, and the
    reference its compiled form is tested against."""
    from scipy.ndimage import uniform_filter1d

    out = np.empty(video.shape, video.dtype) if out is None else out
    H = video.shape[1]
    n = max(1, min(H, 4 * workers()))
    edges = [H * i // n for i in range(n + 1)]

    def one(i: int) -> None:
        a, b = edges[i], edges[i + 1]
        uniform_filter1d(video[:, a:b], size, axis=0, mode="nearest", output=out[:, a:b])

    for_each(one, n)
    return out


BOX_COLUMNS = 4096
"""The fewest columns (values of a sub-frame) a task of :func:`box_in_time` takes."""


def kaverage_flow(small: np.ndarray, K: int, flow_fn, stride: int, *, average: np.ndarray | None = None,
                  memo=None):
    """Velocity ``(S, h, w, 2)`` of the :func:`~flexvox_core.flow.estimate.downscale` d video
    ``small``, in its pixels, and the baseline used (sub-frames). ``average``: its
    :func:`kaverage`, when the caller has it already; ``memo``: as
    :func:`~flexvox_core.flow.estimate.run_pairs`."""
    measured = KAverageFlow(small, K, flow_fn, stride, average=average, memo=memo)
    S, h, w = small.shape
    vel = np.empty((S, h, w, 2), np.float32)
    for s in range(S):
        measured.at(s, vel[s])
    return vel, measured.span


def measurements(S: int, K: int, stride: int) -> tuple[int, list[int]]:
    """The K-average's plan for ``S`` sub-frames: (span, the first sub-frame of each measurement), a measurement
    being the flow from sub-frame ``a`` to ``a + span`` (the last one ends at the last sub-frame)."""
    span = max(1, min(K, S - 1))
    starts = list(range(0, S - span, stride))
    if not starts or starts[-1] != S - 1 - span:
        starts.append(S - 1 - span)
    return span, starts


def blend(centres: np.ndarray, s: int) -> tuple[int, int, float]:
    """(j0, j1, a): sub-frame ``s``'s velocity is (1 − a)·disp[j0] + a·disp[j1], the measurements centred at
    ``centres``; j0 = j1 (a = 0) before the first centre and past the last."""
    j = int(np.searchsorted(centres, s))
    if j == 0 or j == len(centres):
        k = min(j, len(centres) - 1)
        return k, k, 0.0
    return j - 1, j, (s - centres[j - 1]) / (centres[j] - centres[j - 1])


class KAverageFlow:
    """The K-average's flow measured across ``span`` sub-frames every ``stride`` sub-frames, and the
    velocity of any sub-frame from it (:meth:`at`, a sub-frame at a time: no volume is made).
    Arguments as :func:`kaverage_flow`, which gives every sub-frame's."""

    def __init__(self, small: np.ndarray, K: int, flow_fn, stride: int, *, average: np.ndarray | None = None,
                 memo=None):
        S, h, w = small.shape
        span, starts = measurements(S, K, stride)
        self.span = span
        average = kaverage(small, K) if average is None else average
        u8 = to_uint8_planes(average)
        disp = np.empty((len(starts), h, w, 2), np.float32)
        conf = np.empty((len(starts), h, w), np.float32)  # each pair writes its plane (run_pairs)
        run_pairs(flow_fn, u8, [(a, a + span) for a in starts], disp, conf, consistency=False, memo=memo)
        disp /= span
        self.disp = disp
        self.centres = np.asarray(starts, np.float64) + span / 2

    def at(self, s: int, out: np.ndarray) -> np.ndarray:
        """Velocity ``(h, w, 2)`` of sub-frame ``s`` into ``out``: linear in time between measurements,
        constant beyond the first and last."""
        disp = self.disp
        j0, j1, a = blend(self.centres, s)
        if j0 == j1:
            out[...] = disp[j0]
        else:
            out[...] = (1 - a) * disp[j0] + a * disp[j1]
        return out
