"""The gated flow: motion-aware's velocity of every voxel (the flow stage of :mod:`flexvox_core.motion.stages`).

The paper's §4 step 2: optical flow between successive frames of the high-TR reconstruction.
"""

from __future__ import annotations

from time import perf_counter

import cv2
import numpy as np

from flexvox_core.flow import FlowField
from flexvox_core.flow.backends import backend_params, make_backend
from flexvox_core.flow.baseline import KAverageFlow, blend, box_in_time, default_stride, kaverage
from flexvox_core.flow.estimate import (
    ScaledFlow,
    check_video,
    downscale,
    scaled_vectors,
    successive_flow,
    to_full_size,
)
from flexvox_core.motion.gated_flow_kernel import gate_plane
from flexvox_core.motion.options import DEFAULT_GATE, PERIOD_GATE, SLOW_SPEED
from flexvox_core.threads import for_each

DIS_PARAMS = {"variational_iterations": 2}
"""Motion-aware's DIS flow (every pair it measures): 2 iterations of the variational refinement (Brox's energy)
instead of OpenCV's 5. The refinement smooths the flow of the high-TR video across its motion edges, where the
trajectories matter most; fewer iterations keep those edges, and each pair's flow costs less. One or none
lose on still scenes. ``flexvox bench`` and ``bench/bench_motion_margin.py`` measure it (docs/benchmarks.md);
``bench/make_quality_figure.py``'s "before" column runs OpenCV's 5."""

DETECTOR_DIS_PARAMS = DIS_PARAMS
"""The motion detector's DIS flow (successive sub-frames of the K-average, at half the flow's size), which only
opens the gate: :data:`DIS_PARAMS`. A search no finer than pyramid level 2 (``finest_scale=2``) does a quarter of
the work but moved PSNR both ways (drummer +0.15 to +0.3 dB, balls −0.09 dB at 240×320; docs/benchmarks.md)."""


def gated_flow(video: np.ndarray, K: int, *, backend: str, gate=DEFAULT_GATE, scale: float = 0.5,
               consistency: bool = False, slow_speed: float | None = SLOW_SPEED,
               period_gate=PERIOD_GATE, memo=None) -> FlowField | ScaledFlow:
    """Flow of ``video`` with still regions set to zero and slow motion measured over a long baseline.

    The motion detector looks only at the K-average, which holds every sampling phase once and
    so cannot swim (a still region is exactly still): its flow across K sub-frames
    (:func:`~flexvox_core.flow.baseline.kaverage_flow`) and, for fast motion smeared in the
    average, its flow between successive sub-frames; the larger speed opens the ``gate`` ramp.
    Where the long-baseline flow is slower than ``slow_speed`` (and the successive-sub-frame flow
    of ``video`` not much faster) it is the velocity — 20x more accurate there; elsewhere the
    successive-sub-frame flow of ``video`` is. None, or a clip of at most K sub-frames (whose
    averages overlap): successive-sub-frame flow everywhere.

    Motion that the K-average cannot see — aliased at the sampling period, like the built-in fan
    (3 blades, a turn every 48 sub-frames: at K = 16 every pixel sees the same blade phase in
    every frame) — opens the ``period_gate`` ramp instead: the speed of the successive-sub-frame
    flow averaged over K sub-frames. The high-TR video swims with the code's period (about
    1 px per sub-frame at K = 16), which that average cancels (0.1 px median on the still scene,
    0.54 px at the 99th percentile) while steady motion remains (1.5 px median on the fan's blades).
    None: no second gate.

    ``memo`` (a :class:`~flexvox_core.flow.memo.FlowMemo`): flow of pairs of images met before is
    taken from it (a streaming run meets each pair in several windows); it never changes the result.
    """
    lo, hi = gate
    if not 0 <= lo < hi:
        raise ValueError(f"`gate` must be two thresholds 0 <= low < high (px per sub-frame); got {gate!r}")
    if period_gate is not None and not 0 <= period_gate[0] < period_gate[1]:
        raise ValueError(f"`period_gate` must be two thresholds 0 <= low < high (px per sub-frame) or None; "
                         f"got {period_gate!r}")
    if slow_speed is not None and not slow_speed >= 0:
        raise ValueError(f"`slow_speed` must be a number >= 0 (px per sub-frame) or None; got {slow_speed!r}")
    video = check_video(video)
    flow_fn = make_backend(backend, **(DIS_PARAMS if backend == "dis" else {}))
    t0 = perf_counter()
    # Everything at the flow's own (small) resolution; resized once at the end.
    small = downscale(video, scale)
    vel, conf = successive_flow(small, flow_fn, consistency=consistency, temporal_window=1, memo=memo)
    px = video.shape[2] / vel.shape[2]  # full-size pixels per flow pixel: thresholds are in full-size ones
    params = {**backend_params(flow_fn), "scale": scale, "consistency": consistency, "temporal_window": 1}
    if not (K > 1 and video.shape[0] > 1):
        vel, conf = to_full_size(vel, conf, video.shape[1:])
        return FlowField(vel, conf, params, perf_counter() - t0)
    average = kaverage(small, K)
    slow = KAverageFlow(small, K, flow_fn, default_stride(K), average=average, memo=memo)
    use_slow = slow_speed is not None and slow.span == K  # shorter: the averages overlap, too blurred
    if use_slow:
        params["slow_speed"] = slow_speed
    # Fast motion is smeared in the K-average and can escape a flow across K of its
    # sub-frames: the detector also takes flow between its successive sub-frames (at half size).
    steps, _ = successive_flow(downscale(average, 0.5), make_backend("dis", **DETECTOR_DIS_PARAMS), consistency=False,
                               temporal_window=1, memo=memo)
    mean = None
    if period_gate is not None:
        # Motion aliased in the K-average (a fan whose blades pass once per K sub-frames leaves
        # it exactly still): the successive-sub-frame flow averaged over one sampling period.
        # The high-TR video swims with the code's period (about 1 px per sub-frame at K = 16),
        # which that average cancels; steady motion stays.
        mean = box_in_time(vel, K)
        params["period_gate"] = tuple(period_gate)
    params["gate"] = (lo, hi)
    out = _GatedFlow(vel, conf, slow, use_slow, slow_speed, steps, mean, (lo, hi), period_gate, px)
    for_each(out.one, len(vel))
    if vel.shape[1:3] == video.shape[1:]:  # at full size already: held as it is
        return FlowField(vel, conf, params, perf_counter() - t0)
    return ScaledFlow(vel, conf, video.shape[1:], params, perf_counter() - t0)


