"""The motion-aware reconstruction as a method (:func:`flexvox_core.motion.motion_aware`); the paper's §4.

Its option values build one :class:`~flexvox_core.motion.options.MotionOptions` (the option names are its
fields), which the pipeline takes as it is (:func:`~flexvox_core.motion.pipeline.run_clip`). It needs the
whole recording's sample range in every chunk (it scales the slow voxels' range weight and bounds the
result), and it can return the flow that drove its tensors and the temporal resolution it chose per voxel
(extras ``flow`` and ``tr``).
"""

from __future__ import annotations

import numpy as np

from flexvox_core.codes import is_identity_code
from flexvox_core.methods.options import Option
from flexvox_core.methods.spec import MethodOutput, MethodSpec
from flexvox_core.motion import resolution_map
from flexvox_core.motion.multiplexed import TIME_FRACTION, motion_aware_multiplexed
from flexvox_core.motion.options import REFINE_SHOWN, offered
from flexvox_core.motion.pipeline import MotionOptions, auto_flow_scale, gated_flow, run_clip
from flexvox_core.motion.stages import cuda_unsupported

__all__ = ["MOTION_AWARE", "REFINE_SHOWN", "MotionAware"]


GPU_VOLUME_BYTES = 140
"""Bytes per voxel of the GPU engine's full-size volumes: 30 float32 (S, H, W) volumes, the flow (8 bytes) and
9 uint8 ones (137), and the taps and tables (:meth:`MotionAware.gpu_voxel_bytes`)."""
GPU_FRAME_BYTES = 24
"""Bytes per pixel of each camera frame: the frames, the leave-one-out estimates, the local choice's weights and
the other estimate, the noise's differences (5 float32 planes, 21 bytes)."""
GPU_FLOW_BYTES = 96
"""Bytes per voxel of the flow's grid: its shrunk videos, velocities and flows, and DIS's pyramids (86 fitted)."""
GPU_FLOW_FRAME_BYTES = 128
"""Bytes per pixel of the flow's grid per camera frame: the K-average's flows (a pair every K/4 sub-frames) and
DIS's for them (121 fitted)."""
GPU_FLOW_PAD = 24
"""Pixels added to each side of the flow's grid: small flow images hold more per pixel (DIS's coarse levels)."""


def _option(f) -> Option:
    """The motion-aware method's option for a field of :class:`MotionOptions`, from its declaration (its rule, kind
    and what a form shows are the field's metadata: one place for each)."""
    m = f.metadata
    return Option(f.name, f.default, m["rule"], m["accepts"], m["kind"], m["label"], m["help"], m["choices"],
                  m["span"], m["shown_default"])


class MotionAware(MethodSpec):
    """Flow-driven diffusion tensors per voxel (the paper's Section 4)."""

    name = "motion-aware"
    title = "motion-aware: diffusion tensors oriented along optical flow (the paper's Section 4)"
    trade = ("motion-aware chooses the trade per voxel from the flow: high SR where still, "
             "high TR where moving")
    option_specs = tuple(_option(f) for f in offered())
    needs_sample_range = True
    extras = ("flow", "tr")
    bench_axis = "time"

    def build(self, values: dict) -> MotionOptions:
        """The pipeline's options: every value as it is (None: the pipeline's default), checked again as a whole."""
        return MotionOptions(**values)

    def overlap(self, options: MotionOptions, K: int) -> int:
        return options.overlap(K)

    takes_missing = True

    def takes_multiplexed(self, options: MotionOptions) -> bool:
        return True

    def gpu_voxel_bytes(self, options: MotionOptions, K: int, H: int, W: int) -> float:
        """Device memory per voxel of a window (S = F·K sub-frames of H×W) on the GPU: an upper bound of the
        engine's :attr:`Workspace.peak_nbytes <flexvox_core.gpu.volumes.Workspace.peak_nbytes>` ÷ (S·H·W),

        GPU_VOLUME_BYTES + GPU_FRAME_BYTES / K + a·(GPU_FLOW_BYTES + GPU_FLOW_FRAME_BYTES / K),

        a = (max(h, 16) + GPU_FLOW_PAD)·(max(w, 16) + GPU_FLOW_PAD) / (H·W), h×w the flow's size
        (:func:`~flexvox_core.flow.estimate.flow_size`; DIS's images are padded to 16 px and its coarsest levels
        and patch grids weigh more on small ones). Derived from the workspace of every stage with two passes,
        every branch taken (still and slow voxels, noise, the local choice), at 81 sizes from 8×8 to
        1920×1080 at K = 4 and 16: the bound holds at each (the margins: docs/benchmarks.md, "Figures behind
        the code"). One pass, the default, holds less. Reproduce:
        ``NUMBA_ENABLE_CUDASIM=1 python -m tests.flexvox_core.gpu.workspace_size`` (the table;
        ``tests/flexvox_core/gpu/test_workspace_size.py`` fails where a run holds more); on a card
        ``bench/bench_gpu.py`` prints the bytes a run held next to this figure."""
        from flexvox_core.flow.estimate import MIN_FLOW_SIDE, flow_size

        h, w = flow_size(H, W, auto_flow_scale(H, W) if options.flow_scale is None else options.flow_scale)
        a = (max(h, MIN_FLOW_SIDE) + GPU_FLOW_PAD) * (max(w, MIN_FLOW_SIDE) + GPU_FLOW_PAD) / (H * W)
        return GPU_VOLUME_BYTES + GPU_FRAME_BYTES / K + a * (GPU_FLOW_BYTES + GPU_FLOW_FRAME_BYTES / K)

    def cpu_only(self, options, code) -> str | None:
        if not is_identity_code(code):
            return "a multiplexed capture's motion-aware runs on the CPU"
        return cuda_unsupported(options)

    def run(self, frames, code, options: MotionOptions, *, sample_range=None, extras=False, missing=None,
            device="cpu") -> MethodOutput:
        if not is_identity_code(code):
            return self._run_multiplexed(frames, code, options, extras)
        r = run_clip(frames, code, options, sample_range=sample_range, missing=missing, device=device)
        return MethodOutput(r.video, {"flow": r.flow.flow, "tr": r.tr} if extras else {}, device=r.device,
                            device_note=r.device_note)

    def _run_multiplexed(self, frames, code, options: MotionOptions, extras) -> MethodOutput:
        """GAP with the motion-compensated Gaussian (time n · TIME_FRACTION per iteration); the extras are the
        gated flow of the result and the TR it implies (refinement and slow reach do not apply)."""
        video = motion_aware_multiplexed(frames, code, flow=options.flow, passes=options.passes,
                                         time=options.time * TIME_FRACTION)
        if not extras:
            return MethodOutput(video)
        K = code.shape[2]
        flow = gated_flow(np.clip(video, 0, 1), K, backend=options.flow, scale=auto_flow_scale(*video.shape[1:])).flow
        return MethodOutput(video, {"flow": flow, "tr": resolution_map(flow, K)[0]})

    def label(self, values: dict) -> str:
        return "motion-aware" + "".join(f.metadata["tag"](values[f.name]) for f in offered())

    def bench_rank(self, row: dict, values: dict, code) -> tuple[tuple, bool]:
        def key(f, v):
            return f.metadata["rank"](v) if f.metadata["rank"] else v

        differ = sum(key(f, row[f.name]) != key(f, values[f.name]) for f in offered() if f.name != self.bench_axis)
        return (differ,), differ == 0


MOTION_AWARE = MotionAware()
