"""Motion-aware reconstruction (the paper's Section 4, with flexvox's safeguards): :func:`motion_aware`.

The pipeline is a sequence of named stages (:mod:`flexvox_core.motion.stages`): high-TR nc, gated flow, speed
classes, the guides, noise, the trajectory gathers (fast and long-reach), the refinement, the local choice and
the gaps. :func:`run_window` runs them on the CPU or on an NVIDIA GPU (:mod:`flexvox_core.gpu`).

1. **High-TR reconstruction**: normalized convolution with ``diag(1, 1, 0.05)`` (the paper's Step 1), so fast
   motion is not blurred away before flow is measured.
2. **Flow** between successive sub-frames of it, gated by a motion detector that cannot swim
   (:func:`~flexvox_core.motion.gated_flow.gated_flow`).
3. **Motion-driven diffusion**: the tensor field of Eq. 4 (``c``), applied by the motion-compensated normalized
   convolution (:func:`~flexvox_core.motion.mcnc.motion_compensated_nc`) and refined by the monotone
   variable-tensor diffusion (:func:`~flexvox_core.motion.vardiff.variable_tensor_diffusion`).
4. Optionally further **passes**: flow re-estimated on the motion-aware result.
"""

from __future__ import annotations

import logging
from dataclasses import fields

import numpy as np

from flexvox_core.deprecations import renamed_keyword
from flexvox_core.gaps import as_missing
from flexvox_core.motion.gated_flow import DIS_PARAMS, gated_flow
from flexvox_core.motion.options import (
    DEFAULT_GATE,
    DEFAULT_TIME,
    FLOW_SIDE,
    LONG_REACH_RANGE,
    LONG_REACH_SIGMA_S,
    MAX_REFINE_TIME,
    MAX_SLOW_REACH,
    PERIOD_GATE,
    REFINE_C,
    SLOW_REACH,
    SLOW_SPEED,
    STEP1_TENSOR,
    STEP1_TIME,
    STILL_SPEED,
    STILL_TENSOR,
    MotionOptions,
    auto_flow_scale,
    check_sample_range,
    sample_bounds,
)
from flexvox_core.motion.result import MotionAwareResult
from flexvox_core.motion.stages import CpuStages, Window, cuda_unsupported, run_stages
from flexvox_core.reconstruct._common import check_frames, check_identity_code

_logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_GATE", "DEFAULT_TIME", "DIS_PARAMS", "FLOW_SIDE", "LONG_REACH_RANGE", "LONG_REACH_SIGMA_S",
    "MAX_REFINE_TIME", "MAX_SLOW_REACH", "PERIOD_GATE", "REFINE_C", "SLOW_REACH", "SLOW_SPEED", "STEP1_TENSOR",
    "STEP1_TIME", "STILL_SPEED", "STILL_TENSOR", "MotionAwareResult", "MotionOptions", "auto_flow_scale",
    "check_sample_range", "engine_for", "gated_flow", "motion_aware", "run_clip", "run_window", "sample_bounds",
]


def motion_aware(frames, code, *, sample_range: tuple[float, float] | None = None, missing=None, device: str = "cpu",
                 **options) -> MotionAwareResult:
    """Motion-aware reconstruction of an identity-code capture.

    The keywords from ``flow`` to ``noise_aware`` are the fields of :class:`MotionOptions` (declared there, with
    their rules; ``inspect.signature(motion_aware)`` lists them with their defaults).

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
        Eigenvalues of Eq. 4 (default the paper's 0.95, 0.05, 0.05).
    refine_time : float or None
        Time of the variable-tensor diffusion along the trajectories after the gather
        (:func:`~flexvox_core.motion.vardiff.variable_tensor_diffusion` with :data:`REFINE_C`; 0: none).
        None (default): (K/16)² — 1 at K = 16, 0.25 at K = 8: a diffusion time grows with the square of the
        distance to cover, here the sampling period (chosen with ``flexvox bench``, K = 8 and 16;
        ``docs/reconstruction.md``, "The refinement").
    gate : (low, high)
        Motion-detector ramp, pixels per sub-frame.
    flow_scale : float or None
        Resolution at which flow is computed, in (0, 1]; None (default): :func:`auto_flow_scale`.
    still_speed : float or None
        Voxels slower than this take their own samples interpolated in time (see
        :data:`STILL_SPEED`); None gathers along trajectories everywhere.
    flow_consistency : bool
        Also compute backward flow for a forward–backward confidence map. Off by default: it costs a second
        flow per pair for little change in PSNR.
    slow_speed : float or None
        Below this speed (px per sub-frame) the velocity is the K-average's long-baseline flow
        (see :func:`gated_flow`); None: successive-sub-frame flow everywhere (and no slow voxels).
    slow_reach : float or None
        Voxels that move, slower than ``slow_speed``, take a range-weighted gather reaching this
        many sampling periods (K sub-frames) each way along their trajectory
        (:func:`~flexvox_core.motion.longreach.long_reach_nc`); 0: the short gather of the fast
        voxels; None: :data:`SLOW_REACH`. The accuracy knob that costs most time where the whole picture drifts
        slowly.
    sample_range : (lo, hi) or None
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
        the gathered voxels. On by default (its gain: ``flexvox bench``'s "gather-only" rows; the module says
        where it is biased: single-frame captures of still subjects).
    noise_aware : bool
        Estimate the capture's noise from its still pixels' successive samples and let the gather smooth
        across space where the picture is flat compared with it (:mod:`~flexvox_core.motion.noise_aware`).
        A noiseless or single-frame capture is unchanged. On by default (its gain:
        ``bench/bench_motion_margin.py --noise``).
    device : {"cpu", "cuda", "auto"}
        Where the stages run (:mod:`flexvox_core.gpu`): ``cuda`` on an NVIDIA GPU (raises
        :class:`~flexvox_core.gpu.DeviceUnavailable` naming what is missing when none is usable), ``auto`` there
        when one is usable and on the CPU otherwise. The result's ``device`` says which ran, and its
        ``device_note`` why the CPU ran options the GPU's stages do not run as the CPU's
        (:func:`~flexvox_core.motion.stages.cuda_unsupported`).

    Returns
    -------
    MotionAwareResult
        Its ``video`` in [0, 1] (the pipeline bounds it by the samples' range, which noise may take past [0, 1];
        :func:`run_clip` and :func:`run_window` leave it there).
    """
    sample_range = renamed_keyword(options, "value_range", "sample_range", sample_range, "motion_aware")
    result = run_clip(frames, code, MotionOptions(**options), sample_range=sample_range, missing=missing,
                      device=device)
    np.clip(result.video, 0.0, 1.0, out=result.video)
    return result


