"""The motion-aware reconstruction of the seed's Section 4, with flexvox's safeguards.

1. **High-TR reconstruction**: normalized convolution with ``diag(1, 1, 0.05)`` (the seed's
   Step 1), so fast motion is not blurred away before flow is measured.
2. **Flow** between successive sub-frames of it (:func:`flexvox_core.flow.estimate_flow`).
   A high-TR reconstruction of a still scene "swims": each sub-frame interpolates a
   different set of pixels, so flow sees spurious motion (0.17 px per sub-frame median on
   the still built-in scene, enough to drift 2.7 px over a 16-slot reach). flexvox gates the
   flow with a **motion detector that cannot swim**: flow of the K-sub-frame moving average
   of the same video, in which every sampling phase appears once, so a still region is
   exactly still. Velocity = flow × ramp(detected speed; ``gate`` thresholds). For **slow
   motion** the velocity is the moving average's flow across K sub-frames (K times the
   displacement for the same flow error: on a 0.16 px/sub-frame pan the error falls from
   0.31 to 0.015 px per sub-frame), see :func:`gated_flow`.
3. **Motion-driven diffusion**: the tensor field of Eq. 4 (``c``), applied by the
   motion-compensated normalized convolution (:func:`~flexvox_core.motion.mcnc.motion_compensated_nc`)
   and optionally refined by the monotone variable-tensor diffusion
   (:func:`~flexvox_core.motion.vardiff.variable_tensor_diffusion`).
4. Optionally further **passes**: flow re-estimated on the motion-aware result.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from functools import cached_property
from time import perf_counter as _now

import cv2
import numpy as np

from flexvox_core.flow import FlowField
from flexvox_core.flow.backends import backend_params, make_backend
from flexvox_core.flow.baseline import KAverageFlow, default_stride, kaverage
from flexvox_core.flow.estimate import check_video, downscale, sanitize_flow, successive_flow, to_full_size
from flexvox_core.forward import sample_mask, sparse_volume
from flexvox_core.gaps import as_missing, bridge, bridge_flow, captured, interpolated_subframes
from flexvox_core.motion import local_choice as lc
from flexvox_core.motion import noise_aware as na
from flexvox_core.motion.longreach import long_reach_nc
from flexvox_core.motion.mcnc import motion_compensated_nc
from flexvox_core.motion.tensors import DEFAULT_C, check_c, resolution_map
from flexvox_core.motion.vardiff import explicit_steps, variable_tensor_diffusion
from flexvox_core.numbers import checked_number, number_pair
from flexvox_core.reconstruct._common import check_frames, check_identity_code
from flexvox_core.reconstruct.diffusion import MAX_EXPLICIT_STEPS, diffuse, diffuse_where, sigmas
from flexvox_core.reconstruct.oriented_nc import oriented_nc
from flexvox_core.threads import for_each

_logger = logging.getLogger(__name__)

STEP1_TENSOR = (1.0, 1.0, 0.05)
STEP1_TIME = 2.0
DEFAULT_TIME = 5.0
FLOW_SIDE = 160
"""Flow runs with the shorter image side at about this many pixels (:func:`auto_flow_scale`)."""
DIS_PARAMS = {"variational_iterations": 2}
"""Motion-aware's DIS flow (every pair it measures): 2 iterations of the variational refinement instead of
OpenCV's 5. The refinement smooths the flow across the high-TR video's motion edges; measured on
`flexvox bench`'s captures (96×128, seed 0): the built-in scenes at K = 16 25.21 → 25.36 dB (fan +0.17, drummer
+0.38, balls −0.04, pan −0.04, the still scene 43.3 → 42.3), K = 8 +0.01, Runner +0.01, Drop +0.02; the margin
over the best fixed tensor on fan, balls and drummer +2.01 → +2.21 dB (+2.01 → +2.23 with noise; seed 1: +2.12 →
+2.33); 1 iteration +2.32 but K = 8 −0.05 and the still scenes −1.4. At 640×480 balls −0.18, drummer +0.12, fan
+0.18, pan −0.06 dB, and each pair's flow about a fifth faster."""
STILL_TENSOR = (0.0, 0.0, 1.0)
"""Tensor of the still voxels' normalized convolution (with time K²/8: a Gaussian of K/2 sub-frames)."""
STILL_SPEED = 0.02
"""Below this gated speed (px per sub-frame) a voxel is still: it takes its own pixel's samples
averaged in time (a Gaussian of standard deviation K/2 sub-frames: Eq. 4's tensor in the limit
c -> (0, 0, 1)), exact for a still scene and averaging its noise; no trajectory gather runs there."""
SLOW_REACH = 0.75
"""Reach of the slow voxels' range-weighted gather (:mod:`~flexvox_core.motion.longreach`), in
sampling periods (K sub-frames) each way; also its temporal standard deviation."""
LONG_REACH_SIGMA_S = 0.3
"""Spatial standard deviation (px) of the slow voxels' gather."""
LONG_REACH_RANGE = 0.1
"""Range-weight scale of the slow voxels' gather, as a fraction of the samples' range."""
SLOW_SPEED = 0.6
"""Below this speed (px per sub-frame) of the K-average's long-baseline flow, that flow is the velocity."""
REFINE_C = (0.95, 0.0, 0.0)
"""Tensor eigenvalues of the refinement: along each voxel's trajectory only. A still voxel then
diffuses in time alone, so a still scene stays exact; measured on `flexvox bench`'s groups against
Eq. 4's (0.95, 0.05, 0.05): 25.03 against 25.07 dB at K = 16, the same elsewhere."""
MAX_REFINE_TIME = MAX_EXPLICIT_STEPS / (2 * sum(REFINE_C))
"""The longest refinement: the explicit solver's step limit (``time · 2·Σc`` steps)."""
MAX_SLOW_REACH = 1000.0
"""The slow voxels' longest reach, in sampling periods (1000 camera frames each way: longer than any clip
previews or batches hold, and short of integer overflow)."""
DEFAULT_GATE = (0.03, 0.15)
PERIOD_GATE = (0.9, 1.5)
"""Second gate ramp (px per sub-frame) on the successive-sub-frame flow averaged over K sub-frames."""
"""Gate ramp in pixels per sub-frame: below 0.03 still, above 0.15 trusted as moving."""


