"""Motion-aware's options (:class:`MotionOptions`) and the constants that set its defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from numbers import Integral, Real

import numpy as np

from flexvox_core.flow.backends import BACKENDS
from flexvox_core.gaps import captured
from flexvox_core.motion.tensors import DEFAULT_C, check_c
from flexvox_core.motion.vardiff import explicit_steps
from flexvox_core.numbers import number_pair
from flexvox_core.reconstruct.diffusion import MAX_EXPLICIT_STEPS, sigmas

STEP1_TENSOR = (1.0, 1.0, 0.05)
"""Tensor of the high-TR reconstruction (the paper's Step 1): little smoothing in time."""
STEP1_TIME = 2.0
"""Its diffusion time."""
DEFAULT_TIME = 5.0
"""Diffusion time n of the trajectory gather (the accuracy knob)."""
GATHER_REACH = 1.25
"""Motion-aware's trajectory gather reaches this many standard deviations of its trajectory Gaussian at zero flow,
√(2 n c1), each way (4 sub-frames at the default n = 5, c1 = 0.95, at any K): the voxels it gathers move, so their
own Gaussian, √(2 n c1 / (1 + u² + v²)), is narrower still. The earlier reach (3 standard deviations and at least
a sampling period, each voxel up to its weight of :data:`~flexvox_core.motion.gather_weights.CUTOFF`) read up to
2.75 times the offsets for a PSNR within 0.03 dB of this one on every capture of ``bench/motion_psnr_table.py``
(docs/benchmarks.md, "Less work per voxel")."""
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


REFINE_SHOWN = "(K/16)²"
"""What forms show for the default refinement time: it depends on the code (1 at K = 16, 0.25 at K = 8)."""


def _real(v) -> bool:
    """A finite real number (Python's or numpy's), not a bool."""
    return isinstance(v, Real) and not isinstance(v, bool) and math.isfinite(v)


def _flag(v) -> bool:
    return isinstance(v, bool | np.bool_)


def _check_gate(gate):
    try:
        lo, hi = (float(v) for v in gate)
    except (TypeError, ValueError):
        lo, hi = math.nan, math.nan
    if not 0 <= lo < hi:
        raise ValueError(f"`gate` must be two thresholds 0 <= low < high (px per sub-frame); got {gate!r}")
    return gate


def declared(default, rule: str = "", accepts=None, *, check=None, kind: str | None = None, label: str = "",
             help: str = "", span=None, shown_default=None, choices=(), tag=None, rank=None):
    """A :class:`MotionOptions` field and its declaration, which its metadata holds: the rule (``accepts`` a value,
    None included, and the rule in ``rule``'s words: "`name` must be <rule>; got <value>"; or ``check``, which
    returns the value as kept and raises in its own words), and, for the options the motion-aware method offers
    (``kind`` given: an option kind's name, :mod:`flexvox_core.methods.option_kinds`), what its option shows:
    ``label``, ``help``, ``span``, ``shown_default``, ``choices``; ``tag``: its words in the method's label
    (value -> str); ``rank``: what the bench compares of its value (default the value)."""
    return field(default=default, metadata={
        "rule": rule, "accepts": accepts, "check": check, "kind": kind, "label": label, "help": help, "span": span,
        "shown_default": shown_default, "choices": tuple(choices), "tag": tag, "rank": rank})


@dataclass(frozen=True)
class MotionOptions:
    """The options of :func:`~flexvox_core.motion.pipeline.motion_aware` (see there), checked once: what the
    motion-aware method builds from its option values and what :func:`~flexvox_core.motion.pipeline.run_window`
    takes. Each field's metadata declares its rule (:func:`declared`), and, for the options the motion-aware
    method offers, what its option shows: the method's options are made from them
    (:mod:`flexvox_core.methods.motion_aware_method`). ``slow_reach`` None stands for :data:`SLOW_REACH` (and
    reads back as it); ``refine_time`` None for (K/16)² (:meth:`refine`)."""

    flow: str = declared(
        "dis", f"one of {', '.join(BACKENDS)}", lambda v: isinstance(v, str) and v in BACKENDS, kind="choice",
        choices=BACKENDS,
        label="optical flow", help="optical-flow backend (dis: DIS + variational refinement)", tag=lambda v: f" {v}")
    time: float = declared(
        DEFAULT_TIME, "a finite number > 0", lambda v: _real(v) and v > 0, kind="number", label="diffusion time n",
        help="diffusion time n, the accuracy knob (not a convergence tolerance)", span=(0.25, 20.0, 0.5),
        tag=lambda v: f" n={v:g}")
    passes: int = declared(
        1, "a whole number >= 1", lambda v: isinstance(v, Integral) and not isinstance(v, bool) and v >= 1,
        kind="integer", label="passes", help="flow re-estimated from the previous pass N-1 times", span=(1, 4, 1),
        tag=lambda v: f" x{v}" if v > 1 else "")
    c: tuple = declared(DEFAULT_C, check=check_c)
    refine_time: float | None = declared(
        None, f"a number from 0 to {MAX_REFINE_TIME:.0f} or None ((K/16)²)",
        lambda v: v is None or _real(v) and 0 <= v <= MAX_REFINE_TIME, kind="number", label="refinement time",
        help="time of the monotone diffusion along the trajectories after the gather (default (K/16)²: "
             "1 at K = 16, 0.25 at K = 8; 0 for none)", span=(0.0, 10.0, 0.5), shown_default=REFINE_SHOWN,
        tag=lambda v: f" +refine {v:g}" if v is not None else "",
        rank=lambda v: v is None or v > 0)  # None: the default refinement; any other time > 0 counts as refining
    gate: tuple = declared(DEFAULT_GATE, check=_check_gate)
    flow_scale: float | None = declared(None, "in (0, 1] or None", lambda v: v is None or _real(v) and 0 < v <= 1)
    still_speed: float | None = declared(STILL_SPEED, "a number >= 0 (px per sub-frame) or None",
                                         lambda v: v is None or _real(v) and v >= 0)
    flow_consistency: bool = declared(False, "True or False", _flag)
    slow_speed: float | None = declared(SLOW_SPEED, "a number >= 0 (px per sub-frame) or None",
                                        lambda v: v is None or _real(v) and v >= 0)
    slow_reach: float | None = declared(
        None, f"a number from 0 to {MAX_SLOW_REACH:g} (sampling periods) or None",
        lambda v: v is None or _real(v) and 0 <= v <= MAX_SLOW_REACH, kind="number", label="slow-drift reach",
        help="how far the slowly moving voxels' gather reaches along their trajectory, in sampling periods each "
             "way (0: no long gather, faster where the whole picture drifts slowly)", span=(0.0, 4.0, 0.25),
        shown_default=SLOW_REACH, tag=lambda v: f" slow-reach {v:g}" if v is not None else "")
    local_choice: bool = declared(
        True, "True or False", _flag, kind="flag", label="local choice (leave-one-out)",
        help="blend in nc (its kernel following the edges of the high-TR reconstruction) wherever it predicts "
             "left-out samples better than the trajectory gather (off: the gather alone)",
        tag=lambda v: "" if v else " gather-only")
    noise_aware: bool = declared(
        True, "True or False", _flag, kind="flag", label="noise-aware smoothing",
        help="estimate the noise from still pixels' successive samples and smooth across space where the "
             "picture is flatter than it (off: Eq. 3's narrow spatial blur everywhere)",
        tag=lambda v: "" if v else " noise-blind")

    def __post_init__(self):
        for f in fields(self):
            value = check_field(f, getattr(self, f.name))
            if value is not getattr(self, f.name):
                object.__setattr__(self, f.name, value)
        object.__setattr__(self, "slow_reach", SLOW_REACH if self.slow_reach is None else float(self.slow_reach))
        # Across fields: the guides' blur (time with c) within MAX_SIGMA.
        sigmas((self.c[2], self.c[1], self.c[0]), self.time)

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


def check_field(f, value):
    """``value`` of :class:`MotionOptions`' field ``f`` by its declaration: as kept, or a ``ValueError`` in the
    rule's words."""
    meta = f.metadata
    if meta["check"] is not None:
        return meta["check"](value)
    if not meta["accepts"](value):
        raise ValueError(f"`{f.name}` must be {meta['rule']}; got {value!r}")
    return value


def offered() -> tuple:
    """The fields of :class:`MotionOptions` the motion-aware method offers as options (a ``kind`` declared)."""
    return tuple(f for f in fields(MotionOptions) if f.metadata["kind"] is not None)


def check_sample_range(frames: np.ndarray, missing, sample_range) -> tuple[float, float]:
    """The samples' range: ``sample_range`` checked to contain the captured frames' values, or theirs (None)."""
    samples = captured(frames, missing)
    lo, hi = float(samples.min()), float(samples.max())
    if sample_range is None:
        return lo, hi
    r_lo, r_hi = number_pair("sample_range", sample_range, "two numbers (lo, hi) or None")
    if not (np.isfinite(r_lo) and np.isfinite(r_hi) and r_lo <= lo and hi <= r_hi):
        raise ValueError(f"`sample_range` {sample_range!r} must be finite and contain the frames' values "
                         f"[{lo:g}, {hi:g}]")
    return r_lo, r_hi


def sample_bounds(frames: np.ndarray, missing, value_range) -> tuple[float, float]:
    """Deprecated name of :func:`check_sample_range` (removed in the next release)."""
    from flexvox_core.deprecations import warn_renamed

    warn_renamed("flexvox_core.motion.options.sample_bounds", "check_sample_range")
    return check_sample_range(frames, missing, value_range)
