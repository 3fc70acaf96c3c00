"""Capture settings and their checks (Qt-free model of the Capture workspace).

A :class:`CapturePlan` is the operator's choice of code (tile, identity or multiplexed),
camera rate and exposure, and projector pattern exposure. :meth:`CapturePlan.timing` checks
it against the projector's rules (``rig_drivers.interfaces.check_pattern_timing``: exposure =
period, or at most period − 230 µs; 1-bit patterns ≥ 235 µs) and the camera's exposure window,
and says how fast a free-running camera would drift (the projector counts whole µs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from flexvox_core.codes import code_from_order, verify
from flexvox_core.design import design_code
from flexvox_core.divisions import Division
from flexvox_core.forward import tiled_code
from flexvox_core.multiplex import multiplexed_code
from rig_drivers.errors import SettingError
from rig_drivers.interfaces import (
    MIN_DARK_US,
    MIN_EXPOSURE_1BIT_US,
    PatternSequence,
    ProjectorTrigger,
    check_pattern_timing,
)

TILES = ((2, 2), (2, 4), (4, 2), (3, 5), (4, 4), (1, 7), (1, 3), (5, 7))
"""Tiles offered in the Capture workspace (multiplexed needs K ≡ 3 mod 4: 1×3, 1×7, 3×5, 5×7)."""


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
    errors: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """No errors."""
        return not self.errors


@dataclass(frozen=True)
class CapturePlan:
    """What the operator chose in the Capture workspace.

    Parameters
    ----------
    tile : (m, n)
    multiplexed : bool
        An S-matrix code (K ≡ 3 mod 4) instead of the designed identity code.
    camera_hz : float
    camera_exposure_us : float or None
        Camera exposure; default one sequence (K · period).
    projector_exposure_us : int or None
        Pattern exposure; default the period (what the video port needs).
    """

    tile: tuple[int, int] = (4, 4)
    multiplexed: bool = False
    camera_hz: float = 15.0
    camera_exposure_us: float | None = None
    projector_exposure_us: int | None = None

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per camera frame."""
        return self.tile[0] * self.tile[1]

    @cached_property
    def code(self) -> np.ndarray:
        """The shutter code (m, n, K) bool. Raises ValueError for an impossible choice."""
        if self.multiplexed:
            return multiplexed_code(self.tile).code
        result = design_code(self.tile)
        if not result.success:
            raise ValueError(f"no code for a {self.tile[0]}x{self.tile[1]} tile: {result.message}")
        return result.code

    def resolutions(self) -> list[Division]:
        """The [TR, SR] choices the code supports after capture (multiplexed: of its placement order)."""
        if self.multiplexed:
            return verify(code_from_order(multiplexed_code(self.tile).placement)).supported
        return verify(self.code).supported

    def code_summary(self) -> str:
        """One line about the code."""
        if self.multiplexed:
            mc = multiplexed_code(self.tile)
            return (f"S-matrix multiplexed, K = {mc.K}: light throughput {mc.throughput:.0%} "
                    f"(identity {1 / mc.K:.0%}); SNR ×{mc.snr_gain_read:.2f} read-noise-limited, "
                    f"×{mc.snr_gain_photon:.2f} photon-limited")
        return f"identity code, K = {self.K}, each pixel open in 1 of {self.K} slots"

    @property
    def period_us(self) -> int:
        """Pattern period in whole µs."""
        return int(1e6 // (self.camera_hz * self.K))

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
            errors.append(f"projector: {self.camera_hz:g} Hz × K = {self.K} needs {period} µs patterns; "
                          f"the DLPC350 shows 1-bit patterns no shorter than {MIN_EXPOSURE_1BIT_US} µs "
                          f"(at most {1e6 / (MIN_EXPOSURE_1BIT_US * self.K):.0f} Hz at this K)")
        if proj != period:
            notes.append(f"pattern exposure {proj} µs < period {period} µs (≥ {MIN_DARK_US} µs dark): "
                         "fine from flash, but the video port needs exposure = period")
        cam = seq if self.camera_exposure_us is None else float(self.camera_exposure_us)
        frame_us = 1e6 / self.camera_hz
        if cam > frame_us:
            errors.append(f"camera: exposure {cam:.0f} µs is longer than the frame period {frame_us:.0f} µs")
        elif cam > seq:
            notes.append(f"camera: exposure {cam:.0f} µs is longer than the {self.K} patterns ({seq} µs): "
                         "it also sees the next sequence's first slots")
        elif cam < seq - period:
            missed = math.ceil((seq - cam) / period) - 0
            errors.append(f"camera: exposure {cam:.0f} µs misses the last {missed} of {self.K} slots "
                          f"(one sequence is {seq} µs)")
        drift = frame_us - seq
        if drift > 1e-6:
            notes.append(f"the projector counts whole µs: {self.K} × {period} µs = {seq / 1000:.3f} ms < "
                         f"{frame_us / 1000:.3f} ms, so a free-running camera drifts one slot every "
                         f"{period / drift / self.camera_hz:.0f} s: trigger it from TRIG_OUT_2 or the sync box")
        return TimingCheck(period, proj, seq, tuple(errors), tuple(notes))

    def sequence(self, projector_size: tuple[int, int], *, camera_size: tuple[int, int] | None = None,
                 calibration=None) -> PatternSequence:
        """The pattern sequence for a projector of ``projector_size`` (H, W) pixels, one trigger out per frame.

        Without ``calibration`` the code is tiled over the projector (an identity map). With a
        :class:`~app.capture.service.CaptureCalibration` and the ``camera_size``, the patterns are the
        capture service's (:func:`app.capture.patterns.shutter_patterns`: through the homography, phase
        compensated), so the live view shutters the camera as a recording will.
        """
        H, W = projector_size
        t = self.timing()
        if calibration is None:
            patterns = tiled_code(self.code, H, W)
        else:
            from app.capture.patterns import shutter_patterns

            if camera_size is None:
                raise ValueError("`camera_size` is needed with a `calibration`")
            patterns = shutter_patterns(self.code, camera_size, (H, W), homography=calibration.homography,
                                        phase_slots=int(calibration.phase_slots) % self.K)
        return PatternSequence(patterns, exposure_us=t.projector_exposure_us,
                               period_us=t.period_us, trigger=ProjectorTrigger.INTERNAL)