class _GatedFlow:
    """:func:`gated_flow`'s gate, a sub-frame at a time (:meth:`one`): each sub-frame's gated velocity written over
    its successive-sub-frame one at the flow's own scale (:class:`~flexvox_core.flow.estimate.ScaledFlow` makes the
    full-size planes when they are read), in one compiled pass over its planes
    (:func:`~flexvox_core.motion.gated_flow_kernel.gate_plane`): the same values as the whole-volume numpy form,
    without a dozen volumes at flow size (fresh memory is dear: at 640x480 they would cost about a second of page
    faults, docs/benchmarks.md)."""

    def __init__(self, successive, conf, slow, use_slow, slow_speed, steps, mean, gate, period_gate, px):
        self.successive, self.conf, self.slow = successive, conf, slow
        self.use_slow, self.steps, self.mean = use_slow, steps, mean
        f32 = np.float32
        lo, hi = gate
        plo, phi = period_gate if period_gate is not None else (0.0, 1.0)
        # Python numbers as numpy reads them beside float32 arrays: rounded to float32 first.
        self.numbers = (f32(px), bool(use_slow), f32(0.0 if slow_speed is None else slow_speed), f32(lo),
                        f32(hi - lo), f32(plo), f32(phi - plo))
        h, w = conf.shape[1:]
        self.max_magnitude = f32(0.5 * max(h, w))
        self.step_ratio = np.array([w / steps.shape[2], h / steps.shape[1]], np.float32)

    def one(self, t: int) -> None:
        """Gate sub-frame ``t``: its plane of ``successive`` (read by no other sub-frame) becomes the gated,
        sanitised velocity, and its confidence is sanitised."""
        vel, conf = self.successive[t], self.conf[t]
        h, w = conf.shape
        disp = self.slow.disp
        j0, j1, a = blend(self.slow.centres, t)
        steps = np.asarray(cv2.resize(scaled_vectors(self.steps[t], self.step_ratio), (w, h),
                                      interpolation=cv2.INTER_LINEAR), np.float32)  # float32 already: no copy
        mean = self.mean[t] if self.mean is not None else vel
        px, use_slow, slow_speed, lo, width, plo, pwidth = self.numbers
        if gate_plane(vel, conf, disp[j0], disp[j1], np.float64(1 - a), np.float64(a), j0 != j1, steps, mean,
                      self.mean is not None, px, use_slow, slow_speed, lo, width, plo, pwidth, self.max_magnitude):
            np.clip(conf, 0, 1, out=conf)  # as sanitize_flow: a NaN stays
