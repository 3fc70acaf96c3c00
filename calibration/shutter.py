"""Shutter masks: a code tiled in camera pixels, turned into the projector's K patterns.

:func:`make_shutter_patterns` maps every projector pixel's centre through the calibrated
projector→camera homography to the *nearest* camera pixel and gives it that camera pixel's
slots (no blending: a mirror is on or off). Pattern ``j`` is shown in projector slot ``j``;
with a sync phase ``p`` (exposure slot ``t`` sees pattern ``(t + p) mod K``, see
:mod:`flexvox_calibration.sync`) pattern ``j`` carries code slot ``(j − p) mod K`` so that exposure
slot ``s`` sees code slot ``s``. :func:`~rig_drivers.dlpc350.bitplanes.pack_bitplanes`
packs them for the projector's video port.

:func:`verify_shutter` shows each slot's pattern alone (static), decodes which slot every
camera pixel sees (the brightest above black), and reports the fraction correct among the
decodable pixels and a map of the wrong ones.

A projector can address a camera pixel alone only where its pixels are smaller than the
camera's; where they are larger (scale > 1 camera px per projector px) some camera pixels
get no mirror of their own. :class:`ShutterPatterns` says so (``addressable``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.results import StepResult
from flexvox_core.codes import validate_code
from flexvox_core.forward import tiled_code
from flexvox_core.memory_budget import check_fits, shutter_pattern_bytes
from rig_drivers.dlpc350.bitplanes import pack_bitplanes
from rig_drivers.pixel_layout import mirror_centres

_logger = logging.getLogger(__name__)

CROSSTALK_RATIO = 0.75
"""A pixel whose second slot gets more than this fraction of its first one's light is crosstalk."""


@dataclass
class ShutterPatterns:
    """The K projector patterns of a shutter code.

    Attributes
    ----------
    patterns : ndarray (K, Hp, Wp) bool
        Pattern j is shown in projector slot j.
    packed : ndarray (ceil(K/24), Hp, Wp, 3) uint8
        The patterns as 24-bit video frames (DLPC350 bit-plane order).
    code : ndarray (m, n, K) bool
    phase_slots : int
        The sync phase the patterns were relabelled for.
    addressable : float
        Fraction of the camera's pixels (inside the projector's image) that hold the centre
        of at least one projector pixel: the ones a per-pixel shutter can reach alone.
    unaddressed : ndarray (H, W) bool
        Camera pixels (inside the projector's image) that no projector pixel centre reaches.
    """

    patterns: np.ndarray
    packed: np.ndarray
    code: np.ndarray
    phase_slots: int
    addressable: float
    unaddressed: np.ndarray
    notes: list = field(default_factory=list)

    @property
    def K(self) -> int:  # noqa: N802 - the field's name
        """Slots."""
        return int(self.patterns.shape[0])


def make_shutter_patterns(code, homography, camera_size, projector_size, *, phase_slots: int = 0,
                          layout: str = "square") -> ShutterPatterns:
    """The projector patterns that open each camera pixel in its code slot.

    Parameters
    ----------
    code : ndarray (m, n, K) bool
        Tiled over the camera from its top-left pixel (docs/architecture.md, "Conventions").
    homography : array (3, 3)
        Projector → camera.
    camera_size, projector_size : (H, W)
    phase_slots : int
        Sync phase to compensate (see the module docstring).
    layout : "square" or "diamond"
        How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`): each pixel takes the
        code of the camera pixel its mirror's centre lands on, odd rows of a diamond DMD half a
        pixel along. The homography maps mirror coordinates.

    Raises
    ------
    CalibrationError
        For a bad code, homography or phase.
    MemoryBudgetError
        (a ValueError) For patterns that would not fit in memory (a mistyped projector size, say).
    """
    try:
        c = validate_code(code)
    except ValueError as exc:
        raise CalibrationError(f"`code`: {exc}") from exc
    h = geometry.check_matrix(homography)
    H, W = (int(v) for v in camera_size)
    Hp, Wp = (int(v) for v in projector_size)
    K = c.shape[2]
    if isinstance(phase_slots, bool) or not isinstance(phase_slots, int | np.integer) or not 0 <= phase_slots < K:
        raise CalibrationError(f"`phase_slots` must be a whole number 0..{K - 1}; got {phase_slots!r}")
    check_fits(shutter_pattern_bytes(K, (Hp, Wp), (H, W)),
               f"making shutter patterns for a {Hp}x{Wp} projector at K = {K}",
               "check the projector size (capture --projector-size, or the rig profile's)")
    cam_code = tiled_code(c, H, W)  # (K, H, W)
    cam_xy = geometry.apply(h, mirror_centres((Hp, Wp), layout))
    with np.errstate(invalid="ignore"):
        xi = np.rint(cam_xy[..., 0])
        yi = np.rint(cam_xy[..., 1])
        inside = np.isfinite(xi) & np.isfinite(yi) & (xi >= 0) & (xi < W) & (yi >= 0) & (yi < H)
    xi = np.where(inside, xi, 0).astype(np.intp)
    yi = np.where(inside, yi, 0).astype(np.intp)
    code_pats = cam_code[:, yi, xi] & inside[None]
    patterns = np.roll(code_pats, int(phase_slots), axis=0)
    reached = np.zeros((H, W), bool)
    reached[yi[inside], xi[inside]] = True
    # Camera pixels inside the projector's image (the image of the projector's frame).
    cam_in_proj = geometry.apply(np.linalg.inv(h), geometry.pixel_grid((H, W)))
    lit = (cam_in_proj[..., 0] >= -0.5) & (cam_in_proj[..., 0] <= Wp - 0.5) & \
          (cam_in_proj[..., 1] >= -0.5) & (cam_in_proj[..., 1] <= Hp - 0.5)
    unaddressed = lit & ~reached
    addressable = float(reached[lit].mean()) if lit.any() else 0.0
    notes = []
    if addressable < 0.999:
        scale = geometry.describe(h, (H, W), (Hp, Wp)).scale
        notes.append(f"{1 - addressable:.1%} of the camera pixels hold no projector pixel centre (projector "
                     f"pixels are {scale:.2f} camera pixels wide): they cannot be shuttered alone and will see a "
                     "neighbour's slot. Use a projector finer than the camera over the field of view.")
    return ShutterPatterns(patterns, pack_bitplanes(patterns), c, int(phase_slots), addressable, unaddressed, notes)


