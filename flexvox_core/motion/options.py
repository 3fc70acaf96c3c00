"""Motion-aware's options (:class:`MotionOptions`) and the constants that set its defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flexvox_core.flow.backends import make_backend
from flexvox_core.gaps import captured
from flexvox_core.motion.tensors import DEFAULT_C, check_c
from flexvox_core.motion.vardiff import explicit_steps
from flexvox_core.numbers import checked_number, number_pair
from flexvox_core.reconstruct.diffusion import MAX_EXPLICIT_STEPS, sigmas

STEP1_TENSOR = (1.0, 1.0, 0.05)
"""Tensor of the high-TR reconstruction (the paper's Step 1): little smoothing in time."""
STEP1_TIME = 2.0
"""Its diffusion time."""
DEFAULT_TIME = 5.0
"""Diffusion time n of the trajectory gather (the accuracy knob)."""
FLOW_SIDE = 160
"""Flow runs with the shorter image side at about this many pixels (:func:`auto_flow_scale`)."""
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
diffuses in time alone, so a still scene stays exact (Eq. 4's (0.95, 0.05, 0.05) would also blur it
across space; on `flexvox bench`'s groups the two score within 0.05 dB)."""
MAX_REFINE_TIME = MAX_EXPLICIT_STEPS / (2 * sum(REFINE_C))
"""The longest refinement: the explicit solver's step limit (``time · 2·Σc`` steps)."""
MAX_SLOW_REACH = 1000.0
"""The slow voxels' longest reach, in sampling periods (1000 camera frames each way: longer than any clip
previews or batches hold, and short of integer overflow)."""
DEFAULT_GATE = (0.03, 0.15)
"""Gate ramp in pixels per sub-frame: below 0.03 still, above 0.15 trusted as moving."""
PERIOD_GATE = (0.9, 1.5)
"""Second gate ramp (px per sub-frame) on the successive-sub-frame flow averaged over K sub-frames."""


def auto_flow_scale(height: int, width: int) -> float:
    """Flow scale with the shorter side at :data:`FLOW_SIDE` px (at most 1: never upsampled).

    Flow needs far less spatial resolution than the scene, and its time grows with the pixels: a fixed
    size in pixels keeps small captures at full size (96×128; 0.625 on the 256×256 SCI clips), where
    halving costs accuracy, and takes a 640×480 clip at a third, where it does not. ``flexvox bench`` and
    ``bench/bench_motion_throughput.py [--flow-scale S]`` measure the trade (docs/benchmarks.md).
    """
    return min(1.0, FLOW_SIDE / max(1, min(height, width)))


@dataclass(frozen=True)
class MotionOptions:
    """The options of :func:`~flexvox_core.motion.pipeline.motion_aware` (see there), checked once: what the
    motion-aware method builds from its option values and what :func:`~flexvox_core.motion.pipeline.run_window`
    takes. ``slow_reach`` None stands for :data:`SLOW_REACH` (and reads back as it); ``refine_time`` None for
    (K/16)² (:meth:`refine`)."""

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
    slow_reach: float | None = SLOW_REACH
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
        reach = SLOW_REACH if self.slow_reach is None else self.slow_reach
        object.__setattr__(self, "slow_reach", checked_number(
            "slow_reach", reach, f"a number from 0 to {MAX_SLOW_REACH:g} (sampling periods)",
            lambda v: 0 <= v <= MAX_SLOW_REACH))
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
