"""Co-location aid: live alignment numbers and the parallax test.

Live numbers
    :func:`measure_alignment` projects the Gray code (integer precision is plenty while
    the operator turns screws), fits a homography and reports where the projector's centre
    lands (offset from the camera's centre), its rotation and scale in the camera, whether
    it is mirrored, and how much of the camera frame it lights. :func:`live_alignment`
    repeats it for a wizard's timer.

Parallax test
    A co-located rig (the projector's and the camera's centres of projection coincide
    through the beam splitter) has **one** homography for every depth. The operator
    captures a flat target at two or more depths (:func:`capture_view` each time; in
    simulation see :mod:`rig_drivers.simulated_target` for how depth is emulated), and
    :func:`parallax_test` fits one homography to all of them and shows the residuals per
    view as heat maps. When they disagree, the shift between the nearest and the farthest
    view says where the projector's centre sits: a lateral offset ``b`` moves near points
    by ``f·b·(1/Z_near − 1/Z_far)`` in the direction of ``b``; an offset along the axis
    scales near points about the image centre.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import cv2
import numpy as np

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.homography import Correspondences, capture_correspondences, fit_homography
from flexvox_calibration.results import StepResult
from rig_drivers.errors import DeviceTimeoutError

_logger = logging.getLogger(__name__)


@dataclass(kw_only=True)
class AlignmentResult(StepResult):
    """Live alignment numbers (statuses as :class:`~flexvox_calibration.homography.HomographyResult`'s).

    Attributes
    ----------
    offset_px : (dx, dy) or None
        Where the projector's centre lands relative to the camera's centre, camera pixels.
    rotation_deg : float
        Angle of the projector's x axis in the camera image.
    scale : float
        Camera pixels per projector pixel.
    mirrored : bool
    lit_fraction : float
        Fraction of camera pixels the projector lights.
    homography : ndarray (3, 3) or None
    """

    offset_px: tuple | None = None
    rotation_deg: float = float("nan")
    scale: float = float("nan")
    mirrored: bool = False
    lit_fraction: float = 0.0
    homography: np.ndarray | None = None

    def summary(self) -> dict:
        """JSON-ready figures."""
        return {"status": self.status, "message": self.message, "warnings": list(self.warnings),
                "offset_px": None if self.offset_px is None else list(self.offset_px),
                "rotation_deg": self.rotation_deg, "scale": self.scale, "mirrored": self.mirrored,
                "lit_fraction": self.lit_fraction}


def measure_alignment(session, *, progress: Callable[[int, int], None] | None = None) -> AlignmentResult:
    """One set of live numbers: project the Gray code, find it in the camera, fit, describe."""
    try:
        corr = capture_correspondences(session, phase_steps=0, progress=progress)
    except DeviceTimeoutError as exc:
        return AlignmentResult(status="no_frames", message=f"no frame from the camera: {exc}")
    fit = fit_homography(corr, session.projector_size, ransac_threshold_px=2.0, max_rms_px=2.0, min_coverage=0.0)
    lit = float((~corr.shadow).mean())
    if fit.homography is None or fit.geometry is None or fit.status not in ("ok", "partial"):
        return AlignmentResult(status=fit.status, message=fit.message, lit_fraction=lit)
    g = fit.geometry
    dx, dy = g.offset_px
    hint = []
    if abs(dx) > 1 or abs(dy) > 1:
        hint.append(f"the projector's centre lands {abs(dx):.1f} px {'right' if dx > 0 else 'left'} and "
                    f"{abs(dy):.1f} px {'below' if dy > 0 else 'above'} the camera's centre")
    if abs(g.rotation_deg) > 0.2 and not g.mirrored:
        hint.append(f"it is rotated {g.rotation_deg:+.2f} deg")
    if lit < 0.99:
        hint.append(f"it lights only {lit:.0%} of the camera frame")
    msg = (f"offset ({dx:+.1f}, {dy:+.1f}) px, rotation {g.rotation_deg:+.2f} deg, scale {g.scale:.3f} camera px "
           f"per projector px" + ("; " + ", ".join(hint) if hint else "; centred"))
    return AlignmentResult(status="ok", message=msg, warnings=list(g.notes), offset_px=(dx, dy),
                           rotation_deg=g.rotation_deg, scale=g.scale, mirrored=g.mirrored, lit_fraction=lit,
                           homography=fit.homography)


def live_alignment(session, count: int | None = None) -> Iterator[AlignmentResult]:
    """Yield :func:`measure_alignment` results, ``count`` times (forever when None)."""
    done = 0
    while count is None or done < count:
        yield measure_alignment(session)
        done += 1


def capture_view(session, **options) -> Correspondences:
    """Decode one view of a flat target for the parallax test (sub-pixel)."""
    return capture_correspondences(session, **options)


@dataclass(kw_only=True)
class ParallaxResult(StepResult):
    """The parallax test: one homography for every view, and how far each view is from it.

    Statuses: ``ok`` (co-located), ``not_co_located``, ``too_few_points``.

    Attributes
    ----------
    homography : ndarray (3, 3) or None
        One fit to all views.
    residual_maps : list of ndarray (H, W)
        Per view: residual magnitude (camera px) per decoded pixel, NaN elsewhere (the heat maps).
    view_rms_px, view_p95_px : list of float
        Per view: residuals of the decoded pixels against the joint fit.
    disagreement_px : list of float
        Per view: largest distance over the frame between the view's own homography and the
        first view's (what the status is judged on: per-pixel noise averages out).
    shift_px : (dx, dy)
        Mean displacement of the first view relative to the last (camera px).
    scale_change : float
        Relative scale of the first view about the image centre against the last.
    advice : str
        Which way to move, in words.
    """

    homography: np.ndarray | None = None
    residual_maps: list = field(default_factory=list)
    view_rms_px: list = field(default_factory=list)
    view_p95_px: list = field(default_factory=list)
    disagreement_px: list = field(default_factory=list)
    shift_px: tuple = (0.0, 0.0)
    scale_change: float = 0.0
    advice: str = ""

    def summary(self) -> dict:
        """JSON-ready figures (no maps)."""
        return {"status": self.status, "message": self.message, "view_rms_px": list(self.view_rms_px),
                "view_p95_px": list(self.view_p95_px),
                "disagreement_px": list(self.disagreement_px), "shift_px": list(self.shift_px),
                "scale_change": self.scale_change, "advice": self.advice}


def _view_homography(corr: Correspondences, projector_size):
    fit = fit_homography(corr, projector_size, max_rms_px=np.inf, min_coverage=0.0)
    return fit.homography


def parallax_test(views, projector_size, *, tolerance_px: float = 0.5, near_first: bool = True) -> ParallaxResult:
    """Fit one homography to targets at different depths and judge the residuals.

    Parameters
    ----------
    views : list of Correspondences
        At least two, ordered by depth (nearest first when ``near_first``).
    projector_size : (Hp, Wp)
    tolerance_px : float
        Co-located when every view's own homography is within this of the first view's.
    near_first : bool
        The order of ``views`` (for the direction advice).
    """
    views = list(views)
    if len(views) < 2 or not all(isinstance(v, Correspondences) for v in views):
        raise CalibrationError(f"`views` must be at least two Correspondences (targets at different depths); "
                               f"got {len(views)}")
    shape = views[0].camera_size
    if any(v.camera_size != shape for v in views):
        raise CalibrationError("`views` must come from the same camera (one size)")
    H, W = shape
    cams, projs = [], []
    for v in views:
        ys, xs = np.nonzero(v.decoded)
        cams.append(np.stack([xs, ys], axis=1).astype(np.float64))
        projs.append(v.projector_xy[ys, xs])
    if min(len(c) for c in cams) < 200:
        return ParallaxResult(status="too_few_points", message=(
            "a view has fewer than 200 decoded pixels: light the target fully at every depth"))
    h, _ = cv2.findHomography(np.concatenate(projs), np.concatenate(cams), cv2.RANSAC, 3.0)
    if h is None:
        return ParallaxResult(status="too_few_points", message="no homography fits the views together")
    h = h / h[2, 2]
    maps, rms, p95 = [], [], []
    for cam, proj in zip(cams, projs, strict=True):
        r = np.linalg.norm(geometry.apply(h, proj) - cam, axis=1)
        m = np.full((H, W), np.nan)
        m[cam[:, 1].astype(int), cam[:, 0].astype(int)] = r
        maps.append(m)
        rms.append(float(np.sqrt(np.mean(r**2))))
        p95.append(float(np.percentile(r, 95)))
    # Displacement of the first view against the last, over the camera frame.
    h_first = _view_homography(views[0], projector_size)
    h_last = _view_homography(views[-1], projector_size)
    grid = geometry.pixel_grid((H, W)).reshape(-1, 2)[:: max(1, H * W // 4000)]
    d = geometry.apply(h_first, geometry.apply(np.linalg.inv(h_last), grid)) - grid
    shift = d.mean(axis=0)
    centred = grid - np.array([(W - 1) / 2, (H - 1) / 2])
    scale = float(np.sum((d - shift) * centred) / np.sum(centred**2))
    sign = 1.0 if near_first else -1.0
    b = sign * shift  # direction of the projector's lateral offset in the camera image
    parts = []
    if np.hypot(*shift) > tolerance_px / 2:
        ways = []
        if abs(b[0]) > abs(b[1]) / 4:
            ways.append("left" if b[0] > 0 else "right")
        if abs(b[1]) > abs(b[0]) / 4:
            ways.append("up" if b[1] > 0 else "down")
        parts.append(f"near targets land ({b[0]:+.2f}, {b[1]:+.2f}) px from far ones: the projector's centre of "
                     f"projection sits off the camera's; move the projector (or the beam splitter) so that its "
                     f"image moves {' and '.join(ways)} on near targets until the shift vanishes")
    scale_span = abs(scale) * max(H, W) / 2
    if scale_span > tolerance_px / 2:
        closer = sign * scale < 0
        parts.append(f"near targets are {'smaller' if sign * scale < 0 else 'larger'} by {abs(scale):.2%}: move "
                     f"the projector along its optical axis {'towards' if not closer else 'away from'} the "
                     "beam splitter")
    advice = "; ".join(parts)
    # Each view's own homography against the first view's, over the frame (noise averages out).
    inv_first = np.linalg.inv(h_first)
    disagreement = [float(np.max(np.linalg.norm(geometry.apply(_view_homography(v, projector_size),
                                                               geometry.apply(inv_first, grid)) - grid, axis=1)))
                    for v in views]
    worst = max(disagreement)
    if worst <= tolerance_px:
        status = "ok"
        msg = (f"co-located: one homography fits all {len(views)} depths (the views' own homographies differ by "
               f"at most {worst:.2f} px <= {tolerance_px:g} px)")
    else:
        status = "not_co_located"
        msg = (f"NOT co-located: the views' homographies differ by up to {worst:.2f} px over the frame "
               f"(tolerance {tolerance_px:g} px). "
               + (advice or "The residual pattern is not a shift or a scale: check that the target is flat"))
    return ParallaxResult(status=status, message=msg, homography=h, residual_maps=maps, view_rms_px=rms,
                          view_p95_px=p95, disagreement_px=disagreement,
                          shift_px=(float(shift[0]), float(shift[1])), scale_change=scale,
                          advice=advice)
