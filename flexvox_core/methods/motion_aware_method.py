"""The motion-aware reconstruction as a method (:func:`flexvox_core.motion.motion_aware`).

Its option values build one :class:`~flexvox_core.motion.options.MotionOptions` (the option names are its
fields), which the pipeline takes as it is (:func:`~flexvox_core.motion.pipeline.run_clip`). It needs the
whole recording's sample range in every chunk (it scales the slow voxels' range weight and bounds the
result), and it can return the flow that drove its tensors and the temporal resolution it chose per voxel
(extras ``flow`` and ``tr``).
"""

from __future__ import annotations

import numpy as np

from flexvox_core.codes import is_identity_code
from flexvox_core.flow import BACKENDS
from flexvox_core.methods.diffusion_method import time_option
from flexvox_core.methods.options import choice, flag, integer, number
from flexvox_core.methods.spec import MethodOutput, MethodSpec
from flexvox_core.motion import resolution_map
from flexvox_core.motion.multiplexed import TIME_FRACTION, motion_aware_multiplexed
from flexvox_core.motion.pipeline import (
    DEFAULT_TIME,
    MAX_REFINE_TIME,
    MAX_SLOW_REACH,
    SLOW_REACH,
    MotionOptions,
    auto_flow_scale,
    gated_flow,
    run_clip,
)
from flexvox_core.motion.stages import cuda_unsupported

REFINE_SHOWN = "(K/16)²"
"""What forms show for the default refinement time: it depends on the code (1 at K = 16, 0.25 at K = 8)."""


class MotionAware(MethodSpec):
    """Flow-driven diffusion tensors per voxel (the paper's Section 4)."""

    name = "motion-aware"
    title = "motion-aware: diffusion tensors oriented along optical flow (the paper's Section 4)"
    trade = ("motion-aware chooses the trade per voxel from the flow: high SR where still, "
             "high TR where moving")
    options = (
        choice("flow", "dis", tuple(BACKENDS), label="optical flow",
               help="optical-flow backend (dis: DIS + variational refinement)"),
        time_option(DEFAULT_TIME, (0.25, 20.0, 0.5)),
        integer("passes", 1, label="passes", help="flow re-estimated from the previous pass N-1 times",
                span=(1, 4, 1)),
        number("refine_time", None, maximum=MAX_REFINE_TIME,
               rule=f"a number from 0 to {MAX_REFINE_TIME:.0f} or None ((K/16)²)", label="refinement time",
               help="time of the monotone diffusion along the trajectories after the gather (default (K/16)²: "
                    "1 at K = 16, 0.25 at K = 8; 0 for none)", span=(0.0, 10.0, 0.5), shown_default=REFINE_SHOWN),
        number("slow_reach", None, maximum=MAX_SLOW_REACH,
               rule=f"a number from 0 to {MAX_SLOW_REACH:g} (sampling periods) or None", label="slow-drift reach",
               help="how far the slowly moving voxels' gather reaches along their trajectory, in sampling "
                    "periods each way (0: no long gather, faster where the whole picture drifts slowly)",
               span=(0.0, 4.0, 0.25), shown_default=SLOW_REACH),
        flag("local_choice", True, label="local choice (leave-one-out)",
             help="blend in nc (its kernel following the edges of the high-TR reconstruction) wherever it predicts "
                  "left-out samples better than the trajectory gather (off: the gather alone)"),
        flag("noise_aware", True, label="noise-aware smoothing",
             help="estimate the noise from still pixels' successive samples and smooth across space where the "
                  "picture is flatter than it (off: Eq. 3's narrow spatial blur everywhere)"),
    )
    needs_sample_range = True
    extras = ("flow", "tr")
    bench_axis = "time"

    def build(self, values: dict) -> MotionOptions:
        """The pipeline's options: every value as it is (None: the pipeline's default), checked again as a whole."""
        return MotionOptions(**values)

    def overlap(self, options: MotionOptions, K: int) -> int:
        return options.overlap(K)

    takes_missing = True
    takes_multiplexed = True

    gpu_bytes_per_voxel = 136
    """About 30 float32 volumes and 9 byte volumes (flexvox_core.motion.gpu.engine's workspace)."""

    def cpu_only(self, options, code) -> str | None:
        if not is_identity_code(code):
            return "a multiplexed capture's motion-aware runs on the CPU"
        return cuda_unsupported(options)

    def run(self, frames, code, options: MotionOptions, *, value_range=None, extras=False, missing=None,
            device="cpu") -> MethodOutput:
        if not is_identity_code(code):
            return self._run_multiplexed(frames, code, options, extras)
        r = run_clip(frames, code, options, value_range=value_range, missing=missing, device=device)
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
        extra = f" +refine {values['refine_time']:g}" if values["refine_time"] is not None else ""
        extra += f" x{values['passes']}" if values["passes"] > 1 else ""
        extra += f" slow-reach {values['slow_reach']:g}" if values["slow_reach"] is not None else ""
        extra += " gather-only" if not values["local_choice"] else ""
        extra += " noise-blind" if not values["noise_aware"] else ""
        return f"motion-aware {values['flow']} n={values['time']:g}{extra}"

    def bench_rank(self, row: dict, values: dict, code) -> tuple[tuple, bool]:
        def refines(r):  # None: the default refinement ((K/16)²); any other time > 0 counts as refining
            return r is None or r > 0

        differ = sum((row["passes"] != values["passes"], refines(row["refine_time"]) != refines(values["refine_time"]),
                      row["slow_reach"] != values["slow_reach"], row["local_choice"] != values["local_choice"],
                      row["noise_aware"] != values["noise_aware"], row["flow"] != values["flow"]))
        return (differ,), differ == 0


MOTION_AWARE = MotionAware()