@dataclass(kw_only=True)
class ShutterVerification(StepResult):
    """Which slot every camera pixel sees, against the code.

    Attributes
    ----------
    accuracy : float
        Fraction of decodable camera pixels that see their code slot.
    decodable : ndarray (H, W) bool
        Pixels with enough light from some slot to decide.
    seen_slot : ndarray (H, W) int
        The exposure slot each pixel sees (−1 where not decodable).
    expected_slot : ndarray (H, W) int
    wrong : ndarray (H, W) bool
        Decodable pixels that see another slot.
    crosstalk : float
        Fraction of decodable pixels whose second-brightest slot reaches more than
        :data:`CROSSTALK_RATIO` of the brightest (defocus or a coarse projector: the
        pixel samples two instants).
    """

    accuracy: float
    crosstalk: float
    decodable: np.ndarray
    seen_slot: np.ndarray
    expected_slot: np.ndarray
    wrong: np.ndarray
    decodable_fraction: float = 0.0

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {"status": self.status, "message": self.message, "warnings": list(self.warnings),
                "accuracy": self.accuracy, "crosstalk": self.crosstalk, "decodable_fraction": self.decodable_fraction,
                "wrong": int(self.wrong.sum())}


def verify_shutter(session, shutter: ShutterPatterns, *, min_accuracy: float = 0.999, min_contrast: float = 0.1,
                   progress: Callable[[int, int], None] | None = None) -> ShutterVerification:
    """Show each slot's pattern alone and check which slot every camera pixel sees.

    A pixel is decodable when its brightest slot exceeds black by ``min_contrast`` of the
    frame's median white − black (so pixels in shadow or outside the projector are left
    out, and counted in ``decodable_fraction``).

    Parameters
    ----------
    session : RigSession
        Opened.
    shutter : ShutterPatterns
        From :func:`make_shutter_patterns` (with ``phase_slots=0``: slots are shown one at
        a time, so the sync phase plays no part here).
    min_accuracy : float
        Status ``ok`` needs at least this fraction correct.
    """
    if not isinstance(shutter, ShutterPatterns):
        raise CalibrationError(f"`shutter` must be ShutterPatterns; got {type(shutter).__name__}")
    K = shutter.K
    Hp, Wp = shutter.patterns.shape[1:]
    black = session.capture(np.zeros((Hp, Wp), bool))
    white = session.capture(np.ones((Hp, Wp), bool))
    shots = []
    for j in range(K):
        shots.append(session.capture(shutter.patterns[j]) - black)
        if progress is not None:
            progress(j + 1, K)
    stack = np.stack(shots)
    # The slot shown as pattern j is code slot (j - phase) mod K.
    slot_of_pattern = (np.arange(K) - shutter.phase_slots) % K
    best = np.argmax(stack, axis=0)
    seen = slot_of_pattern[best]
    H, W = black.shape
    order = np.argmax(tiled_code(shutter.code, H, W), axis=0)
    ref = float(np.median(white - black))
    decodable = stack.max(axis=0) > min_contrast * max(ref, 1e-12)
    wrong = decodable & (seen != order)
    n = int(decodable.sum())
    seen_map = np.where(decodable, seen, -1)
    frac = float(decodable.mean())
    if n == 0:
        return ShutterVerification(status="no_light", message=(
            "no camera pixel saw any slot's light: the projector shows nothing in the camera"),
            accuracy=0.0, crosstalk=0.0, decodable=decodable, seen_slot=seen_map, expected_slot=order, wrong=wrong,
            decodable_fraction=frac)
    acc = 1.0 - float(wrong.sum()) / n
    if K > 1:
        top2 = np.sort(stack, axis=0)[-2:]
        cross = float((top2[0][decodable] > CROSSTALK_RATIO * top2[1][decodable]).mean())
    else:  # one slot: no neighbour's slot to get light from
        cross = 0.0
    warnings = list(shutter.notes)
    if cross > 0.01:
        warnings.append(f"{cross:.1%} of the pixels get a neighbour's slot at more than {CROSSTALK_RATIO:.0%} of "
                        "their own light: the projector is defocused on the target (or coarser than the camera); "
                        "focus it, or reconstruct with coarser divisions")
    if acc >= min_accuracy:
        status, msg = "ok", (f"{acc:.3%} of the {n} decodable camera pixels ({frac:.1%} of the frame) see their "
                             f"code slot ({int(wrong.sum())} wrong)")
    else:
        status, msg = "inaccurate", (
            f"only {acc:.2%} of the {n} decodable camera pixels see their code slot (at least {min_accuracy:.1%} "
            f"needed); {int(wrong.sum())} see another slot: recalibrate the homography, or the projector is too "
            "coarse / defocused for this code")
    _logger.info("shutter verification: %s", msg)
    return ShutterVerification(status=status, message=msg, warnings=warnings, accuracy=acc, crosstalk=cross,
                               decodable=decodable,
                               seen_slot=seen_map, expected_slot=order, wrong=wrong, decodable_fraction=frac)