@dataclass
class MotionAwareResult:
    """Video and everything a person may want to look at.

    Attributes
    ----------
    video : ndarray (S, H, W) float32 in the samples' range
    high_tr : ndarray (S, H, W) float32, the Step-1 reconstruction
    flow : FlowField
        The gated flow that drove the tensors (confidence from the high-TR flow).
    K : int
        Slots of the code.
    c : (c1, c2, c3)
        Eigenvalues of Eq. 4 used.
    seconds : dict
        Time of each step: ``high_tr``, ``flow``, ``diffusion``.
    tr, sr : ndarray (S, H, W) float32
        Effective resolution chosen per voxel (:func:`~flexvox_core.motion.tensors.resolution_map`),
        computed from ``flow`` when first asked for (two more volumes a plain reconstruction
        does not need).
    """

    video: np.ndarray
    high_tr: np.ndarray
    flow: FlowField
    K: int
    c: tuple = DEFAULT_C
    seconds: dict = field(default_factory=dict)

    @cached_property
    def _resolution(self) -> tuple[np.ndarray, np.ndarray]:
        return resolution_map(self.flow.flow, self.K, self.c)

    @property
    def tr(self) -> np.ndarray:
        return self._resolution[0]

    @property
    def sr(self) -> np.ndarray:
        return self._resolution[1]


def auto_flow_scale(height: int, width: int) -> float:
    """Flow scale with the shorter side at :data:`FLOW_SIDE` px (at most 1: never upsampled).

    Measured (accuracy benchmark, and ``bench/bench_motion_throughput.py`` at 640×480): at
    96×128 full-size flow beat half-size by 0.3 dB (K = 16) and 0.6 dB (K = 8); on the 256×256
    SCI clips 0.625 beat 0.5 by 0.2 dB; at 640×480 a third of the size scored within
    −0.2/+0.3 dB of half size, and the clip's flow took 3.4 instead of 6.7 s.
    """
    return min(1.0, FLOW_SIDE / max(1, min(height, width)))


