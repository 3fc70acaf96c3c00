"""Synchronisation: which projected slot lands in which exposure slot, the sub-slot delay,
and whether frames arrive without drops or drift.

Why a single-shot sequence
--------------------------
A camera exposure of exactly one sequence (K slots) sees every pattern of a *repeating*
sequence once, whatever the phase, so a still target cannot show the phase. A sequence
played **once** can: the exposure opens ``p + f`` slots after the sequence starts (phase
``p``, sub-slot fraction ``f``, from TRIG_OUT_2 latency or the sync box), so the patterns
shown before it opened are missing from the image. :func:`measure_sync` plays a *band
code* once (pattern k lights the k-th vertical band of the projector's image, so each
camera pixel away from a band edge belongs to exactly one slot) and measures, per slot,
the fraction of its light that reached the exposure:

.. math::  b_k = \\frac{\\sum_{band\\ k} (I_{once} − I_{dark})}{\\sum_{band\\ k} (I_{repeat} − I_{dark})}

— the **leakage curve**: 0 for slots before the exposure, ``1 − f`` for slot ``p``, 1 after.
The light lost, ``L = Σ_k (1 − b_k) = p + f``, gives both at once. Sweeping the camera's
trigger delay ``d`` shifts the exposure further: ``L(d) = p + f + d / period``, a line
whose slope (≈ 1) checks the units and whose intercept is the estimate.

The recommended camera trigger delay ``(1 − f)·period`` makes the exposure open on a slot
boundary (then exposure slot ``t`` sees pattern ``(t + p') mod K`` with ``p' = p + 1`` when
``f > 0``): give ``p'`` to :func:`flexvox_calibration.shutter.make_shutter_patterns`.

:func:`check_frames` reads N frames of a repeating sequence and reports frame-id gaps,
long inter-arrival times and drift against the sequence period.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.files import check_identity, read_versioned, write_versioned
from flexvox_calibration.results import StepResult
from rig_drivers.errors import DeviceTimeoutError

_logger = logging.getLogger(__name__)

SYNC_FORMAT = "flexvox-sync-profile"
SYNC_VERSION = 1

EDGE_GUARD_PX = 2.0
"""Camera pixels whose projector column is within this many projector pixels of a band edge are left out."""


def band_patterns(homography, camera_size, projector_size, K: int) -> tuple[np.ndarray, np.ndarray]:
    """K vertical bands over the part of the projector the camera sees.

    Returns
    -------
    patterns : ndarray (K, Hp, Wp) bool
        Pattern k lights band k only.
    band : ndarray (H, W) int
        The band of each camera pixel, −1 near band edges and outside the projector.
    """
    h = geometry.check_matrix(homography)
    H, W = camera_size
    Hp, Wp = projector_size
    proj = geometry.apply(np.linalg.inv(h), geometry.pixel_grid((H, W)))
    u = proj[..., 0]
    inside = np.isfinite(u) & (u >= -0.5) & (u <= Wp - 0.5) & (proj[..., 1] >= -0.5) & (proj[..., 1] <= Hp - 0.5)
    if not inside.any():
        raise CalibrationError("the homography puts the camera frame outside the projector: recalibrate it")
    lo, hi = max(-0.5, float(np.nanmin(u[inside]))), min(Wp - 0.5, float(np.nanmax(u[inside])))
    edges = np.linspace(lo, hi, K + 1)
    cols = np.arange(Wp)
    col_band = np.clip(np.searchsorted(edges, cols, side="right") - 1, 0, K - 1)
    col_band = np.where((cols >= edges[0]) & (cols <= edges[-1]), col_band, -1)
    patterns = np.zeros((K, Hp, Wp), bool)
    for k in range(K):
        patterns[k][:, col_band == k] = True
    # Band of the projector column each camera pixel sees (mirror x covers [x-1/2, x+1/2]).
    col = np.rint(np.where(inside, u, -1)).astype(int)
    band = np.where(inside & (col >= 0) & (col < Wp), col_band[np.clip(col, 0, Wp - 1)], -1)
    # Guard: stay away from the band edges (in projector columns, mirror edges at x ± 1/2).
    lo_edge = np.array([cols[col_band == k].min() - 0.5 if (col_band == k).any() else np.inf for k in range(K)])
    hi_edge = np.array([cols[col_band == k].max() + 0.5 if (col_band == k).any() else -np.inf for k in range(K)])
    safe = band >= 0
    safe[safe] &= (u[safe] - lo_edge[band[safe]] >= EDGE_GUARD_PX) & (hi_edge[band[safe]] - u[safe] >= EDGE_GUARD_PX)
    return patterns, np.where(safe, band, -1)


@dataclass(kw_only=True)
class SyncResult(StepResult):
    """Phase and sub-slot delay of the camera exposure against the projector sequence.

    Statuses: ``ok``; ``no_trigger`` (no frame: the camera is not triggered by the rig);
    ``no_light`` (the bands are not seen); ``no_overlap`` (the exposure opens after the
    sequence); ``inconsistent`` (the sweep is not a line of slope 1: the camera is not
    synchronised to the projector).

    Attributes
    ----------
    K, period_us : int
    phase_slots : int or None
        Exposure slot t sees pattern (t + phase_slots) mod K (camera delay 0).
    delay_us : float or None
        Sub-slot delay of the exposure after that slot's start.
    offset_slots : float
        ``phase_slots + delay_us / period_us``.
    leakage : list of float
        ``b_k`` at camera delay 0 (see the module docstring).
    sweep : list of (delay_us, lost_slots)
    slope : float
        Fitted slope of the sweep (1 expected).
    recommended_camera_delay_us : float
        Camera trigger delay that opens the exposure on a slot boundary.
    effective_phase_slots : int
        The phase with that delay: give it to the shutter patterns.
    """

    K: int
    period_us: int
    phase_slots: int | None = None
    delay_us: float | None = None
    offset_slots: float = float("nan")
    leakage: list = field(default_factory=list)
    sweep: list = field(default_factory=list)
    slope: float = float("nan")
    recommended_camera_delay_us: float = 0.0
    effective_phase_slots: int | None = None
    residual_leakage: float = float("nan")

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {"status": self.status, "message": self.message, "warnings": list(self.warnings), "K": self.K,
                "period_us": self.period_us, "phase_slots": self.phase_slots, "delay_us": self.delay_us,
                "offset_slots": self.offset_slots, "leakage": list(self.leakage),
                "sweep": [list(p) for p in self.sweep], "slope": self.slope,
                "recommended_camera_delay_us": self.recommended_camera_delay_us,
                "effective_phase_slots": self.effective_phase_slots, "residual_leakage": self.residual_leakage}


def boundary_phase(phase_slots: int, camera_delay_us: float, K: int) -> int:
    """The phase the shutter patterns use once the camera's trigger is delayed by ``camera_delay_us``.

    A delay that moves the exposure's opening to the next slot boundary shifts every exposure slot one
    pattern later: phase + 1 (mod K); no delay keeps the phase.
    """
    return int(phase_slots) % K if camera_delay_us <= 0 else (int(phase_slots) + 1) % K


def _no_trigger_message(exc: Exception) -> str:
    return (f"the camera delivered no frame: it is not synchronised to the projector ({exc}). Wire the "
            "projector's TRIG_OUT_2 (or the sync box's frame output) to the camera's trigger line and set "
            "that line in the rig profile")


def _slot_light(frame: np.ndarray, dark: np.ndarray, band: np.ndarray, K: int) -> np.ndarray:
    d = frame - dark
    return np.array([d[band == k].sum() for k in range(K)])


def _lost_slots(b: np.ndarray) -> float:
    """``Σ (1 − b_k)`` with slots clearly dark (b < 0.05) or clearly whole (b > 0.95) snapped to 0/1.

    Snapping keeps the noise of the K − 2 slots away from the transition out of the sum
    (clipping instead would bias it: noise would only ever add lost light).
    """
    snapped = np.where(b < 0.05, 0.0, np.where(b > 0.95, 1.0, b))
    return float(np.sum(1 - snapped))


def measure_sync(session, homography, *, K: int = 16, sweep_steps: int = 8,
                 progress: Callable[[int, int], None] | None = None) -> SyncResult:
    """Find the phase and sub-slot delay with a single-shot band code and a delay sweep.

    Parameters
    ----------
    session : RigSession
        Opened, with a hardware-triggered camera.
    homography : array (3, 3)
        Projector → camera, from :func:`flexvox_calibration.homography.calibrate_homography`.
    K : int
        Slots per exposure.
    sweep_steps : int
        Camera delays ``0, P/steps, ..., (steps−1)·P/steps`` (P the slot period).
    """
    if isinstance(K, bool) or not isinstance(K, int) or not 2 <= K <= 128:
        raise CalibrationError(f"`K` must be a whole number 2..128; got {K!r}")
    if isinstance(sweep_steps, bool) or not isinstance(sweep_steps, int) or not 1 <= sweep_steps <= 64:
        raise CalibrationError(f"`sweep_steps` must be a whole number 1..64; got {sweep_steps!r}")
    period = session.period_us
    base = dict(K=K, period_us=period)
    patterns, band = band_patterns(homography, session.camera_size, session.projector_size, K)
    counts = np.bincount(band[band >= 0], minlength=K)
    if counts.min() < 10:
        raise CalibrationError(f"the camera sees too little of the projector for {K} bands: calibrate the "
                               "homography first, or use a smaller K")
    total = sweep_steps + 2
    saved_delay = session.camera_delay_us
    try:
        session.set_camera_delay(0.0)
        dark = session.capture_single_shot(np.zeros_like(patterns))
        session.show(patterns, repeat=True)
        ref = np.mean([f.image.astype(np.float64) for f in session.frames(2)], axis=0)
        if progress is not None:
            progress(2, total)
        full = _slot_light(ref, dark, band, K)
        noise = math.sqrt(max(float(np.var(ref - dark)), 1e-12))
        if full.min() <= 3 * noise * math.sqrt(counts.min()):
            return SyncResult(status="no_light", message=(
                "the projector's bands are not seen in the camera: check the projector and the homography"), **base)
        sweep, leakage = [], []
        for i in range(sweep_steps):
            d = i * period / sweep_steps
            session.set_camera_delay(d)
            b = _slot_light(session.capture_single_shot(patterns), dark, band, K) / full
            if i == 0:
                leakage = [float(v) for v in b]
            sweep.append((float(d), _lost_slots(b)))
            if progress is not None:
                progress(i + 3, total)
    except DeviceTimeoutError as exc:
        return SyncResult(status="no_trigger", message=_no_trigger_message(exc), **base)
    finally:
        try:
            session.set_camera_delay(saved_delay)
        except DeviceTimeoutError:  # pragma: no cover - the camera has just failed already
            _logger.warning("could not restore the camera trigger delay")
    usable = [(d, lost) for d, lost in sweep if lost < K - 0.05]
    if not usable:
        return SyncResult(status="no_overlap", message=(
            f"no slot of a single-shot sequence reached the exposure: the camera exposure opens more than {K} "
            "slots after the sequence starts (a trigger on the wrong edge, or from the wrong output?)"),
            leakage=leakage, sweep=sweep, **base)
    ds = np.array([u[0] for u in usable]) / period
    ls = np.array([u[1] for u in usable])
    if len(usable) >= 2:
        slope, intercept = np.polyfit(ds, ls, 1)
    else:
        slope, intercept = 1.0, float(ls[0] - ds[0])
    if not 0.8 <= slope <= 1.2 or intercept < -0.25:
        return SyncResult(status="inconsistent", message=(
            f"the light lost does not grow with the camera delay as it must (slope {slope:.2f}, expected 1): the "
            "camera is not synchronised to the projector (free-running, or triggered by something else)"),
            leakage=leakage, sweep=sweep, slope=float(slope), **base)
    offset = max(0.0, float(intercept))
    phase = int(math.floor(offset + 1e-9)) % K
    frac = offset - math.floor(offset + 1e-9)
    delay = frac * period
    rec = 0.0 if frac < 1e-3 else (1 - frac) * period
    eff = boundary_phase(phase, rec, K)
    warnings = []
    if min(frac, 1 - frac) < 0.05:
        warnings.append(f"the exposure opens within 5 % of a slot boundary ({frac:.2f} slot): the phase could be "
                        f"{phase} or {(phase + 1) % K}; use the recommended camera delay")
    msg = (f"exposure slot 0 sees projected slot {phase}, {delay:.0f} µs late ({frac:.2f} slot); set the camera "
           f"trigger delay to {rec:.0f} µs and use phase {eff} for the shutter patterns")
    _logger.info("sync: %s", msg)
    return SyncResult(status="ok", message=msg, warnings=warnings, phase_slots=phase, delay_us=float(delay),
                      offset_slots=offset, leakage=leakage, sweep=sweep, slope=float(slope),
                      recommended_camera_delay_us=float(rec), effective_phase_slots=eff, **base)


@dataclass(kw_only=True)
class FrameCheck(StepResult):
    """Frame ids and arrival times of N frames of a repeating sequence.

    Statuses: ``ok``, ``dropped_frames``, ``drifting``, ``no_trigger``.

    Attributes
    ----------
    frames : int
        Frames read.
    gaps : int
        Frames missing between the first and last id.
    long_intervals : int
        Inter-arrival times over 1.5× the expected period (per id step).
    frame_period_us : float
        Measured (fit of timestamps against ids).
    expected_period_us : int
        K · slot period.
    drift_us_per_frame : float
        ``frame_period_us − expected_period_us``.
    seconds_per_slot_slip : float
        How long until the exposure slips by one slot (inf without drift).
    """

    frames: int = 0
    gaps: int = 0
    long_intervals: int = 0
    frame_period_us: float = float("nan")
    expected_period_us: int = 0
    drift_us_per_frame: float = float("nan")
    seconds_per_slot_slip: float = float("inf")

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {"status": self.status, "message": self.message, "frames": self.frames, "gaps": self.gaps,
                "long_intervals": self.long_intervals, "frame_period_us": self.frame_period_us,
                "expected_period_us": self.expected_period_us, "drift_us_per_frame": self.drift_us_per_frame,
                "seconds_per_slot_slip": self.seconds_per_slot_slip}


def check_frames(session, patterns, n: int = 30, *, max_drift_us_per_frame: float = 0.5) -> FrameCheck:
    """Run ``patterns`` (a repeating sequence) and check ``n`` frames for drops and drift.

    Parameters
    ----------
    session : RigSession
    patterns : ndarray (K, Hp, Wp) bool
    n : int
        Frames to read (at least 3).
    max_drift_us_per_frame : float
        Larger |drift| is reported as ``drifting``.
    """
    if isinstance(n, bool) or not isinstance(n, int) or n < 3:
        raise CalibrationError(f"`n` must be a whole number >= 3; got {n!r}")
    pats = np.asarray(patterns, dtype=bool)
    expected = int(pats.shape[0] * session.period_us)
    try:
        session.show(pats, repeat=True)
        frames = session.frames(n)
    except DeviceTimeoutError as exc:
        return FrameCheck(status="no_trigger", message=_no_trigger_message(exc), expected_period_us=expected)
    ids = np.array([f.frame_id for f in frames])
    ts = np.array([f.timestamp_s for f in frames]) * 1e6
    steps = np.diff(ids)
    gaps = int(np.sum(steps - 1))
    intervals = np.diff(ts)
    long_ = int(np.sum(intervals > 1.5 * expected * steps))
    period, _ = np.polyfit(ids.astype(np.float64), ts, 1)
    drift = float(period - expected)
    slip = math.inf if abs(drift) < 1e-9 else session.period_us / abs(drift) * period / 1e6
    base = dict(frames=len(frames), gaps=gaps, long_intervals=long_, frame_period_us=float(period),
                expected_period_us=expected, drift_us_per_frame=drift, seconds_per_slot_slip=float(slip))
    if abs(drift) > max_drift_us_per_frame:
        return FrameCheck(status="drifting", message=(
            f"the camera's frame period is {period:.1f} µs but a sequence lasts {expected} µs: the exposure slips "
            f"by one slot every {slip:.0f} s. Trigger the camera from the projector (TRIG_OUT_2) or the sync box "
            "instead of letting it run free"), **base)
    if gaps or long_:
        return FrameCheck(status="dropped_frames", message=(
            f"{gaps} of {ids[-1] - ids[0] + 1} frames were dropped (frame-id gaps), {long_} late arrivals: "
            "lower the frame rate or the image size, or use a faster link"), **base)
    return FrameCheck(status="ok", message=f"{len(frames)} frames, no gaps, period {period:.1f} µs (no drift)",
                      **base)


def save_sync_profile(path, result: SyncResult, identity, *, frame_check: FrameCheck | None = None,
                      overwrite: bool = False, now=None) -> Path:
    """Write a sync profile (versioned JSON) for a successful :class:`SyncResult`, atomically;
    an existing file only with ``overwrite``."""
    if not isinstance(result, SyncResult):
        raise CalibrationError(f"`result` must be a SyncResult; got {type(result).__name__}")
    if not result.success:
        raise CalibrationError(f"refusing to save a failed sync measurement ({result.status}): {result.message}")
    body = {"sync": result.summary(), "frame_check": None if frame_check is None else frame_check.summary()}
    return write_versioned(path, SYNC_FORMAT, SYNC_VERSION, identity, body, overwrite=overwrite, now=now)


def load_sync_profile(path, identity=None) -> dict:
    """Read a sync profile; with ``identity``, refuse one made for another rig."""
    data = read_versioned(path, SYNC_FORMAT, SYNC_VERSION)
    if identity is not None:
        check_identity(data, identity, path)
    return data


__all__ = ["FrameCheck", "SyncResult", "band_patterns", "boundary_phase", "check_frames", "load_sync_profile",
           "measure_sync", "save_sync_profile"]
