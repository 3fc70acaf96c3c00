"""What a capture records with, and its checks: the code, the timing and the projector's patterns.

A :class:`CapturePlan` is the operator's choice of code (a tile's designed identity code, its
S-matrix multiplexed code, or a ``flexvox design -o`` file), camera rate and exposure, and
projector pattern exposure. ``flexvox capture`` and the Capture workspace both build one.
:meth:`CapturePlan.timing` checks it against the projector's rules
(``rig_drivers.interfaces.check_pattern_timing``: exposure = period, or at most period − 230 µs;
1-bit patterns ≥ 235 µs) and the camera's exposure window, and says how fast a free-running
camera would drift (the projector counts whole µs). :meth:`CapturePlan.patterns` turns the code
into the projector's patterns through :func:`flexvox_calibration.shutter.make_shutter_patterns`, the one
function calibration verifies with: what was verified is what is projected.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from flexvox_calibration.capture_setup import CaptureCalibration
from flexvox_calibration.session import EXPOSURE_MARGIN_US
from flexvox_calibration.shutter import ShutterPatterns, make_shutter_patterns
from flexvox_core.codes import code_from_order, verify
from flexvox_core.divisions import Division
from flexvox_core.multiplex import MultiplexedCode, multiplexed_code
from flexvox_core.rates import MAX_CAMERA_HZ
from rig_drivers.errors import SettingError
from rig_drivers.interfaces import (
    MIN_DARK_US,
    MIN_EXPOSURE_1BIT_US,
    check_pattern_timing,
)

TILES = ((2, 2), (2, 4), (4, 2), (3, 5), (4, 4), (1, 7), (1, 3), (5, 7))
"""Tiles offered in the Capture workspace (multiplexed needs K ≡ 3 mod 4: 1×3, 1×7, 3×5, 5×7)."""


def pattern_period_us(camera_hz: float, K: int) -> int:
    """The projector's pattern period for ``K`` slots per camera frame at ``camera_hz``: whole µs, rounded down."""
    return int(1e6 // (float(camera_hz) * int(K)))


@dataclass(frozen=True)
class TimingCheck:
    """The projector/camera timing of a plan.

    Attributes
    ----------
    period_us : int
        Pattern period: floor(1e6 / (camera_hz · K)) whole µs.
    projector_exposure_us : int
    sequence_us : int
        K · period: one camera frame's worth of patterns.
    errors, notes : list of str
        Errors make the plan unusable; notes are worth reading.
    """

    period_us: int
    projector_exposure_us: int
    sequence_us: int
    camera_exposure_us: float
    errors: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """No errors."""
        return not self.errors


def designed_code(tile: tuple[int, int]) -> np.ndarray:
    """The tile's designed identity code (m, n, K) bool, a fresh copy. The design (``flexvox_core.design``, which
    loads scipy.optimize) runs once per tile and process; the application's start-up runs it for the remembered
    tile behind its start-up window."""
    return _designed(tuple(int(v) for v in tile)).copy()


@functools.lru_cache(maxsize=16)
def _designed(tile: tuple[int, int]) -> np.ndarray:
    from flexvox_core.design import design_code  # scipy.optimize: only when a code is designed

    return design_code(tile).require()


@dataclass(frozen=True)
class CapturePlan:
    """What the operator chose for a capture.

    The code is a tile's designed identity code (``tile``), its S-matrix code (``multiplexed``), or
    one given explicitly (:meth:`from_code`, :meth:`from_code_file`), which is held in the fields
    ``order`` or ``placement``: a plan compares, prints and copies (``dataclasses.replace``) with
    its code.

    Parameters
    ----------
    tile : (m, n)
    multiplexed : bool
        An S-matrix code (K ≡ 3 mod 4) instead of an identity code.
    camera_hz : float
    camera_exposure_us : float or None
        Camera exposure; default one sequence less :data:`~flexvox_calibration.session.EXPOSURE_MARGIN_US`
        of read-out before the next trigger.
    projector_exposure_us : int or None
        Pattern exposure; default the period (what the video port needs).
    order : tuple of tuples, optional
        An identity code's firing order (m rows of slot numbers); default the tile's designed one.
    placement : tuple of tuples, optional
        A multiplexed code's placement order (where its demultiplexed slots go); default the designed one.
    code_file : Path, optional
        Where the code came from (a ``flexvox design -o`` file), for the record.
    """

    tile: tuple[int, int] = (4, 4)
    multiplexed: bool = False
    camera_hz: float = 15.0
    camera_exposure_us: float | None = None
    projector_exposure_us: int | None = None
    order: tuple | None = None
    placement: tuple | None = None
    code_file: Path | None = None

    def __post_init__(self):
        hz = self.camera_hz
        if (isinstance(hz, bool) or not isinstance(hz, int | float) or not math.isfinite(hz)
                or not 0 < hz <= MAX_CAMERA_HZ):
            raise ValueError(f"`camera_hz` must be a rate above 0 and at most {MAX_CAMERA_HZ:g} Hz; got {hz!r}")
        cam = self.camera_exposure_us  # -1 had been timed as "misses the last 17 of 16 slots", NaN failed at start
        if cam is not None and (isinstance(cam, bool) or not isinstance(cam, int | float | np.integer | np.floating)
                                or not math.isfinite(cam) or cam <= 0):
            raise ValueError(f"`camera_exposure_us` must be a finite number of µs above 0, or None (the default "
                             f"exposure); got {cam!r}")
        proj = self.projector_exposure_us  # 1.5 had been cut to 1 µs
        if proj is not None and (isinstance(proj, bool) or not isinstance(proj, int | np.integer) or proj <= 0):
            raise ValueError(f"`projector_exposure_us` must be a whole number of µs above 0, or None (the pattern "
                             f"period); got {proj!r}")
        if not isinstance(self.multiplexed, bool | np.bool_):  # multiplexed="no" had captured an S-matrix code
            raise ValueError(f"`multiplexed` must be True or False; got {self.multiplexed!r}")
        object.__setattr__(self, "multiplexed", bool(self.multiplexed))
        if isinstance(self.tile, str):  # "4x4": the one spelling of sizes everywhere (a bad one refused by its rule)
            from flexvox_core.tiles import parse_tile

            object.__setattr__(self, "tile", parse_tile(self.tile))
        try:
            tile = tuple(self.tile)
        except TypeError:
            tile = ()
        if (len(tile) != 2 or not all(isinstance(v, int | np.integer) and not isinstance(v, bool) or
                                      isinstance(v, float | np.floating) and float(v).is_integer() for v in tile)
                or min(tile) < 1):  # (4, 4.7) had been read as (4, 4)
            raise ValueError(f"`tile` must be two whole numbers (m, n) >= 1; got {self.tile!r}")
        tile = tuple(int(v) for v in tile)
        object.__setattr__(self, "tile", tile)
        for name in ("order", "placement"):
            v = getattr(self, name)
            if v is not None:
                arr = np.asarray(v)
                if arr.shape != tile:
                    raise ValueError(f"`{name}` must have the tile's shape {tile}; got {arr.shape}")
                object.__setattr__(self, name, tuple(tuple(int(x) for x in row) for row in arr))
        if self.order is not None and self.multiplexed:
            raise ValueError("`order` is an identity code's; a multiplexed plan takes a `placement`")
        if self.placement is not None and not self.multiplexed:
            raise ValueError("`placement` goes with a multiplexed plan")

    @classmethod
    def from_code(cls, code, **options) -> CapturePlan:
        """A plan with a given code: an identity code ``(m, n, K)`` or a :class:`MultiplexedCode`."""
        from flexvox_core.codes import is_identity_code, order_from_code, validate_code

        if isinstance(code, MultiplexedCode):
            return cls(tile=code.tile, multiplexed=True, placement=code.placement, **options)
        code = validate_code(code)
        if not is_identity_code(code):
            raise ValueError("`code` must be an identity code (each pixel open in one slot, each slot once per "
                             "tile) or a MultiplexedCode")
        return cls(tile=tuple(code.shape[:2]), order=order_from_code(code), **options)

    @classmethod
    def from_code_file(cls, path, **options) -> CapturePlan:
        """A plan with the code of a ``flexvox design -o`` file (``CodeFileError`` when it cannot shutter)."""
        from flexvox_core.code_file import load_shutter_code

        path = Path(path)
        return cls.from_code(load_shutter_code(path), code_file=path, **options)

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per camera frame."""
        return self.tile[0] * self.tile[1]

    @cached_property
    def shutter_code(self) -> np.ndarray | MultiplexedCode:
        """The code as capture records it: an identity code, or the multiplexed code (which says how to
        demultiplex). Raises ValueError for an impossible choice."""
        if self.multiplexed:
            return multiplexed_code(self.tile, placement=self.placement)
        if self.order is not None:
            return code_from_order(self.order)
        return designed_code(self.tile)

    @property
    def code(self) -> np.ndarray:
        """The shutter code (m, n, K) bool: which slots each tile pixel is open in."""
        sc = self.shutter_code
        return sc.code if isinstance(sc, MultiplexedCode) else sc

    def resolutions(self) -> list[Division]:
        """The [TR, SR] choices the code supports after capture (multiplexed: of its placement order)."""
        sc = self.shutter_code
        if isinstance(sc, MultiplexedCode):
            return verify(code_from_order(sc.placement)).supported
        return verify(sc).supported

    def code_summary(self) -> str:
        """One line about the code."""
        sc = self.shutter_code
        where = f" from {self.code_file.name}" if self.code_file is not None else ""
        if isinstance(sc, MultiplexedCode):
            return (f"S-matrix multiplexed{where}, K = {sc.K}: light throughput {sc.throughput:.0%} "
                    f"(identity {1 / sc.K:.0%}); SNR ×{sc.snr_gain_read:.2f} read-noise-limited, "
                    f"×{sc.snr_gain_photon:.2f} photon-limited")
        return f"identity code{where}, K = {self.K}, each pixel open in 1 of {self.K} slots"

    @property
    def period_us(self) -> int:
        """Pattern period in whole µs."""
        return pattern_period_us(self.camera_hz, self.K)

    def timing(self) -> TimingCheck:
        """Check the plan against the projector's and camera's rules."""
        errors, notes = [], []
        period = self.period_us
        proj = period if self.projector_exposure_us is None else int(self.projector_exposure_us)
        seq = self.K * period
        try:
            check_pattern_timing(proj, period)
        except SettingError as exc:
            errors.append(f"projector: {exc}")
        if period < MIN_EXPOSURE_1BIT_US:
            errors.append(f"projector: {self.camera_hz:g} Hz × K = {self.K} needs {period} µs patterns; the "
                          f"projector's shortest is {MIN_EXPOSURE_1BIT_US} µs: a DLPC350 shows 1-bit patterns no "
                          f"shorter than {MIN_EXPOSURE_1BIT_US} µs (at most "
                          f"{1e6 / (MIN_EXPOSURE_1BIT_US * self.K):.0f} Hz at this K)")
        if proj != period:
            notes.append(f"pattern exposure {proj} µs < period {period} µs (≥ {MIN_DARK_US} µs dark): "
                         "fine from flash, but the video port needs exposure = period")
        cam = max(1.0, seq - EXPOSURE_MARGIN_US) if self.camera_exposure_us is None else float(self.camera_exposure_us)
        frame_us = 1e6 / self.camera_hz
        if cam > frame_us:
            errors.append(f"camera: exposure {cam:.0f} µs is longer than the frame period {frame_us:.0f} µs")
        elif cam > seq:
            notes.append(f"camera: exposure {cam:.0f} µs is longer than the {self.K} patterns ({seq} µs): "
                         "it also sees the next sequence's first slots")
        elif cam < seq - period:
            missed = math.ceil((seq - cam) / period)
            errors.append(f"camera: exposure {cam:.0f} µs misses the last {missed} of {self.K} slots "
                          f"(one sequence is {seq} µs)")
        drift = frame_us - seq
        if drift > 1e-6:
            notes.append(f"the projector counts whole µs: {self.K} × {period} µs = {seq / 1000:.3f} ms < "
                         f"{frame_us / 1000:.3f} ms, so a free-running camera drifts one slot every "
                         f"{_duration(period / drift / self.camera_hz)}: trigger it from TRIG_OUT_2 or the sync box")
        return TimingCheck(period, proj, seq, cam, tuple(errors), tuple(notes))

    def patterns(self, camera_size: tuple[int, int], projector_size: tuple[int, int],
                 calibration: CaptureCalibration | None = None, *, layout: str = "square") -> ShutterPatterns:
        """The projector's patterns for this plan through ``calibration`` (default: uncalibrated).

        :func:`flexvox_calibration.shutter.make_shutter_patterns` with the calibration's homography and the
        phase :meth:`flexvox_calibration.capture_setup.CaptureCalibration.for_plan` gives at this plan's timing:
        exactly the patterns calibration verifies, relabelled for the phase. ``layout`` is the
        projector's pixel layout (its driver's ``pixel_layout``).
        """
        cal = calibration or CaptureCalibration()
        phase, _delay, _warnings = cal.for_plan(self.K, self.period_us)
        return make_shutter_patterns(self.code, cal.homography, camera_size, projector_size, phase_slots=phase,
                                     layout=layout)


def _duration(seconds: float) -> str:
    """A time in words a timing note can give: "12 s", "1.5 s", "40 ms"."""
    if seconds >= 10:
        return f"{seconds:.0f} s"
    if seconds >= 1:
        return f"{seconds:.1f} s"
    return f"{seconds * 1000:.0f} ms"