def gated_flow(video: np.ndarray, K: int, *, backend: str, gate=DEFAULT_GATE, scale: float = 0.5,
               consistency: bool = False, slow_speed: float | None = SLOW_SPEED,
               period_gate=PERIOD_GATE, memo=None) -> FlowField:
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
    t0 = _now()
    # Everything at the flow's own (small) resolution; resized once at the end.
    small = downscale(video, scale)
    vel, conf = successive_flow(small, flow_fn, consistency=consistency, temporal_window=1, memo=memo)
    px = video.shape[2] / vel.shape[2]  # full-size pixels per flow pixel: thresholds are in full-size ones
    params = {**backend_params(flow_fn), "scale": scale, "consistency": consistency, "temporal_window": 1}
    if not (K > 1 and video.shape[0] > 1):
        vel, conf = to_full_size(vel, conf, video.shape[1:])
        return FlowField(vel, conf, params, _now() - t0)
    average = kaverage(small, K)
    slow = KAverageFlow(small, K, flow_fn, default_stride(K), average=average, memo=memo)
    use_slow = slow_speed is not None and slow.span == K  # shorter: the averages overlap, too blurred
    if use_slow:
        params["slow_speed"] = slow_speed
    # Fast motion is smeared in the K-average and can escape a flow across K of its
    # sub-frames: the detector also takes flow between its successive sub-frames (at half size).
    steps, _ = successive_flow(downscale(average, 0.5), make_backend("dis", **DIS_PARAMS), consistency=False,
                               temporal_window=1, memo=memo)
    mean = None
    if period_gate is not None:
        # Motion aliased in the K-average (a fan whose blades pass once per K sub-frames leaves
        # it exactly still): the successive-sub-frame flow averaged over one sampling period.
        # The high-TR video swims with the code's period (about 1 px per sub-frame at K = 16),
        # which that average cancels; steady motion stays.
        from scipy.ndimage import uniform_filter1d

        mean = uniform_filter1d(vel, K, axis=0, mode="nearest")
        params["period_gate"] = tuple(period_gate)
    params["gate"] = (lo, hi)
    out = _GatedFlow(vel, conf, slow, use_slow, slow_speed, steps, mean, (lo, hi), period_gate, px,
                     video.shape[1:])
    for_each(out.one, len(vel))
    return FlowField(out.flow, out.full_confidence(), params, _now() - t0)


class _GatedFlow:
    """:func:`gated_flow`'s gate and resize, a sub-frame at a time (:meth:`one`): every step
    element-wise on small planes that stay in cache, each sub-frame's gated velocity resized
    straight into the full-size flow. The same operations, in the same order, as on whole
    volumes (the same values), without the dozen volumes at flow size those made (fresh
    memory is dear: 0.8-1.4 s of the 640x480 clip's flow went to them)."""

    def __init__(self, successive, conf, slow, use_slow, slow_speed, steps, mean, gate, period_gate, px, size):
        self.successive, self.conf, self.slow = successive, conf, slow
        self.use_slow, self.slow_speed, self.steps, self.mean = use_slow, slow_speed, steps, mean
        self.gate, self.period_gate, self.px = gate, period_gate, np.float32(px)
        S, h, w = conf.shape
        H, W = size
        self.size = size
        self.flow = np.empty((S, H, W, 2), np.float32)
        self.max_magnitude = 0.5 * max(h, w)
        self.ratio = np.array([W / w, H / h], np.float32)
        self.step_ratio = np.array([w / steps.shape[2], h / steps.shape[1]], np.float32)

    def one(self, t: int) -> None:
        lo, hi = self.gate
        px = self.px
        vel = self.successive[t]
        slow = self.slow.at(t, np.empty_like(vel))
        speed = np.hypot(slow[..., 0], slow[..., 1]) * px
        if self.use_slow:
            slow_speed = self.slow_speed
            use = (speed < slow_speed) & (np.hypot(vel[..., 0], vel[..., 1]) * px < 2 * slow_speed)
            vel = np.where(use[..., None], slow, vel)
        else:
            vel = vel.copy()
        h, w = vel.shape[:2]
        steps = cv2.resize(self.steps[t] * self.step_ratio, (w, h), interpolation=cv2.INTER_LINEAR)
        speed = np.maximum(speed, np.hypot(steps[..., 0], steps[..., 1]) * px)
        ramp = np.clip((speed - lo) / (hi - lo), 0, 1).astype(np.float32)
        if self.mean is not None:
            plo, phi = self.period_gate
            mean = self.mean[t]
            mean_speed = np.hypot(mean[..., 0], mean[..., 1]) * px
            ramp = np.maximum(ramp, np.clip((mean_speed - plo) / (phi - plo), 0, 1))
        vel *= ramp[..., None]
        # to_full_size's sanitising (element-wise, so the same a plane at a time), then its resize.
        vel, self.conf[t] = sanitize_flow(vel, self.conf[t], max_magnitude=self.max_magnitude)
        if (h, w) == self.size:
            self.flow[t] = vel
        else:
            cv2.resize(vel * self.ratio, self.size[::-1], dst=self.flow[t], interpolation=cv2.INTER_LINEAR)

    def full_confidence(self) -> np.ndarray:
        """The confidence resized as :func:`~flexvox_core.flow.estimate.to_full_size` does."""
        conf = self.conf
        S, h, w = conf.shape
        H, W = self.size
        if (h, w) == (H, W):
            return conf
        if conf.min() == 1:  # the usual case without a round-trip check: a read-only view of 1
            return np.broadcast_to(np.float32(1), (S, H, W))
        full = np.empty((S, H, W), np.float32)
        for i, c in enumerate(conf):
            cv2.resize(c, (W, H), dst=full[i], interpolation=cv2.INTER_LINEAR)
        return full


