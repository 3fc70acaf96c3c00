"""Motion-aware's stages on the GPU: :class:`CudaStages`, the twin of :class:`~flexvox_core.motion.stages.CpuStages`.

The camera frames go up once; every stage reads and writes device arrays held in one
:class:`~flexvox_core.gpu.volumes.Workspace` (reused from window to window by a streaming run); the result's
kept sub-frames come down at the end, and the high-TR video and the flow only when a caller reads them.
"""

from __future__ import annotations

import logging
from time import perf_counter
from typing import Any

import numpy as np
from numba import cuda

from flexvox_core.codes import order_from_code
from flexvox_core.flow import FlowField
from flexvox_core.forward import tiled_order
from flexvox_core.gaps import captured
from flexvox_core.gpu import volumes
from flexvox_core.gpu.diffusion import NcPlan, nc
from flexvox_core.gpu.volumes import Workspace
from flexvox_core.motion import local_choice, noise_aware, stages
from flexvox_core.motion.gated_flow import DETECTOR_DIS_PARAMS, DIS_PARAMS
from flexvox_core.motion.gpu import gaps
from flexvox_core.motion.gpu import gated_flow as gate
from flexvox_core.motion.gpu import local_choice as choice
from flexvox_core.motion.gpu import noise_aware as noise
from flexvox_core.motion.gpu.longreach import long_reach
from flexvox_core.motion.gpu.mcnc import trajectory_gather
from flexvox_core.motion.gpu.vardiff import refine
from flexvox_core.motion.longreach_kernel import corner_table
from flexvox_core.motion.options import (
    PERIOD_GATE,
    REFINE_C,
    STEP1_TENSOR,
    STEP1_TIME,
    STILL_TENSOR,
)
from flexvox_core.motion.result import MotionAwareResult
from flexvox_core.motion.stages import Flow, StageTimes, Volume, Window
from flexvox_core.motion.vardiff import refine_still_speed
from flexvox_core.reconstruct.diffusion import diffuse

_logger = logging.getLogger(__name__)


class Buffers:
    """The names of the engine's device buffers in its :class:`~flexvox_core.gpu.volumes.Workspace`: the window's
    inputs, then one per stage's result (the stage's own scratch buffers carry its name as a prefix)."""

    FRAMES = "frames"
    ORDER = "order"
    PRESENT = "present"
    NC = "nc"
    """The scratch of every normalized convolution (high-TR, the guides)."""
    HIGH_TR = "high_tr"
    SPARSE = "samples.sparse"
    MASK = "samples.mask"
    FLOW = "gated_flow"
    STILL = "speed_classes.still"
    SLOW = "speed_classes.slow"
    GATHER = "speed_classes.gather"
    FIXED = "guides.fixed"
    BASE = ("guides.base0", "guides.base1")
    """With several passes: the guides of even and odd passes (a pass must not overwrite the last one's result)."""
    STILL_VALUE = "guides.still_value"
    NOISE = "noise.g"
    LOO = "trajectory_gather.loo"