def _signature():
    """``motion_aware``'s signature as ``help()`` and ``inspect`` show it: the frames and code, every field of
    :class:`MotionOptions` with its default (the keywords are its fields: they are not listed twice), then
    ``sample_range``, ``missing`` and ``device``."""
    import inspect

    own = inspect.signature(motion_aware)
    kw = inspect.Parameter.KEYWORD_ONLY
    params = [own.parameters["frames"], own.parameters["code"],
              *(inspect.Parameter(f.name, kw, default=f.default, annotation=f.type) for f in fields(MotionOptions)),
              *(p for n, p in own.parameters.items() if n in ("sample_range", "missing", "device"))]
    return own.replace(parameters=params)


motion_aware.__signature__ = _signature()  # type: ignore[attr-defined]


def run_clip(frames, code, options: MotionOptions, *, sample_range: tuple[float, float] | None = None, missing=None,
             device: str = "cpu") -> MotionAwareResult:
    """:func:`motion_aware` with its options already checked (the motion-aware method's): the frames, code,
    ``missing`` and ``sample_range`` checked, then :func:`run_window` over the whole clip."""
    f = check_frames(frames)
    code = check_identity_code(code)
    missing = as_missing(missing, f.shape[0])
    lo, hi = check_sample_range(f, missing, sample_range)
    return run_window(f, code, options, (lo, hi), missing=missing, device=device)


def run_window(f: np.ndarray, code: np.ndarray, options: MotionOptions, sample_range: tuple[float, float], *,
               missing=None, keep: tuple[int, int] | None = None, memo=None, device: str = "cpu",
               workspace=None) -> MotionAwareResult:
    """The motion-aware stages on checked ``frames`` (F, H, W) float32 and identity ``code``.

    ``sample_range``: the samples' range (:func:`check_sample_range`). ``keep`` = (s0, s1): only these
    sub-frames are wanted (a streaming run's window, :mod:`~flexvox_core.motion.streaming`): the
    trajectory gathers and the refinement run over them (and the refinement's reach around them)
    alone, and the result's ``video`` holds them alone — the same values as the whole run's (with
    a second pass, or dropped frames in the window, everything is gathered and then cut). Everything
    else (high-TR, flow, the fixed-tensor guides) is computed over the whole window.
    ``memo``: a :class:`~flexvox_core.flow.memo.FlowMemo` for the flow (CPU). ``device``: ``cpu``, ``cuda`` or
    ``auto`` (:func:`flexvox_core.gpu.resolve_device`); ``workspace``: the GPU's device buffers
    (:class:`~flexvox_core.gpu.volumes.Workspace`) to reuse, as a streaming run does from window to window.
    """
    window = Window.plan(f, code, options, sample_range, missing=missing, keep=keep)
    device, note = engine_for(options, device)
    if device == "cuda":
        from flexvox_core.motion.gpu.engine import CudaStages

        return run_stages(CudaStages(window, ws=workspace))
    result = run_stages(CpuStages(window, memo=memo))
    result.device_note = note
    return result


def engine_for(options: MotionOptions, device: str) -> tuple[str, str | None]:
    """(``cpu`` or ``cuda``, why the CPU when the GPU was asked for): ``device`` resolved
    (:func:`flexvox_core.gpu.resolve_device`), then the CPU for options the GPU's stages do not run as the CPU's
    (:func:`~flexvox_core.motion.stages.cuda_unsupported`), logged once per call as a warning."""
    if device == "cpu":
        return "cpu", None
    from flexvox_core.gpu.device import resolve_device

    if resolve_device(device) == "cpu":
        return "cpu", None
    why = cuda_unsupported(options)
    if why is None:
        return "cuda", None
    _logger.warning("motion-aware: %s", why)
    return "cpu", why