def _speed_classes(flow: np.ndarray, still_speed: float | None, slow_speed: float | None):
    """Bool volumes ``still`` (speed < ``still_speed``) and ``slow`` (not still, speed < ``slow_speed``),
    a sub-frame at a time (no full-volume speed array); None: no such voxels."""
    S, H, W = flow.shape[:3]
    still = np.zeros((S, H, W), bool)
    slow = np.zeros((S, H, W), bool)

    def one(t):  # a sub-frame at a time, on every core
        speed = cv2.magnitude(flow[t, ..., 0], flow[t, ..., 1])
        if still_speed is not None:
            np.less(speed, still_speed, out=still[t])
        if slow_speed is not None:
            np.less(speed, slow_speed, out=slow[t])
            slow[t] &= ~still[t]

    for_each(one, S)
    return still, slow


def motion_aware(
    frames,
    code,
    *,
    flow: str = "dis",
    passes: int = 1,
    time: float = DEFAULT_TIME,
    c=DEFAULT_C,
    refine_time: float | None = None,
    gate=DEFAULT_GATE,
    flow_scale: float | None = None,
    still_speed: float | None = STILL_SPEED,
    flow_consistency: bool = False,
    slow_speed: float | None = SLOW_SPEED,
    slow_reach: float = SLOW_REACH,
    value_range: tuple[float, float] | None = None,
    missing=None,
    local_choice: bool = True,
    noise_aware: bool = True,
) -> MotionAwareResult:
    """Motion-aware reconstruction of an identity-code capture.

    Parameters
    ----------
    frames : ndarray (F, H, W)
    code : ndarray (m, n, K), identity code
    flow : {"dis", "deepflow", "farneback", "tvl1"}
    passes : int
        1: flow from the high-TR reconstruction; 2+: flow re-estimated from the previous pass.
    time : float
        Diffusion time n of the motion-compensated normalized convolution (the accuracy knob).
    c : (c1, c2, c3)
        Eigenvalues of Eq. 4 (default the seed's 0.95, 0.05, 0.05).
    refine_time : float or None
        Time of the variable-tensor diffusion along the trajectories after the gather
        (:func:`~flexvox_core.motion.vardiff.variable_tensor_diffusion` with :data:`REFINE_C`; 0: none).
        None (default): (K/16)² — 1 at K = 16, 0.25 at K = 8: a diffusion time grows with the square of the
        distance to cover, here the sampling period. Measured on `flexvox bench`'s groups
        (``docs/reconstruction.md``): +0.4 dB on the built-in scenes at K = 16; at K = 8 0.25 beat the earlier
        K/16 = 0.5 by 0.11 dB (0.08 and 0.04 with photon noise), the SCI clips within 0.02 dB; a time of 1 at
        K = 8 lost 0.36 dB. Only K = 8 and 16 were measured.
    gate : (low, high)
        Motion-detector ramp, pixels per sub-frame.
    flow_scale : float or None
        Resolution at which flow is computed, in (0, 1]; None (default): :func:`auto_flow_scale`.
    still_speed : float or None
        Voxels slower than this take their own samples interpolated in time (see
        :data:`STILL_SPEED`); None gathers along trajectories everywhere.
    flow_consistency : bool
        Also compute backward flow for a forward–backward confidence map. Off by default: on
        the built-in scenes it changed PSNR by at most 0.06 dB and cost 10–40 % of the flow time.
    slow_speed : float or None
        Below this speed (px per sub-frame) the velocity is the K-average's long-baseline flow
        (see :func:`gated_flow`); None: successive-sub-frame flow everywhere (and no slow voxels).
    slow_reach : float
        Voxels that move, slower than ``slow_speed``, take a range-weighted gather reaching this
        many sampling periods (K sub-frames) each way along their trajectory
        (:func:`~flexvox_core.motion.longreach.long_reach_nc`); 0: the short gather of the fast
        voxels. The accuracy knob that costs most time where the whole picture drifts slowly.
    value_range : (lo, hi) or None
        Range of the whole recording's samples: it scales the slow voxels' range weight and
        bounds the result. None: this clip's own range. A run in time chunks passes the whole
        recording's, so that the result does not depend on the chunking; it must contain
        every value of ``frames`` (of the frames not missing).
    missing : ndarray (F,) bool, optional
        Frames the camera dropped (:mod:`flexvox_core.gaps`): they hold no samples. The flow is
        bridged linearly across each gap (and half a sampling period on each side, whose flow
        was measured across it), and the gap's sub-frames are filled from both sides along it
        (:func:`~flexvox_core.gaps.bridge`).
    local_choice : bool
        Where oriented normalized convolution (:mod:`~flexvox_core.reconstruct.oriented_nc`, its kernel
        following the high-TR reconstruction's edges) predicts the samples better than the trajectory gather
        (each sample estimated from the others, :mod:`~flexvox_core.motion.local_choice`), blend it in at
        the gathered voxels. On by default: on ``flexvox bench`` Drop +2.0 dB and Runner +0.3 against the
        gather alone, the built-in scenes +0.1 (K = 16) and +0.3 dB (K = 8); see the module for its bias on
        single-frame captures of still subjects.
    noise_aware : bool
        Estimate the capture's noise from its still pixels' successive samples and let the gather smooth
        across space where the picture is flat compared with it (:mod:`~flexvox_core.motion.noise_aware`).
        A noiseless or single-frame capture is unchanged. On by default: +0.12 dB on the noisy built-in
        moving scenes at K = 16.
    """
    f = check_frames(frames)
    code = check_identity_code(code)
    options = MotionOptions(flow=flow, passes=passes, time=time, c=c, refine_time=refine_time, gate=gate,
                            flow_scale=flow_scale, still_speed=still_speed, flow_consistency=flow_consistency,
                            slow_speed=slow_speed, slow_reach=slow_reach, local_choice=local_choice,
                            noise_aware=noise_aware)
    missing = as_missing(missing, f.shape[0])
    lo, hi = sample_bounds(f, missing, value_range)
    return run_window(f, code, options, (lo, hi), missing=missing)