class CudaStages:
    """The stages on the GPU for one :class:`~flexvox_core.motion.stages.Window`.

    ``ws``: a workspace to reuse (a streaming run passes the same one for every window). ``pairs``: where the
    optical flow of image pairs runs, ``gpu`` (DIS on the card) or ``cpu`` (OpenCV's DIS on the host).
    """

    device = "cuda"

    def __init__(self, window: Window, *, ws: Workspace | None = None, pairs: str = "gpu"):
        self.window = w = window
        self.ws = ws if ws is not None else Workspace()
        self.pair_flow = gate.PairFlow(self.ws, pairs, DIS_PARAMS)
        self.detector_flow = gate.PairFlow(self.ws, pairs, DETECTOR_DIS_PARAMS)
        F, H, W = w.frames.shape
        self.present = np.ones(F, bool) if w.missing is None else ~np.asarray(w.missing, bool)
        self.frames_d = self.ws.put(Buffers.FRAMES, np.ascontiguousarray(w.frames, np.float32))
        self.order_d = self.ws.put(Buffers.ORDER, np.ascontiguousarray(tiled_order(w.code, H, W), np.int32))
        self.corners = corner_table(order_from_code(w.code))  # the long reach's cells
        self.present_d = self.ws.put(Buffers.PRESENT, self.present.astype(np.uint8))
        kept = captured(w.frames, w.missing)
        self.captured_range = (float(kept.min()), float(kept.max()))  # this window's own samples'
        self.fixed_ready = self.still_ready = False
        self.generation = self.ws.next_generation()
        # What the stages set, for the stages after them.
        self.sparse = self.mask = None  # samples
        self.flow_params: dict = {}  # gated_flow
        self.n_still = self.n_slow = 0  # speed_classes
        self.gather_mask = None  # speed_classes: the voxels the trajectory gather estimates
        self.passes_run = 0  # guides: the passes whose guides were made

    def sync(self) -> None:
        cuda.synchronize()

    def _volume(self, name: str, dtype=np.float32) -> Volume:
        w = self.window
        return self.ws.get(name, (w.S, *w.frames.shape[1:]), dtype)

    def _nc(self, tensor, time: float, out, tag: str) -> None:
        """Normalized convolution into ``out``; the rare voxels with no sample in reach take the CPU's value."""
        w = self.window
        lo, hi = self.captured_range
        low = nc(self.ws, self.frames_d, self.order_d, self.present_d, NcPlan(w.frames.shape[0], w.K, tensor, time,
                 None if w.missing is None else self.present), lo, hi, out, tag=tag)
        if low:
            _logger.info("gpu nc: %d voxels with no sample in reach: the volume is computed on the CPU", low)
            out.copy_to_device(diffuse(w.frames, w.code, tensor=tensor, time=time, missing=w.missing))

    # ----------------------------------------------------------------------------------------------- stages

    def high_tr(self) -> Volume:
        out = self._volume(Buffers.HIGH_TR)
        self._nc(STEP1_TENSOR, STEP1_TIME, out, Buffers.NC)
        return out

    def samples(self) -> None:
        self.sparse = self._volume(Buffers.SPARSE)
        self.mask = self._volume(Buffers.MASK, np.uint8)
        volumes.samples(self.frames_d, self.order_d, self.present_d, self.window.K, self.sparse, self.mask)

    def gated_flow(self, current: Volume) -> Flow:
        w = self.window
        flow = self.ws.get(Buffers.FLOW, (w.S, *w.frames.shape[1:], 2))
        params = gate.gated_flow(self.ws, current, w.K, gate=w.flow_gate, scale=w.flow_scale, slow_speed=w.slow_speed,
                                 period_gate=PERIOD_GATE, pair_flow=self.pair_flow,
                                 detector_flow=self.detector_flow, out=flow)
        self.flow_params = {"backend": "dis", **DIS_PARAMS, **params, "pairs": self.pair_flow.where}
        if w.missing is not None:
            gaps.bridge_flow(flow, w.missing, w.K, margin=w.bridge_margin)
        return flow

    def hold_high_tr(self, high_tr: Volume) -> Volume:
        """Its values rounded through float16 in place (the CPU holds it in float16 from the flow on: the same
        values, in the device's float32 buffer)."""
        if stages.HIGH_TR_HELD is not np.float32:
            volumes.through_half(high_tr)
        return high_tr

    def speed_classes(self, flow: Flow) -> tuple[Volume, Volume]:
        w = self.window
        still, slow, gather = (self._volume(n, np.uint8) for n in (Buffers.STILL, Buffers.SLOW, Buffers.GATHER))
        self.n_still, self.n_slow = gate.speed_classes(self.ws, flow, w.still_speed, w.slow_class_speed, w.skip,
                                                       still, slow, gather)
        self.gather_mask = gather
        return still, slow

    def guides(self, still: Volume) -> Volume:
        w = self.window
        fixed = self._volume(Buffers.FIXED)
        if not self.fixed_ready:
            self._nc(w.guide_tensor, w.gather_time, fixed, Buffers.NC)
            self.fixed_ready = w.passes > 1  # a later pass reads it again
        base = fixed
        if w.passes > 1:  # `fixed` serves every pass; two volumes in turn, so as not to overwrite the last pass's
            self.passes_run += 1
            base = self._volume(Buffers.BASE[self.passes_run % 2])
            volumes.copy(base, fixed)
        if self.n_still:
            still_value = self._volume(Buffers.STILL_VALUE)
            if not self.still_ready:
                self._nc(STILL_TENSOR, w.still_time, still_value, Buffers.NC)
                self.still_ready = w.passes > 1
            volumes.copy_where(base, still_value, still)
        return base

    def noise(self, current: Volume, still: Volume) -> Volume | None:
        w = self.window
        g = self._volume(Buffers.NOISE)
        if not noise.noise_weights(self.ws, self.frames_d, current, still, self.mask, w.K, g):
            return None
        return g

    def trajectory_gather(self, flow: Flow, base: Volume, still: Volume, slow: Volume, high_tr: Volume,
                          wide: Volume | None, *, leave_one_out: bool) -> tuple[Volume, Any, Any]:
        w = self.window
        loo = None
        if leave_one_out:
            loo = self.ws.get(Buffers.LOO, w.frames.shape)
            volumes.fill(loo, np.nan)
        c1, c2, _ = w.gather_c
        # The gather writes into the guides' volume: the voxels it does not gather keep their value there.
        trajectory_gather(self.ws, self.sparse, self.mask, flow, self.gather_mask, base, high_tr, time=w.gather_time,
                          c1=c1, c2=c2, reach=w.gather_reach, wide=wide, wide_sigma=noise_aware.wide_sigma(w.K),
                          loo=loo)
        return base, loo, (self.gather_mask if loo is not None else None)

    def long_reach(self, flow: Flow, video: Volume, slow: Volume) -> None:
        w = self.window
        if not self.n_slow:
            return
        long_reach(self.ws, self.frames_d, self.order_d, self.present_d, self.corners, flow, video, slow,
                   w.long_reach_plan)

    def refinement(self, video: Volume, flow: Flow, slow: Volume) -> None:
        w = self.window
        t = w.refine_time
        if t <= 0:
            return
        g0, g1 = w.gathered
        refine(self.ws, video[g0:g1], self.mask[g0:g1], flow[g0:g1], slow[g0:g1], c=REFINE_C, time=t,
               still_speed=refine_still_speed(w.still_speed))

    def local_choice(self, video: Volume, loo: Volume, gathered: Volume, flow: Flow, high_tr: Volume) -> None:
        w = self.window
        choice.local_choice(self.ws, video, loo, gathered, self.mask, flow, self.frames_d, self.order_d,
                            self.present_d, high_tr, w.K, score_still_voxels=w.scores_still_voxels,
                            still_speed=local_choice.STILL_VOXEL_SPEED,
                            sigma=local_choice.pooling_sigma(*w.frames.shape[1:]))

    def gaps(self, video: Volume, flow: Flow) -> None:
        w = self.window
        gaps.bridge(video, flow, w.missing, w.K)

    def clip(self, video: Volume) -> Volume:
        lo, hi = self.window.sample_range
        volumes.clip(video, lo, hi)
        return video

    def result(self, current: Volume, high_tr: Volume, flow: Flow, times: StageTimes) -> MotionAwareResult:
        w = self.window
        s0, s1 = w.keep
        t0 = perf_counter()
        video = current[s0:s1].copy_to_host()
        times.seconds["download"] = perf_counter() - t0
        params = dict(self.flow_params)
        shape = (w.S, *w.frames.shape[1:])

        def fresh(array):
            if self.ws.generation != self.generation:
                raise RuntimeError("this GPU result's high-TR video and flow were overwritten by a later window of "
                                   "the same workspace: read them before the next window runs")
            return array.copy_to_host()

        def flow_field():
            return FlowField(fresh(flow), np.broadcast_to(np.float32(1), shape), params,
                             times.seconds.get("gated_flow", 0.0))

        return MotionAwareResult(video, lambda: fresh(high_tr), flow_field, w.K, w.gather_c, times.summary(),
                                 dict(times.seconds), self.device)
