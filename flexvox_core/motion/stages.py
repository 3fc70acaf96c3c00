r"""Motion-aware's pipeline as named stages, in the paper's order (its Section 4, with flexvox's safeguards).

=====================  ==========================================================================================
stage                  what it computes
=====================  ==========================================================================================
``high_tr``            normalized convolution with ``diag(1, 1, 0.05)``, n = 2 (the paper's Step 1): sharp in
                       time, so fast motion survives for the flow
``samples``            the samples' mask; a dropped frame's sub-frames hold none (no stage reads a sample volume: the
                       gathers read the frames and the code)
``gated_flow``         velocity of every voxel: the high-TR video's flow, gated by a motion detector that cannot
                       swim, slow motion measured over a long baseline (:mod:`~flexvox_core.motion.gated_flow`);
                       bridged across dropped frames; from here on the high-TR video is held in float16
                       (:data:`HIGH_TR_HELD`: its later readers take its values to float32 as they read them)
``speed_classes``      still voxels (speed < ``still_speed``) and slow ones (< ``slow_speed``)
``guides``             the fixed-tensor nc of Eq. 4's tensor at zero flow, with the still voxels' own values (their
                       pixel's samples averaged over a Gaussian of K/2 sub-frames) written in: the value of every
                       voxel no trajectory gather reaches
``noise``              the capture's noise from still pixels' successive samples, and the weight of the wide
                       spatial kernel per voxel (:mod:`~flexvox_core.motion.noise_aware`)
``trajectory_gather``  motion-compensated nc along each moving voxel's trajectory (Eq. 3 with Eq. 4's tensor,
                       :mod:`~flexvox_core.motion.mcnc`), and each sample's leave-one-out estimate
``long_reach``         the slow voxels' range-weighted gather over ``slow_reach`` sampling periods
                       (:mod:`~flexvox_core.motion.longreach`)
``refinement``         the monotone variable-tensor diffusion along the trajectories, the still voxels' at zero
                       flow (:mod:`~flexvox_core.motion.vardiff`)
``local_choice``       where oriented nc predicts the samples better, blend it in
                       (:mod:`~flexvox_core.motion.local_choice`)
``gaps``               a dropped frame's sub-frames filled from both sides along the flow (:mod:`flexvox_core.gaps`)
=====================  ==========================================================================================

Each stage is a method of an engine with the same name on the CPU (:class:`CpuStages`, here) and on the GPU
(:class:`flexvox_core.motion.gpu.engine.CudaStages`); :func:`run_stages` runs them in order, for each pass. An engine
holds one window's inputs (:class:`Window`) and its working memory: which volume a stage may write into, and
when one is no longer needed (fresh memory is dear on the CPU: at 640×480 × 240 sub-frames each new volume costs
0.1–0.5 s of page faults), so the stages themselves read as the algorithm.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from time import perf_counter
from typing import TYPE_CHECKING, Any, Protocol

import cv2
import numpy as np
import numpy.typing as npt

from flexvox_core.gaps import bridge, bridge_flow
from flexvox_core.motion import local_choice, longreach, noise_aware
from flexvox_core.motion.classes_kernel import classify_plane, speed_class
from flexvox_core.motion.gated_flow import gated_flow
from flexvox_core.motion.longreach import LongReachPlan
from flexvox_core.motion.mcnc import default_reach, trajectory_gather
from flexvox_core.motion.options import (
    GATHER_REACH,
    LONG_REACH_RANGE,
    LONG_REACH_SIGMA_S,
    REFINE_C,
    STEP1_TENSOR,
    STEP1_TIME,
    STILL_TENSOR,
    MotionOptions,
    auto_flow_scale,
)
from flexvox_core.motion.packed import PackedVolume
from flexvox_core.motion.result import MotionAwareResult
from flexvox_core.motion.sample_bands import SampleMask
from flexvox_core.motion.vardiff import refine_still_speed, variable_tensor_diffusion
from flexvox_core.planes import Bands, band
from flexvox_core.reconstruct.diffusion import diffuse, diffuse_where
from flexvox_core.reconstruct.oriented_nc import OrientedNc
from flexvox_core.threads import for_each, workers

if TYPE_CHECKING:
    from flexvox_core.flow.memo import FlowMemo

_logger = logging.getLogger(__name__)

STAGES = ("high_tr", "samples", "gated_flow", "speed_classes", "guides", "noise", "trajectory_gather", "long_reach",
          "refinement", "local_choice", "gaps")
"""The stages in the order they run (the keys of a result's ``stage_seconds``)."""

HIGH_TR_HELD: type[np.floating[Any]] = np.float16
"""The dtype the high-TR video is held in after the first pass's flow (which reads it in float32): its later
readers (the noise's weights, the trajectory gather's fallback, the local choice's guide, the result's ``high_tr``)
read these values, rounded to nearest even; half the memory (147 MB on a 1-s 640×480 clip) for a change of the
PSNR below 0.001 dB on the built-in scenes. ``np.float32`` keeps it as computed."""


@dataclass(frozen=True)
class Window:
    """One run's checked inputs and what follows from them.

    Attributes
    ----------
    frames : ndarray (F, H, W) float32
        Camera frames of an identity ``code`` (m, n, K).
    options : MotionOptions
    sample_range : (lo, hi)
        The samples' range (:func:`~flexvox_core.motion.options.check_sample_range`).
    missing : ndarray (F,) bool or None
        Dropped frames.
    keep : (s0, s1)
        The sub-frames wanted.
    gathered : (g0, g1)
        The sub-frames the trajectory gathers and the refinement run over: ``keep`` and the refinement's reach
        around it, or every sub-frame (a second pass or a dropped frame reads the whole window's result).
    skip : ndarray (S,) bool or None
        Sub-frames outside ``gathered`` (None: none).
    flow_scale : float
        The resolution of the flow.
    """

    frames: np.ndarray
    code: np.ndarray
    options: MotionOptions
    sample_range: tuple[float, float]
    missing: np.ndarray | None
    keep: tuple[int, int]
    gathered: tuple[int, int]
    skip: np.ndarray | None
    flow_scale: float

    @classmethod
    def plan(cls, frames: np.ndarray, code: np.ndarray, options: MotionOptions, sample_range: tuple[float, float], *,
             missing: np.ndarray | None = None, keep: tuple[int, int] | None = None) -> Window:
        """The window of ``frames`` (checked) with ``keep`` = (s0, s1) or None (every sub-frame)."""
        K = code.shape[2]
        S = frames.shape[0] * K
        s0, s1 = (0, S) if keep is None else (max(0, int(keep[0])), min(S, int(keep[1])))
        if not s0 < s1:
            raise ValueError(f"`keep` must be a non-empty range of the window's {S} sub-frames; got {keep!r}")
        reach = options.refine_reach(K)
        g0, g1 = max(0, s0 - reach), min(S, s1 + reach)
        skip = None
        if (g0, g1) != (0, S) and options.passes == 1 and missing is None:
            skip = np.ones(S, bool)
            skip[g0:g1] = False
        else:
            g0, g1 = 0, S
        scale = auto_flow_scale(*frames.shape[1:]) if options.flow_scale is None else options.flow_scale
        lo, hi = float(sample_range[0]), float(sample_range[1])
        return cls(frames, code, options, (lo, hi), missing, (s0, s1), (g0, g1), skip, scale)

    @property
    def K(self) -> int:
        K: int = self.code.shape[2]
        return K

    @property
    def S(self) -> int:
        S: int = self.frames.shape[0] * self.K
        return S

    @property
    def slow_class(self) -> bool:
        """Whether slow voxels take the long-reach gather (a reach and more than one frame)."""
        reach = self.options.slow_reach
        assert reach is not None, "MotionOptions resolves a slow_reach of None to SLOW_REACH"
        return reach > 0 and self.frames.shape[0] > 1

    @property
    def guide_rows(self) -> tuple[int, int] | None:
        """The sub-frames of the guides that are read (None: all)."""
        return None if self.skip is None else self.gathered

    @property
    def still_time(self) -> float:
        """Diffusion time of the still voxels' time average (a Gaussian of K/2 sub-frames)."""
        return self.K * self.K / 8

    @property
    def guide_tensor(self) -> tuple[float, float, float]:
        """The guides' fixed tensor: Eq. 4's at zero flow, ``diag(c3, c2, c1)`` in (x, y, t) order."""
        c = self.options.c
        return (c[2], c[1], c[0])

    @property
    def bridge_margin(self) -> int:
        """Sub-frames on each side of a gap whose flow is bridged too (measured across the gap): half a period."""
        return self.K // 2

    @property
    def long_reach(self) -> int:
        """The slow voxels' gather's reach each way (and its temporal standard deviation), in sub-frames."""
        reach = self.options.slow_reach
        assert reach is not None, "MotionOptions resolves a slow_reach of None to SLOW_REACH"
        return max(1, round(reach * self.K))

    @property
    def range_weight(self) -> float:
        """The slow voxels' gather's range-weight scale: :data:`LONG_REACH_RANGE` of the samples' range."""
        lo, hi = self.sample_range
        return LONG_REACH_RANGE * max(hi - lo, 1e-12)

    @property
    def long_reach_plan(self) -> LongReachPlan:
        """The slow voxels' gather as both engines run it: :attr:`long_reach` each way and as σ_t,
        :data:`LONG_REACH_SIGMA_S`, :attr:`range_weight`."""
        return LongReachPlan.of(self.S, reach=self.long_reach, sigma_t=self.long_reach, sigma_s=LONG_REACH_SIGMA_S,
                                h=self.range_weight)

    # The options as the engines read them: every field of MotionOptions reaches the engines through one of
    # these (OPTION_PLAN says which), never through ``options`` itself.

    @property
    def flow_backend(self) -> str:
        """The optical flow's backend (the GPU's is DIS: another runs on the CPU, :func:`cuda_unsupported`)."""
        return self.options.flow

    @property
    def flow_consistency(self) -> bool:
        """Whether the flow is checked forward against backward (the CPU's alone)."""
        return self.options.flow_consistency

    @property
    def flow_gate(self) -> tuple[float, float]:
        """The motion detector's gate (:func:`~flexvox_core.motion.gated_flow.gated_flow`)."""
        return self.options.gate

    @property
    def slow_speed(self) -> float | None:
        """Below this speed (px per sub-frame) the gated flow measures over a long baseline, and a voxel not still
        is slow (None: neither)."""
        return self.options.slow_speed

    @property
    def still_speed(self) -> float | None:
        """Below this speed a voxel is still (None: none is)."""
        return self.options.still_speed

    @property
    def slow_class_speed(self) -> float | None:
        """The speed classes' slow threshold: :attr:`slow_speed` where the slow voxels take the long reach
        (:attr:`slow_class`), else None."""
        return self.options.slow_speed if self.slow_class else None

    @property
    def passes(self) -> int:
        """How many times the stages from the gated flow on run (each later pass measures the flow on the last
        pass's result)."""
        return self.options.passes

    @property
    def gather_time(self) -> float:
        """Eq. 3's diffusion time n of the trajectory gather and of the guides."""
        return self.options.time

    @property
    def gather_c(self) -> tuple[float, float, float]:
        """Eq. 4's tensor eigenvalues (c1, c2, c3) of the trajectory gather."""
        return self.options.c

    @property
    def refine_time(self) -> float:
        """The refinement's diffusion time at this window's K (0: no refinement)."""
        return self.options.refine(self.K)

    @property
    def leave_one_out(self) -> bool:
        """Whether the last pass's gather gives each sample's leave-one-out estimate, for the local choice."""
        return self.options.local_choice

    @property
    def noise_aware(self) -> bool:
        """Whether the gather mixes in the wide kernel where the picture is flat against the capture's noise."""
        return self.options.noise_aware

    @property
    def sampling_period(self) -> int:
        """Sub-frames between a pixel's samples: S over the frames that hold samples (an identity code samples each
        pixel once a frame; S when none does)."""
        present = self.frames.shape[0] - (0 if self.missing is None else int(np.count_nonzero(self.missing)))
        return self.S // present if present else self.S

    @property
    def gather_reach(self) -> int:
        """The trajectory gather's largest offset |d| in sub-frames: :data:`~flexvox_core.motion.options.GATHER_REACH`
        standard deviations of its trajectory Gaussian at zero flow, ⌈1.25 √(2 n c1)⌉ (n :attr:`gather_time`, c1 of
        :attr:`gather_c`), within :func:`~flexvox_core.motion.mcnc.default_reach` (of :attr:`sampling_period`;
        at most S − 1)."""
        time, c1 = self.gather_time, self.gather_c[0]
        return min(default_reach(time, c1, self.sampling_period, self.S),
                   math.ceil(GATHER_REACH * math.sqrt(2 * time * c1)))

    @property
    def scores_still_voxels(self) -> bool:
        """Whether the local choice scores the gather at gathered voxels slower than
        :data:`~flexvox_core.motion.local_choice.STILL_VOXEL_SPEED` by the pixel's own sample
        (:func:`~flexvox_core.motion.local_choice.still_voxel_loo`): such voxels exist unless the slow class takes
        every voxel below a ``slow_speed`` at least that speed."""
        s = self.slow_speed
        return not (s is not None and s >= local_choice.STILL_VOXEL_SPEED and self.slow_class)


OPTION_PLAN: dict[str, tuple[str, ...]] = {
    "flow": ("flow_backend",),
    "passes": ("passes",),
    "time": ("gather_time", "gather_reach"),
    "c": ("gather_c", "guide_tensor", "gather_reach"),
    "refine_time": ("refine_time", "gathered"),
    "gate": ("flow_gate",),
    "flow_scale": ("flow_scale",),
    "still_speed": ("still_speed",),
    "flow_consistency": ("flow_consistency",),
    "slow_speed": ("slow_speed", "slow_class_speed", "scores_still_voxels"),
    "slow_reach": ("slow_class", "long_reach", "long_reach_plan"),
    "local_choice": ("leave_one_out",),
    "noise_aware": ("noise_aware",),
}
"""Each field of :class:`~flexvox_core.motion.options.MotionOptions` and the :class:`Window` members that carry it
to the engines (a test checks that every field has one, and a CPU/GPU parity case)."""


def cuda_unsupported(options: MotionOptions) -> str | None:
    """Why :class:`~flexvox_core.motion.gpu.engine.CudaStages` cannot run ``options`` as the CPU does (None: it can).

    The GPU's optical flow is DIS alone (:mod:`flexvox_core.gpu.dis`) and has no backward flow, so another
    ``flow`` backend or ``flow_consistency`` runs on the CPU; the reason says so, and reaches the result's
    ``device_note`` (and the command line's ``device:`` line)."""
    why = []
    if options.flow != "dis":
        why.append(f"flow={options.flow!r} runs on the CPU (the GPU's optical flow is DIS)")
    if options.flow_consistency:
        why.append("flow_consistency runs on the CPU (the GPU's DIS has no backward flow)")
    return "; ".join(why) or None


class StageTimes:
    """Seconds spent in each stage (summed over passes); ``sync`` is called before each clock reading (a GPU
    engine waits for its queued kernels there)."""

    def __init__(self, sync: Callable[[], None] | None = None) -> None:
        self.seconds: dict[str, float] = {}
        self._sync: Callable[[], None] = sync or (lambda: None)

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        self._sync()
        t0 = perf_counter()
        try:
            yield
        finally:
            self._sync()
            self.seconds[stage] = self.seconds.get(stage, 0.0) + perf_counter() - t0

    def summary(self) -> dict[str, float]:
        """``high_tr``, ``flow`` and ``diffusion`` (everything after the flow), as results have always reported."""
        s = self.seconds
        rest = sum(v for k, v in s.items() if k not in ("high_tr", "samples", "gated_flow"))
        return {"high_tr": s.get("high_tr", 0.0), "flow": s.get("gated_flow", 0.0), "diffusion": rest}


Volume = Any
"""A volume a stage reads or writes: a numpy array on the CPU, a numba-cuda device array on the GPU."""
Flow = Any
"""The gated flow a stage reads: a :class:`~flexvox_core.flow.FlowField` on the CPU, its (S, H, W, 2) device
array on the GPU."""


class Stages(Protocol):
    """What :func:`run_stages` runs: one engine per device, each holding one :class:`Window` and its working
    memory. :class:`CpuStages` and :class:`~flexvox_core.motion.gpu.engine.CudaStages` implement it with the
    same signatures (a test checks them)."""

    device: str
    window: Window

    def sync(self) -> None:
        """Wait for queued work (before each clock reading)."""

    def high_tr(self) -> Volume:
        """The high-TR video (Step 1)."""

    def samples(self) -> None:
        """The sample volume and its mask, held by the engine."""

    def gated_flow(self, current: Volume) -> Flow:
        """The velocity of every voxel, from ``current`` (the high-TR video or the last pass's result); a pass
        starts here."""

    def hold_high_tr(self, high_tr: Volume) -> Volume:
        """The high-TR video as every stage after the first pass's flow reads it (:data:`HIGH_TR_HELD`)."""

    def speed_classes(self, flow: Flow) -> tuple[Volume, Volume]:
        """(still, slow) voxels."""

    def guides(self, still: Volume) -> Volume:
        """The value of the voxels no trajectory gather estimates (the gather writes into it)."""

    def noise(self, current: Volume, still: Volume) -> Volume | None:
        """The wide kernel's weight per voxel (None: none)."""

    def trajectory_gather(self, flow: Flow, base: Volume, still: Volume, slow: Volume, high_tr: Volume,
                          wide: Volume | None, *, leave_one_out: bool) -> tuple[Volume, Any, Any]:
        """(video, loo, gathered)."""

    def long_reach(self, flow: Flow, video: Volume, slow: Volume) -> None:
        """The slow voxels' range-weighted gather, into ``video``."""

    def refinement(self, video: Volume, flow: Flow, slow: Volume) -> None:
        """The monotone diffusion along the trajectories, in place."""

    def local_choice(self, video: Volume, loo: Volume, gathered: Volume, flow: Flow, high_tr: Volume) -> None:
        """Oriented nc blended in where it predicts the samples better, in place."""

    def gaps(self, video: Volume, flow: Flow) -> None:
        """Dropped frames' sub-frames bridged along the flow, in place."""

    def clip(self, video: Volume) -> Volume:
        """``video`` clipped to the window's sample range, in place."""

    def result(self, current: Volume, high_tr: Volume, flow: Flow, times: StageTimes) -> MotionAwareResult:
        """What the run gives back."""


def run_stages(engine: Stages) -> MotionAwareResult:
    """Run motion-aware's stages on ``engine`` (:class:`CpuStages` or its GPU twin); returns its result."""
    win = engine.window
    times = StageTimes(engine.sync)
    with times("high_tr"):
        high_tr = engine.high_tr()
    with times("samples"):
        engine.samples()
    current = high_tr
    flow = None
    for pass_ in range(win.passes):
        last = pass_ + 1 == win.passes
        with times("gated_flow"):
            flow = engine.gated_flow(current)
            if pass_ == 0:  # the flow read it as computed; every later reader reads it as held
                current = high_tr = engine.hold_high_tr(high_tr)
        with times("speed_classes"):
            still, slow = engine.speed_classes(flow)
        with times("guides"):
            base = engine.guides(still)
        with times("noise"):
            wide = engine.noise(current, still) if win.noise_aware else None
        with times("trajectory_gather"):
            video, loo, gathered = engine.trajectory_gather(flow, base, still, slow, high_tr, wide,
                                                            leave_one_out=win.leave_one_out and last)
        del base, still  # read by no later stage: the CPU's volumes go now
        with times("long_reach"):
            engine.long_reach(flow, video, slow)
        with times("refinement"):
            engine.refinement(video, flow, slow)
        if loo is not None:
            with times("local_choice"):
                engine.local_choice(video, loo, gathered, flow, high_tr)
        if win.missing is not None:
            with times("gaps"):
                engine.gaps(video, flow)
        current = engine.clip(video)
    _logger.info("motion-aware (%s): %s", engine.device,
                 ", ".join(f"{k} {v:.3f} s" for k, v in times.seconds.items()))
    return engine.result(current, high_tr, flow, times)


class CpuStages:
    """The stages on the CPU (numpy, OpenCV and numba), for one :class:`Window`.

    ``memo``: a :class:`~flexvox_core.flow.memo.FlowMemo` the optical flow of pairs is looked up in and kept in
    (a stream's, from window to window)."""

    device = "cpu"

    def __init__(self, window: Window, *, memo: FlowMemo | None = None) -> None:
        self.window = window
        self.memo = memo
        self.passes_run = 0  # gated_flow starts each pass
        self.last = False  # the pass running is the last: what no later pass reads may be freed or overwritten
        self.mask: SampleMask | None = None
        self.fixed: npt.NDArray[np.float32] | None = None
        self.still_value: npt.NDArray[np.float32] | None = None
        self.gathered: PackedVolume | None = None  # speed_classes: the voxels the gather estimates

    def sync(self) -> None:
        return None

    def _mask(self) -> SampleMask:
        """The samples' mask, read a band of sub-frames at a time (:meth:`samples` sets it, before every later
        stage)."""
        assert self.mask is not None, "the samples stage runs first"
        return self.mask

    # ----------------------------------------------------------------------------------------------- stages

    def high_tr(self) -> Volume:
        w = self.window
        return diffuse(w.frames, w.code, tensor=STEP1_TENSOR, time=STEP1_TIME, missing=w.missing)

    def samples(self) -> None:
        """The samples' mask, made a band at a time from the code and the dropped frames (a dropped frame's
        sub-frames hold no samples); no stage reads a sample volume: the gathers read the frames and the code."""
        w = self.window
        self.mask = SampleMask(w.code, (w.S, *w.frames.shape[1:]), w.missing)

    def gated_flow(self, current: Volume) -> Flow:
        w = self.window
        self.passes_run += 1
        self.last = self.passes_run == w.passes
        field_ = gated_flow(current, w.K, backend=w.flow_backend, gate=w.flow_gate, scale=w.flow_scale,
                            consistency=w.flow_consistency, slow_speed=w.slow_speed, memo=self.memo)
        if w.missing is not None:  # bridged at the flow's own scale (ScaledFlow's `held`: its small flow)
            bridge_flow(field_.held, w.missing, w.K, margin=w.bridge_margin)
        return field_

    def hold_high_tr(self, high_tr: Volume) -> Volume:
        return high_tr if HIGH_TR_HELD is np.float32 else held_as(high_tr, HIGH_TR_HELD)

    def speed_classes(self, flow: Flow) -> tuple[Volume, Volume]:
        w = self.window
        still, slow, self.gathered = packed_speed_classes(flow, w.still_speed, w.slow_class_speed, w.skip)
        return still, slow

    def guides(self, still: Volume) -> Volume:
        """The value of the voxels no trajectory gather estimates: the fixed-tensor nc of Eq. 4's tensor at zero
        flow (``diag(c3, c2, c1)``), and at the still voxels their pixel's own samples averaged in time
        (Eq. 4's tensor in the limit c -> (0, 0, 1)): exact for a still scene, and its noise averages out."""
        w = self.window
        fixed = self.fixed
        if fixed is None:  # computed once: every pass reads it
            fixed = self.fixed = guide(w, w.guide_tensor, w.gather_time)
        base = fixed
        if still.any():
            if w.passes == 1 and w.skip is None:
                # `fixed` serves this pass alone: the still voxels' values go straight into it (no volume of them;
                # diffuse_where reads the still voxels' packed bits as they are held).
                diffuse_where(w.frames, w.code, base, still, tensor=STILL_TENSOR, time=w.still_time,
                              missing=w.missing)
            else:
                still_value = self.still_value
                if still_value is None:
                    still_value = self.still_value = guide(w, STILL_TENSOR, w.still_time)
                base = fixed.copy() if w.passes > 1 else fixed  # `fixed` serves every pass
                for t in range(w.S):  # a sub-frame of the still voxels at a time
                    where = band(still, t, t + 1)[0]
                    if where.any():
                        np.copyto(base[t], still_value[t], where=where)
        return base

    def noise(self, current: Volume, still: Volume) -> Volume | None:
        """The wide kernel's weights per sub-frame (None: a noiseless or single-frame capture)."""
        w = self.window
        if w.frames.shape[0] < 2:
            return None
        mask = self._mask()
        noise = noise_aware.frame_noise(w.frames, still, mask, w.K)
        if not noise.any():
            return None
        _logger.info("motion-aware: noise %.4g (median of the frames'), smoothing where flatter",
                     float(np.median(noise)))
        return noise_aware.SmoothWeights(current, np.repeat(noise, w.K))

    def trajectory_gather(self, flow: Flow, base: Volume, still: Volume, slow: Volume, high_tr: Volume,
                          wide: Volume | None, *, leave_one_out: bool) -> tuple[Volume, Any, Any]:
        """(video, loo, gathered): the gather at the voxels neither still nor slow; ``loo`` (F, H, W) each sample's
        leave-one-out estimate (None unless asked for) and ``gathered`` the voxels gathered (with ``loo``)."""
        w = self.window
        assert self.gathered is not None, "the speed classes run before the gather"
        loo = np.full(w.frames.shape, np.nan, np.float32) if leave_one_out else None
        # The gather writes into `base` when no later pass reads it (one volume less).
        into = base if w.passes == 1 or base is not self.fixed else None
        video = trajectory_gather(w.frames, w.code, flow, missing=w.missing, c=w.gather_c, time=w.gather_time,
                                  fallback=high_tr, gathered=self.gathered, still_value=base, loo=loo, wide=wide,
                                  wide_sigma=noise_aware.wide_sigma(w.K), max_reach=w.gather_reach, out=into)
        gathered = self.gathered if loo is not None else None  # the local choice reads it a band at a time
        if self.last:
            self.fixed = self.still_value = None  # read no more (what the video is written into stays as the video)
        return video, loo, gathered

    def long_reach(self, flow: Flow, video: Volume, slow: Volume) -> None:
        w = self.window
        if not slow.any():
            return
        # From the frames and the code (no sample volume); the samples are written back as it goes.
        longreach.long_reach(w.frames, w.code, flow, video, slow, w.long_reach_plan, missing=w.missing, out=video,
                             write_samples=True)

    def refinement(self, video: Volume, flow: Flow, slow: Volume) -> None:
        """Along each trajectory; the slow voxels read their neighbours by clipped Catmull-Rom (a bilinear read
        a fraction of a pixel off is a blur, which would take the texture their long-reach gather kept), the still
        ones (:func:`~flexvox_core.motion.vardiff.refine_still_speed`) none: their flow is taken as zero."""
        w = self.window
        refine_time = w.refine_time
        if refine_time <= 0:
            return
        g0, g1 = w.gathered
        # A band of sub-frames at a time: the mask, the flow and the classes are read by bands (planes.band).
        variable_tensor_diffusion(video[g0:g1], self._mask(), flow, c=REFINE_C, time=refine_time,
                                  out=video[g0:g1], sharp=slow, start=g0,
                                  still_speed=refine_still_speed(w.still_speed))

    def local_choice(self, video: Volume, loo: Volume, gathered: Volume, flow: Flow, high_tr: Volume) -> None:
        w = self.window
        F = loo.shape[0]
        finite = np.zeros(F, bool)

        def some_finite(f: int) -> None:  # a frame per task: no serial pass over the leave-one-out
            finite[f] = np.isfinite(loo[f]).any()

        for_each(some_finite, F)
        if not finite.any():
            return
        if w.scores_still_voxels:  # at gathered voxels slower than STILL_VOXEL_SPEED the pixel's own sample scores
            mask = self._mask()
            # A flow without bands (any object with a whole `flow` array) is read as that array.
            local_choice.still_voxel_loo(loo, video, w.frames, gathered, mask,
                                         flow if hasattr(flow, "band") else flow.flow, w.K)
        # A band of frames at a time: a frame's weights pool its own samples' leave-one-out alone, so each band's
        # oriented nc (at its gathered voxels) is blended in before the next band's is made. What the bands share is
        # made once (oriented nc's checks, the guide's included, and constants); the blend reads oriented nc's value at
        # the gathered voxels alone, so no fallback is copied into it; the gathered voxels are unpacked a sub-frame a
        # task (nothing serial between the bands' parallel passes but their calls).
        frames = np.ascontiguousarray(w.frames, np.float32)  # as oriented nc reads them: made once, not per band
        F, H, W = frames.shape
        per_band = max(1, -(-max(local_choice.BAND, 2 * workers()) // w.K))  # whole frames, two sub-frames a thread
        other = np.empty((min(F, per_band) * w.K, H, W), np.float32)
        chosen = np.empty(other.shape, bool)
        other_loo = np.empty(w.frames.shape, np.float32)
        for_each(lambda f: other_loo[f].fill(np.nan), F)  # a frame per task (18 MB at 640×480, K = 16)
        workspace: list[Any] = []  # the threads' planes, kept from band to band
        plan = OrientedNc(frames, w.code, high_tr, missing=w.missing)
        counts = getattr(gathered, "counts", None)  # a packed volume's True voxels per sub-frame
        for f0 in range(0, F, per_band):
            f1 = min(F, f0 + per_band)
            s0, s1 = f0 * w.K, f1 * w.K
            where = chosen[:s1 - s0]
            if counts is not None and not counts[s0:s1].any():
                continue

            def unpack(i: int, s0: int = s0, where: np.ndarray = where) -> None:
                where[i] = band(gathered, s0 + i, s0 + i + 1)[0]

            for_each(unpack, s1 - s0)
            if counts is None and not where.any():
                continue
            got, _ = plan.run(s0, s1, where, video[s0:s1], out=other[:s1 - s0], loo=other_loo, workspace=workspace,
                              fill=False)
            weights = local_choice.local_weights(loo[f0:f1], other_loo[f0:f1], frames[f0:f1])
            local_choice.blend(video[s0:s1], got, weights, where, w.K)

    def gaps(self, video: Volume, flow: Flow) -> None:
        w = self.window
        bridge(video, w.missing, w.K, flow=flow)

    def clip(self, video: Volume) -> Volume:
        lo, hi = self.window.sample_range
        return np.clip(video, lo, hi, out=video)

    def result(self, current: Volume, high_tr: Volume, flow: Flow, times: StageTimes) -> MotionAwareResult:
        w = self.window
        video = current.astype(np.float32, copy=False)
        s0, s1 = w.keep
        if (s0, s1) != (0, w.S):
            video = np.ascontiguousarray(video[s0:s1])
        held = high_tr  # float32 when first read (the result's high_tr is float32; no copy made until then)
        public = held if held.dtype == np.float32 else (lambda: held.astype(np.float32))
        return MotionAwareResult(video, public, flow, w.K, w.gather_c, times.summary(), dict(times.seconds),
                                 self.device)


def held_as(volume: np.ndarray, dtype: Any) -> np.ndarray:
    """``volume.astype(dtype)``, a sub-frame at a time on every core (its fresh memory faulted in on both cores).
    float32 to float16 by OpenCV (``cv2.multiply`` by 1 into a float16 plane: the CPU's conversion instructions,
    0.2 against 0.8 ns a value), numpy's values bit for bit (every finite float32 checked, and infinities; NaN
    is not held); anything else by numpy."""
    out = np.empty(volume.shape, dtype)
    by_opencv = volume.dtype == np.float32 and out.dtype == np.float16 and volume.ndim == 3

    def one(t: int) -> None:
        if by_opencv:
            cv2.multiply(volume[t], 1.0, dst=out[t], dtype=cv2.CV_16F)
        else:
            out[t] = volume[t]

    for_each(one, len(volume))
    return out


def class_thresholds(still_speed: float | None, slow_speed: float | None) -> tuple[np.float32, np.float32]:
    """:func:`speed_class`'s thresholds, float32 (as the speeds are): −∞ for a class that does not exist."""
    return (np.float32(-np.inf if still_speed is None else still_speed),
            np.float32(-np.inf if slow_speed is None else slow_speed))


def speed_classes(flow: np.ndarray | Bands, still_speed: float | None, slow_speed: float | None,
                  skip: np.ndarray | None = None
                  ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Bool volumes ``still``, ``slow`` and ``gathered`` (:func:`speed_class`; None: no such class; ``skip`` (S,)
    bool: sub-frames outside the gathered ones), a sub-frame at a time (no full-volume speed array); ``flow`` an
    array or a volume read a band at a time (:func:`~flexvox_core.planes.band`)."""
    S, H, W = flow.shape[:3]
    still = np.empty((S, H, W), bool)
    slow = np.empty((S, H, W), bool)
    gathered = np.empty((S, H, W), bool)
    still_below, slow_below = class_thresholds(still_speed, slow_speed)

    def one(t: int) -> None:  # a sub-frame at a time, on every core
        plane = band(flow, t, t + 1)[0]
        speed = cv2.magnitude(plane[..., 0], plane[..., 1])
        still[t], slow[t], gathered[t] = speed_class(speed, still_below, slow_below,
                                                     skip is not None and bool(skip[t]))

    for_each(one, S)
    return still, slow, gathered


def packed_speed_classes(flow: np.ndarray | Bands, still_speed: float | None, slow_speed: float | None,
                         skip: np.ndarray | None = None) -> tuple[PackedVolume, PackedVolume, PackedVolume]:
    """:func:`speed_classes` held a bit per voxel (:class:`~flexvox_core.motion.packed.PackedVolume`, read a band
    at a time; each sub-frame's count of each class kept): ``still``, ``slow`` and ``gathered``, the same bits."""
    S, H, W = flow.shape[:3]
    still, slow, gathered = (PackedVolume((S, H, W)) for _ in range(3))
    still_below, slow_below = class_thresholds(still_speed, slow_speed)

    def one(t: int) -> None:  # a sub-frame at a time, on every core (each writes its own rows)
        plane = band(flow, t, t + 1)[0]
        speed = cv2.magnitude(plane[..., 0], plane[..., 1])
        # speed_class at each voxel, compiled, straight into the packed bits
        counts = classify_plane(speed, still_below, slow_below, skip is not None and bool(skip[t]),
                                still.packed[t], slow.packed[t], gathered.packed[t])
        still.counts[t], slow.counts[t], gathered.counts[t] = counts

    for_each(one, S)
    return still, slow, gathered


def guide(window: Window, tensor: tuple[float, float, float], time: float) -> npt.NDArray[np.float32]:
    """The fixed-tensor normalized convolution of the whole window; only the sub-frames the gathers read when
    the window gathers part of itself (the rest of the volume is 0: nothing reads it)."""
    w = window
    rows = w.guide_rows
    if rows is None:
        return diffuse(w.frames, w.code, tensor=tensor, time=time, missing=w.missing)
    out = np.zeros((w.S, *w.frames.shape[1:]), np.float32)
    out[rows[0]:rows[1]] = diffuse(w.frames, w.code, tensor=tensor, time=time, missing=w.missing, subframes=rows)
    return out