@dataclass(frozen=True)
class MotionOptions:
    """The options of :func:`motion_aware` (see there), checked once."""

    flow: str = "dis"
    passes: int = 1
    time: float = DEFAULT_TIME
    c: tuple = DEFAULT_C
    refine_time: float | None = None
    gate: tuple = DEFAULT_GATE
    flow_scale: float | None = None
    still_speed: float | None = STILL_SPEED
    flow_consistency: bool = False
    slow_speed: float | None = SLOW_SPEED
    slow_reach: float = SLOW_REACH
    local_choice: bool = True
    noise_aware: bool = True

    def __post_init__(self):
        object.__setattr__(self, "c", check_c(self.c))
        for name in ("local_choice", "noise_aware"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"`{name}` must be True or False; got {getattr(self, name)!r}")
        if not isinstance(self.flow_consistency, bool | np.bool_):
            raise ValueError(f"`flow_consistency` must be True or False; got {self.flow_consistency!r}")
        make_backend(self.flow)  # an unknown backend is refused here, naming the backends
        passes = self.passes
        if isinstance(passes, bool) or not isinstance(passes, int) or passes < 1:
            raise ValueError(f"`passes` must be a whole number >= 1; got {passes!r}")
        checked_number("time", self.time, "a finite number > 0", lambda v: v > 0)
        sigmas((self.c[2], self.c[1], self.c[0]), self.time)  # the guides' blur: within MAX_SIGMA
        checked_number("slow_reach", self.slow_reach, f"a number from 0 to {MAX_SLOW_REACH:g} (sampling periods)",
                       lambda v: 0 <= v <= MAX_SLOW_REACH)
        for name, rule, ok in (("refine_time", "a finite number >= 0", lambda v: v >= 0),
                               ("flow_scale", "in (0, 1] or None", lambda v: 0 < v <= 1),
                               ("still_speed", "a number >= 0 (px per sub-frame) or None", lambda v: v >= 0),
                               ("slow_speed", "a number >= 0 (px per sub-frame) or None", lambda v: v >= 0)):
            if getattr(self, name) is not None:
                checked_number(name, getattr(self, name), rule, ok)
        if self.refine_time is not None and float(self.refine_time) > MAX_REFINE_TIME:
            raise ValueError(f"`refine_time` {self.refine_time!r} takes more than {MAX_EXPLICIT_STEPS} explicit steps "
                             f"(time · 2·Σc, Σc = {sum(REFINE_C):g}); take a time of at most {MAX_REFINE_TIME:.0f}")
        try:
            lo, hi = (float(v) for v in self.gate)
        except (TypeError, ValueError):
            lo, hi = math.nan, math.nan
        if not 0 <= lo < hi:
            raise ValueError(f"`gate` must be two thresholds 0 <= low < high (px per sub-frame); got {self.gate!r}")

    def refine(self, K: int) -> float:
        """The refinement time at K slots (None: (K/16)²)."""
        return (K / 16) ** 2 if self.refine_time is None else float(self.refine_time)

    def refine_reach(self, K: int) -> int:
        """Sub-frames the refinement reaches each way (one per explicit step)."""
        t = self.refine(K)
        return explicit_steps(t, REFINE_C) if t > 0 else 0

    def overlap(self, K: int) -> int:
        """Camera frames of context on each side after which a result no longer depends on more
        (a chunked run with this overlap equals the whole one)."""
        # High-TR nc, the K-average gates, flow smoothing; still voxels: 4 σ = 2 periods; slow voxels:
        # their reach in periods (the default 0.75 fits in 3) and the flow and guide it reads there.
        frames = max(3, math.ceil(self.slow_reach) + 2)
        # The refinement's explicit steps reach one sub-frame each.
        return frames + math.ceil(self.refine_reach(K) / K)


