"""Projector–camera homography: Gray code + binary phase shifting, decode, RANSAC fit.

:func:`capture_correspondences` shows black and white frames (twice each: the shadow mask
and the noise level), the Gray code and the phase-shift patterns through a
:class:`~flexvox_calibration.session.RigSession` (which only accepts frames exposed after each
pattern change), and decodes, per camera pixel, the projector point it sees, to sub-pixel
precision (see :mod:`flexvox_calibration.structured_light`). :func:`fit_homography` fits one
homography to them with RANSAC (:func:`cv2.findHomography`), refits on the inliers, and
judges the result: RMS reprojection error, inliers, coverage, a residual map, and the
geometry (mirrored, nearly singular, folded). :func:`calibrate_homography` does both.

Statuses of :class:`HomographyResult`:

``ok``
    A sound homography from a well covered frame.
``no_projector_light``
    White and black frames do not differ: the projector shows nothing in the camera.
``too_dark``
    The projected contrast is too weak against the noise to decode.
``too_few_points``
    Too few decoded pixels, or too few RANSAC inliers, for a trustworthy fit.
``degenerate``
    The fit is nearly singular or folds the frame.
``partial``
    A sound fit, but part of the frame was not decoded (in shadow): it is extrapolated there.
``no_frames``
    The camera delivered no frame (it is not triggered by the projector / sync box).
``inconsistent``
    The RMS residual is too large: decoding errors or a rig that is not co-located.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.results import StepResult
from flexvox_calibration.structured_light import (
    decode_gray,
    decode_phase,
    gray_code_patterns,
    phase_patterns,
    shadow_mask_patterns,
    unwrap,
)
from rig_drivers.errors import DeviceTimeoutError
from rig_drivers.pixel_layout import mean_row_offset

_logger = logging.getLogger(__name__)

MIN_CONTRAST_SIGMA = 6.0
"""A pixel is decodable when white − black exceeds this many noise standard deviations."""


@dataclass
class Correspondences:
    """Decoded projector coordinates per camera pixel.

    Attributes
    ----------
    projector_xy : ndarray (H, W, 2) float
        The sub-pixel projector point (x, y) each camera pixel sees; NaN where not decoded.
    decoded : ndarray (H, W) bool
    black, white : ndarray (H, W) float
        Mean black and white captures (raw units).
    noise : float
        Noise standard deviation of ``white − black`` (raw units), from repeated captures.
    contrast_snr : float
        Median of ``(white − black) / noise`` over the frame.
    shadow : ndarray (H, W) bool
        True where the projector's light was not seen (``white − black`` below threshold).
    """

    projector_xy: np.ndarray
    decoded: np.ndarray
    black: np.ndarray
    white: np.ndarray
    noise: float
    contrast_snr: float
    shadow: np.ndarray

    @property
    def camera_size(self) -> tuple[int, int]:
        """``(H, W)``."""
        return self.decoded.shape

    @property
    def coverage(self) -> float:
        """Fraction of camera pixels decoded."""
        return float(self.decoded.mean())


def _noise(a: np.ndarray, b: np.ndarray) -> float:
    """Robust standard deviation of one capture, from two captures of the same thing."""
    d = (a - b).ravel()
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2))


def capture_correspondences(session, *, phase_period: int = 16, phase_steps: int = 8, average: int = 1,
                            min_contrast_sigma: float = MIN_CONTRAST_SIGMA,
                            progress: Callable[[int, int], None] | None = None) -> Correspondences:
    """Show the calibration patterns and decode every camera pixel.

    Parameters
    ----------
    session : RigSession
        Opened.
    phase_period, phase_steps : int
        Square-wave period (projector pixels) and number of shifts; ``phase_steps=0``
        skips phase shifting (integer Gray-code coordinates, centre of the pixel).
    average : int
        Frames averaged per pattern.
    min_contrast_sigma : float
        Decodable where ``white − black > min_contrast_sigma · noise``.
    progress : callable(done, total), optional
    """
    psize = session.projector_size
    black_pat, white_pat = shadow_mask_patterns(psize)
    gray, bits_x, bits_y = gray_code_patterns(psize)
    phases = [] if phase_steps == 0 else [
        phase_patterns(psize, "x", period=phase_period, steps=phase_steps),
        phase_patterns(psize, "y", period=phase_period, steps=phase_steps)]
    plan = [black_pat, white_pat, black_pat, white_pat, *gray, *(p for group in phases for p in group)]
    shots = []
    for i, pat in enumerate(plan):
        shots.append(session.capture(pat, average=average))
        if progress is not None:
            progress(i + 1, len(plan))
    b1, w1, b2, w2 = shots[:4]
    black, white = (b1 + b2) / 2, (w1 + w2) / 2
    noise_one = max(np.hypot(_noise(b1, b2), _noise(w1, w2)), 1e-9)
    contrast = white - black
    snr = float(np.median(contrast) / noise_one)
    shadow = contrast <= min_contrast_sigma * noise_one
    n_gray = len(gray)
    col, row, _margin = decode_gray(np.stack(shots[4:4 + n_gray]), bits_x, bits_y, psize)
    valid = ~shadow & (col >= 0) & (row >= 0)
    if phases:
        rest = np.stack(shots[4 + n_gray:])
        fx, ax = decode_phase(rest[:phase_steps], period=phase_period)
        fy, ay = decode_phase(rest[phase_steps:], period=phase_period)
        u = unwrap(fx, col.astype(np.float64), phase_period)
        v = unwrap(fy, row.astype(np.float64), phase_period)
        # The fringes must be seen, and the phase must agree with the Gray code (±1.5 px).
        seen = (ax > 0.1 * contrast) & (ay > 0.1 * contrast)
        valid &= seen & (np.abs(u - col) <= 1.5) & (np.abs(v - row) <= 1.5)
    else:
        u, v = col.astype(np.float64), row.astype(np.float64)
    xy = np.stack([u, v], axis=-1)
    xy[~valid] = np.nan
    _logger.info("decoded %.1f%% of the camera pixels (contrast %.1f sigma)", 100 * valid.mean(), snr)
    return Correspondences(xy, valid, black, white, float(noise_one), snr, shadow)


@dataclass(kw_only=True)
class HomographyResult(StepResult):
    """The outcome of a homography calibration (see the module docstring for ``status``).

    Attributes
    ----------
    homography : ndarray (3, 3) or None
        Projector → camera (pixel centres, x/y), ``h[2, 2] = 1``; None when no fit was made.
    rms_px : float
        RMS reprojection error of the inliers, camera pixels (NaN without a fit).
    inliers : int
        RANSAC inliers.
    decoded : int
        Decoded camera pixels.
    coverage : float
        Fraction of camera pixels decoded.
    residual_map : ndarray (H, W) float
        ``|H(projector point) − camera pixel|`` per camera pixel, camera pixels; NaN where
        not decoded.
    geometry : GeometryReport or None
    camera_size, projector_size : (H, W)
    """

    homography: np.ndarray | None
    rms_px: float
    inliers: int
    decoded: int
    coverage: float
    residual_map: np.ndarray
    geometry: geometry.GeometryReport | None
    camera_size: tuple[int, int]
    projector_size: tuple[int, int]
    contrast_snr: float = float("nan")
    details: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """JSON-ready figures (no maps)."""
        return {"status": self.status, "message": self.message, "warnings": list(self.warnings),
                "rms_px": self.rms_px, "inliers": self.inliers, "decoded": self.decoded,
                "coverage": self.coverage, "contrast_snr": self.contrast_snr,
                "homography": None if self.homography is None else self.homography.tolist(),
                "geometry": None if self.geometry is None else self.geometry.as_dict()}


def _uncovered_halves(decoded: np.ndarray, min_fraction: float) -> list[str]:
    H, W = decoded.shape
    halves = {"left": decoded[:, : W // 2], "right": decoded[:, W // 2:],
              "top": decoded[: H // 2], "bottom": decoded[H // 2:]}
    return [name for name, part in halves.items() if part.mean() < min_fraction]


def fit_homography(corr: Correspondences, projector_size, *, ransac_threshold_px: float = 1.0,
                   min_points: int = 200, min_coverage: float = 0.6, max_rms_px: float = 0.5,
                   max_points: int = 40_000, seed: int = 0, layout: str = "square") -> HomographyResult:
    """Fit one projector→camera homography to decoded correspondences and judge it.

    Parameters
    ----------
    corr : Correspondences
    projector_size : (Hp, Wp)
    ransac_threshold_px : float
        RANSAC inlier threshold, camera pixels.
    min_points : int
        Fewest decoded pixels (and inliers) for a fit.
    min_coverage : float
        Below this decoded fraction (or with a frame half almost undecoded) the status is
        ``partial``.
    max_rms_px : float
        Above this RMS the status is ``inconsistent``.
    max_points : int
        Points used by RANSAC (a seeded subsample; the refit uses every inlier).
    seed : int
        Seeds the subsample.
    layout : "square" or "diamond"
        How the projector's pixels sit: on a diamond DMD the decoded columns are moved into mirror
        coordinates (:func:`rig_drivers.pixel_layout.mean_row_offset`) so that the homography maps
        mirror coordinates, as the shutter patterns expect.
    """
    H, W = corr.camera_size
    nan_map = np.full((H, W), np.nan)
    base = dict(homography=None, rms_px=float("nan"), inliers=0, decoded=int(corr.decoded.sum()),
                coverage=corr.coverage, residual_map=nan_map, geometry=None, camera_size=(H, W),
                projector_size=tuple(projector_size), contrast_snr=corr.contrast_snr)
    if corr.coverage < 0.02 or base["decoded"] < min_points:
        lit = float((~corr.shadow).mean())
        if corr.contrast_snr < 1.5 and lit < 0.02:
            return HomographyResult(
                status="no_projector_light",
                message=(f"the projector's light does not reach the camera: white and black frames differ on "
                         f"{lit:.1%} of the pixels (median contrast {corr.contrast_snr:.1f} noise sigma). Check "
                         "that the projector is on and out of standby, that its patterns reach the target "
                         "(lens cap, aim, beam splitter), and that the camera looks at the same target."), **base)
        if lit < 0.02:
            return HomographyResult(
                status="too_dark",
                message=(f"the scene is too dark to decode: the projected contrast is only "
                         f"{corr.contrast_snr:.1f} noise sigma (at least {MIN_CONTRAST_SIGMA:g} is needed). "
                         "Use a brighter (whiter) target, raise the projector's LED current, or lengthen the "
                         "camera exposure / gain."), **base)
        return HomographyResult(
            status="too_few_points",
            message=(f"only {base['decoded']} camera pixels ({corr.coverage:.1%}) could be decoded (at least "
                     f"{min_points} are needed): the projected patterns are not resolved. Focus the projector "
                     "and the camera on the target."), **base)
    ys, xs = np.nonzero(corr.decoded)
    cam = np.stack([xs, ys], axis=1).astype(np.float64)
    proj = corr.projector_xy[ys, xs] + np.array([mean_row_offset(layout), 0.0])
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(cam), max_points, replace=False) if len(cam) > max_points else np.arange(len(cam))
    h, mask = cv2.findHomography(proj[pick], cam[pick], cv2.RANSAC, ransacReprojThreshold=ransac_threshold_px,
                                 maxIters=2000, confidence=0.999)
    if h is None:
        return HomographyResult(status="degenerate", message="RANSAC found no homography: the decoded points "
                                "are degenerate (all on a line?)", **base)
    resid = np.linalg.norm(geometry.apply(h, proj) - cam, axis=1)
    inl = resid <= ransac_threshold_px
    if inl.sum() < min_points:
        base["homography"] = h / h[2, 2]
        return HomographyResult(status="too_few_points", message=(
            f"only {int(inl.sum())} decoded pixels agree with one homography (at least {min_points} needed): "
            "the decoding is unreliable"), **base)
    h, _ = cv2.findHomography(proj[inl], cam[inl], 0)
    h = h / h[2, 2]
    resid = np.linalg.norm(geometry.apply(h, proj) - cam, axis=1)
    inl = resid <= ransac_threshold_px
    rms = float(np.sqrt(np.mean(resid[inl] ** 2)))
    rmap = nan_map.copy()
    rmap[ys, xs] = resid
    geo = geometry.describe(h, (H, W), projector_size)
    base.update(homography=h, rms_px=rms, inliers=int(inl.sum()), residual_map=rmap, geometry=geo)
    warnings = list(geo.notes)
    if geo.problems:
        return HomographyResult(status="degenerate", message="; ".join(geo.problems), warnings=warnings, **base)
    if rms > max_rms_px:
        return HomographyResult(status="inconsistent", message=(
            f"the decoded points disagree with a single homography (RMS {rms:.2f} px > {max_rms_px:g} px): "
            "the rig may not be co-located (run the parallax test) or the target moved"), warnings=warnings, **base)
    halves = _uncovered_halves(corr.decoded, 0.25)
    if corr.coverage < min_coverage or halves:
        where = f" (the {' and '.join(halves)} half of the frame is almost undecoded: in shadow?)" if halves else ""
        return HomographyResult(status="partial", message=(
            f"only {corr.coverage:.0%} of the camera frame was decoded{where}: the homography is extrapolated "
            f"there. Light the whole frame (remove what casts the shadow) and calibrate again."),
            warnings=warnings, **base)
    msg = (f"homography fitted: RMS {rms:.3f} px over {int(inl.sum())} inliers, {corr.coverage:.1%} of the "
           f"frame decoded; scale {geo.scale:.3f} camera px per projector px, rotation {geo.rotation_deg:+.2f} deg")
    return HomographyResult(status="ok", message=msg, warnings=warnings, **base)


def calibrate_homography(session, *, phase_period: int = 16, phase_steps: int = 8, average: int = 1,
                         progress: Callable[[int, int], None] | None = None, **fit_options) -> HomographyResult:
    """Capture and fit: :func:`capture_correspondences` then :func:`fit_homography`.

    Returns
    -------
    HomographyResult
        Check ``result.success``; ``result.message`` says what to do otherwise.
    """
    if session is None:
        raise CalibrationError("`session` must be an opened RigSession")
    try:
        corr = capture_correspondences(session, phase_period=phase_period, phase_steps=phase_steps,
                                       average=average, progress=progress)
    except DeviceTimeoutError as exc:
        H, W = session.camera_size
        return HomographyResult(
            status="no_frames", message=(f"the camera delivered no frame after a pattern change: it is not "
                                         f"synchronised to the projector ({exc})"),
            homography=None, rms_px=float("nan"), inliers=0, decoded=0, coverage=0.0,
            residual_map=np.full((H, W), np.nan), geometry=None, camera_size=(H, W),
            projector_size=tuple(session.projector_size))
    fit_options.setdefault("layout", session.pixel_layout)
    result = fit_homography(corr, session.projector_size, **fit_options)
    result.details["correspondences"] = corr
    _logger.info("homography: %s", result.message)
    return result