def sample_bounds(frames: np.ndarray, missing, value_range) -> tuple[float, float]:
    """The samples' range: ``value_range`` checked to contain the captured frames' values, or theirs."""
    samples = captured(frames, missing)
    lo, hi = float(samples.min()), float(samples.max())
    if value_range is None:
        return lo, hi
    r_lo, r_hi = number_pair("value_range", value_range, "two numbers (lo, hi) or None")
    if not (np.isfinite(r_lo) and np.isfinite(r_hi) and r_lo <= lo and hi <= r_hi):
        raise ValueError(f"`value_range` {value_range!r} must be finite and contain the frames' values "
                         f"[{lo:g}, {hi:g}]")
    return r_lo, r_hi


def _guide(f, code, tensor, time, missing, rows) -> np.ndarray:
    """The fixed-tensor normalized convolution of the whole window; with ``rows`` (s0, s1) only
    those sub-frames are computed (the rest of the volume is 0: nothing reads it)."""
    if rows is None:
        return diffuse(f, code, tensor=tensor, time=time, missing=missing)
    out = np.zeros((f.shape[0] * code.shape[2], *f.shape[1:]), np.float32)
    out[rows[0]:rows[1]] = diffuse(f, code, tensor=tensor, time=time, missing=missing, subframes=rows)
    return out


def run_window(f: np.ndarray, code: np.ndarray, options: MotionOptions, bounds: tuple[float, float], *,
               missing=None, keep: tuple[int, int] | None = None, memo=None) -> MotionAwareResult:
    """The motion-aware pipeline on checked ``frames`` (F, H, W) float32 and identity ``code``.

    ``bounds``: the samples' range (:func:`sample_bounds`). ``keep`` = (s0, s1): only these
    sub-frames are wanted (a streaming run's window, :mod:`~flexvox_core.motion.streaming`): the
    trajectory gathers and the refinement run over them (and the refinement's reach around them)
    alone, and the result's ``video`` holds them alone — the same values as the whole run's (with
    a second pass, or dropped frames in the window, everything is gathered and then cut). Everything
    else (high-TR, flow, the fixed-tensor guides) is computed over the whole window.
    ``memo``: a :class:`~flexvox_core.flow.memo.FlowMemo` for the flow.
    """
    lo, hi = bounds
    K = code.shape[2]
    S = f.shape[0] * K
    o = options
    c = o.c
    refine_time = o.refine(K)
    s0, s1 = (0, S) if keep is None else (max(0, int(keep[0])), min(S, int(keep[1])))
    if not s0 < s1:
        raise ValueError(f"`keep` must be a non-empty range of the window's {S} sub-frames; got {keep!r}")
    # The gathers run over the kept sub-frames and as far around them as the refinement reads.
    g0, g1 = max(0, s0 - o.refine_reach(K)), min(S, s1 + o.refine_reach(K))
    skip = None
    # A second pass's flow, and the bridging of a dropped frame, read the whole window's result: then the whole
    # window is gathered and refined, and cut at the end.
    if (g0, g1) != (0, S) and o.passes == 1 and missing is None:
        skip = np.ones(S, bool)
        skip[g0:g1] = False
    else:
        g0, g1 = 0, S
    flow_scale = auto_flow_scale(*f.shape[1:]) if o.flow_scale is None else o.flow_scale
    seconds = {"high_tr": 0.0, "flow": 0.0, "diffusion": 0.0}
    t0 = _now()
    high_tr = diffuse(f, code, tensor=STEP1_TENSOR, time=STEP1_TIME, missing=missing)
    seconds["high_tr"] = _now() - t0
    sparse = sparse_volume(np.asarray(f, np.float32), code)
    mask = sample_mask(sparse.shape, code)
    if missing is not None:  # a dropped frame's sub-frames hold no samples
        gap = interpolated_subframes(missing, K)
        mask[gap] = False
        sparse[gap] = 0
    current = high_tr
    field_ = None
    fixed = still_value = None
    for pass_ in range(o.passes):
        t0 = _now()
        field_ = gated_flow(current, K, backend=o.flow, gate=o.gate, scale=flow_scale,
                            consistency=o.flow_consistency, slow_speed=o.slow_speed, memo=memo)
        if missing is not None:
            bridge_flow(field_.flow, missing, K, margin=K // 2)
        seconds["flow"] += _now() - t0
        t0 = _now()
        slow_class = o.slow_reach > 0 and f.shape[0] > 1
        still, slow = _speed_classes(field_.flow, o.still_speed, o.slow_speed if slow_class else None)
        if skip is not None:  # outside the kept range nothing is gathered
            slow[skip] = False
        if fixed is None:  # the fixed-tensor result: the guide of the slow voxels, and where not still
            fixed = _guide(f, code, (c[2], c[1], c[0]), o.time, missing, None if skip is None else (g0, g1))
        base = fixed
        if still.any():
            # Still voxels: Eq. 4's tensor in the limit c -> (0, 0, 1), the pixel's own samples
            # averaged in time (a Gaussian of half a sampling period: noise averages out).
            if o.passes == 1 and skip is None:
                # `fixed` serves this pass alone: the still voxels' values go straight into it (no volume of them).
                diffuse_where(f, code, base, still, tensor=STILL_TENSOR, time=K * K / 8, missing=missing)
            else:
                if still_value is None:
                    still_value = _guide(f, code, STILL_TENSOR, K * K / 8, missing, None if skip is None else (g0, g1))
                base = fixed.copy() if o.passes > 1 else fixed  # `fixed` serves every pass
                np.copyto(base, still_value, where=still)
        not_gathered = still | slow
        if skip is not None:
            not_gathered[skip] = True
        last = pass_ + 1 == o.passes
        wide = None
        if o.noise_aware and f.shape[0] > 1:
            noise = na.frame_noise(f, still, mask, K)
            if noise.any():
                wide = na.SmoothWeights(current, np.repeat(noise, K))
                _logger.info("motion-aware: noise %.4g (median of the frames'), smoothing where flatter",
                             float(np.median(noise)))
        # The trajectory gather's leave-one-out estimate of every sample it reaches, for the local choice.
        loo = np.full(f.shape, np.nan, np.float32) if o.local_choice and last else None
        # The gather writes into `base` when no later pass reads it (one volume less).
        into = base if o.passes == 1 or base is not fixed else None
        video = motion_compensated_nc(sparse, mask, field_.flow, c=c, time=o.time, fallback=high_tr,
                                      still=not_gathered, still_value=base, loo=loo, wide=wide,
                                      wide_sigma=na.wide_sigma(K), out=into)
        into = None
        gathered = ~not_gathered if loo is not None else None
        del base, not_gathered
        if last:
            fixed = still_value = None  # not needed again: free them before the local choice's volume
        if slow.any():
            reach = max(1, round(o.slow_reach * K))
            long_reach_nc(sparse, mask, field_.flow, video, slow, reach=reach, sigma_t=reach,
                          sigma_s=LONG_REACH_SIGMA_S, h=LONG_REACH_RANGE * max(hi - lo, 1e-12), out=video)
            np.copyto(video, sparse, where=mask)
        # After the last pass's gathers the sample volume is dead: the refinement and the local choice
        # write their working volumes into it instead of fresh memory (0.3-0.7 s per 295 MB here).
        spare = sparse if last else None
        if refine_time > 0:
            # The slow voxels read their trajectory neighbours by clipped Catmull-Rom: a bilinear read a fraction
            # of a pixel off is a blur, which took the texture their long-reach gather kept (the pan at K = 16
            # lost 0.40 dB against the unrefined result with bilinear reads, 0.05 with these, by MSE on
            # `flexvox bench`; the static scene gains 0.5 dB).
            variable_tensor_diffusion(video[g0:g1], mask[g0:g1], field_.flow[g0:g1], c=REFINE_C, time=refine_time,
                                      out=video[g0:g1], scratch=None if spare is None else spare[g0:g1],
                                      sharp=slow[g0:g1])
        if loo is not None and np.isfinite(loo).any():
            # Where nc with edge-following kernels predicts the samples better than the gather, it takes
            # over (local_choice); oriented by the high-TR reconstruction, at the gathered voxels alone.
            if not (o.slow_speed is not None and o.slow_speed >= lc.STILL_VOXEL_SPEED and slow_class):
                # Gathered voxels slower than that exist (with the slow class on, every gathered voxel is faster than
                # `slow_speed`): at them the pixel's own sample scores the gather (local_choice.still_voxel_loo).
                lc.still_voxel_loo(loo, video, f, gathered, mask, field_.flow, K)
            other, other_loo = oriented_nc(f, code, high_tr, where=gathered, fallback=video, missing=missing,
                                           out=spare)
            lc.blend(video, other, lc.local_weights(loo, other_loo, f), gathered, K)
            del other, other_loo, gathered
        if missing is not None:
            bridge(video, missing, K, flow=field_.flow)
        current = np.clip(video, lo, hi, out=video)
        seconds["diffusion"] += _now() - t0
    _logger.info("motion-aware: high-TR %.2f s, flow %.2f s, diffusion %.2f s",
                 seconds["high_tr"], seconds["flow"], seconds["diffusion"])
    video = current.astype(np.float32, copy=False)
    if (s0, s1) != (0, S):
        video = np.ascontiguousarray(video[s0:s1])
    return MotionAwareResult(video, high_tr, field_, K, c, seconds)
