"""Homography geometry: apply, compare, and judge a projector→camera homography.

Conventions: a homography maps projector pixel centres ``(x, y)`` to camera pixel centres
``(x, y)`` (OpenCV order, pixel centres at whole numbers), float64, ``h[2, 2] = 1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flexvox_calibration.errors import CalibrationError

MAX_ANISOTROPY = 4.0
"""Largest ratio of the homography's local stretches before it is called nearly singular.
(A DLP LightCrafter 4500's diamond pixels give 2; a sound rig stays well below 4.)"""

SCALE_RANGE = (0.05, 20.0)
"""Camera pixels per projector pixel outside which the fit is called degenerate."""


def check_matrix(h, name: str = "homography") -> np.ndarray:
    """Return ``h`` as a finite 3×3 float64 matrix normalised to ``h[2, 2] = 1``."""
    arr = np.asarray(h, dtype=np.float64)
    if arr.shape != (3, 3) or not np.isfinite(arr).all():
        raise CalibrationError(f"`{name}` must be a finite 3x3 matrix; got shape {arr.shape}")
    if abs(arr[2, 2]) < 1e-12 or abs(np.linalg.det(arr)) < 1e-300:
        raise CalibrationError(f"`{name}` must be invertible with h[2, 2] != 0")
    return arr / arr[2, 2]


def apply(h, xy) -> np.ndarray:
    """Map points ``(..., 2)`` through ``h``; returns the same shape (NaN where w = 0)."""
    pts = np.asarray(xy, dtype=np.float64)
    flat = pts.reshape(-1, 2)
    w = h[2, 0] * flat[:, 0] + h[2, 1] * flat[:, 1] + h[2, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (h[0, 0] * flat[:, 0] + h[0, 1] * flat[:, 1] + h[0, 2]) / w
        y = (h[1, 0] * flat[:, 0] + h[1, 1] * flat[:, 1] + h[1, 2]) / w
    return np.stack([x, y], axis=-1).reshape(pts.shape)


def pixel_grid(size) -> np.ndarray:
    """Centres ``(H, W, 2)`` (x, y) of every pixel of an ``(H, W)`` image."""
    H, W = size
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    return np.stack([xs, ys], axis=-1)


def homography_error_px(fitted, true, camera_size) -> float:
    """Largest distance, in camera pixels, between two projector→camera mappings over the frame.

    For every camera pixel centre ``c`` the true projector point is ``p = true⁻¹(c)``; the
    error is ``|fitted(p) − c|``. The maximum over the frame is returned.
    """
    f = check_matrix(fitted, "fitted")
    t = check_matrix(true, "true")
    cam = pixel_grid(camera_size).reshape(-1, 2)
    proj = apply(np.linalg.inv(t), cam)
    err = np.linalg.norm(apply(f, proj) - cam, axis=1)
    return float(np.nanmax(err))


def jacobian(h, xy) -> np.ndarray:
    """Jacobians ``(N, 2, 2)`` of the mapping ``h`` at points ``(N, 2)``."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    x, y = pts[:, 0], pts[:, 1]
    w = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    u = h[0, 0] * x + h[0, 1] * y + h[0, 2]
    v = h[1, 0] * x + h[1, 1] * y + h[1, 2]
    J = np.empty((len(pts), 2, 2))
    J[:, 0, 0] = (h[0, 0] * w - u * h[2, 0]) / w**2
    J[:, 0, 1] = (h[0, 1] * w - u * h[2, 1]) / w**2
    J[:, 1, 0] = (h[1, 0] * w - v * h[2, 0]) / w**2
    J[:, 1, 1] = (h[1, 1] * w - v * h[2, 1]) / w**2
    return J


@dataclass
class GeometryReport:
    """How a projector→camera homography looks over the camera frame.

    Attributes
    ----------
    scale : float
        Camera pixels per projector pixel (square root of the area ratio) at the frame centre.
    rotation_deg : float
        Angle of the projector's x axis in the camera image (counter-clockwise on screen is
        negative, since image y points down), at the frame centre.
    offset_px : (dx, dy)
        Where the projector's centre lands, relative to the camera's centre, camera pixels.
    anisotropy : float
        Largest ratio of the two local stretches over the frame (1 = no shear/squash).
    mirrored : bool
        The camera sees the projector mirrored (negative determinant).
    folded : bool
        The homography's horizon crosses the camera frame (it is not a valid mapping there).
    problems : list of str
        Sentences describing what is wrong (empty when the geometry is sound).
    notes : list of str
        Sentences the operator should read that are not errors (a mirror image).
    """

    scale: float
    rotation_deg: float
    offset_px: tuple[float, float]
    anisotropy: float
    mirrored: bool
    folded: bool
    problems: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    def as_dict(self) -> dict:
        """JSON-ready form."""
        return {"scale": self.scale, "rotation_deg": self.rotation_deg, "offset_px": list(self.offset_px),
                "anisotropy": self.anisotropy, "mirrored": self.mirrored, "folded": self.folded,
                "problems": list(self.problems), "notes": list(self.notes)}


def describe(h, camera_size, projector_size, *, max_anisotropy: float = MAX_ANISOTROPY) -> GeometryReport:
    """Judge a projector→camera homography over the camera frame.

    Parameters
    ----------
    h : array (3, 3)
        Projector → camera.
    camera_size, projector_size : (H, W)
    max_anisotropy : float
        Ratio of local stretches above which the mapping is called nearly singular.
    """
    h = check_matrix(h)
    H, W = camera_size
    Hp, Wp = projector_size
    g = np.linalg.inv(h)
    # Camera frame sampled on a grid (corners included): where is the mapping valid?
    ys, xs = np.meshgrid(np.linspace(-0.5, H - 0.5, 9), np.linspace(-0.5, W - 0.5, 9), indexing="ij")
    cam = np.stack([xs.ravel(), ys.ravel()], axis=1)
    w = g[2, 0] * cam[:, 0] + g[2, 1] * cam[:, 1] + g[2, 2]
    folded = bool(w.min() <= 0 < w.max() or np.any(np.abs(w) < 1e-9))
    proj = apply(g, cam)
    J = jacobian(h, proj)
    dets = np.linalg.det(J)
    sv = np.linalg.svd(J, compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        aniso = float(np.nanmax(sv[:, 0] / sv[:, 1])) if np.all(np.isfinite(sv)) else math.inf
    centre_cam = np.array([(W - 1) / 2, (H - 1) / 2])
    centre_proj = apply(g, centre_cam)
    Jc = jacobian(h, centre_proj)[0]
    det_c = float(np.linalg.det(Jc))
    scale = math.sqrt(abs(det_c))
    mirrored = det_c < 0
    rotation = math.degrees(math.atan2(Jc[1, 0], Jc[0, 0]))
    landed = apply(h, np.array([(Wp - 1) / 2, (Hp - 1) / 2]))
    offset = (float(landed[0] - centre_cam[0]), float(landed[1] - centre_cam[1]))
    problems, notes = [], []
    if folded or not np.all(np.isfinite(proj)):
        problems.append("the homography folds the camera frame (its horizon crosses the image): it cannot "
                        "describe a co-located projector; the decoded points are wrong or degenerate")
    elif np.any(np.sign(dets) != np.sign(det_c)):
        problems.append("the homography changes orientation inside the camera frame: degenerate fit")
    if not folded and aniso > max_anisotropy:
        problems.append(f"the homography is nearly singular: the projector's image is squashed {aniso:.1f}:1 "
                        f"in the camera (at most {max_anisotropy:g}:1 is plausible for a co-located rig); "
                        "check the beam splitter angle and that the decoded area is not a thin strip")
    if not folded and not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
        problems.append(f"the homography's scale is {scale:.3g} camera px per projector px, outside "
                        f"{SCALE_RANGE[0]:g}..{SCALE_RANGE[1]:g}: degenerate fit")
    if mirrored:
        if Jc[0, 0] < 0 < Jc[1, 1]:
            which = "left-right"
        elif Jc[1, 1] < 0 < Jc[0, 0]:
            which = "up-down"
        else:
            which = "mirror image, rotated"
        notes.append(f"the camera sees the projector mirrored ({which}): expected when one of them looks "
                     "through the beam splitter's reflection. Shutter masks account for it; to see the "
                     "projector upright, enable the projector's image flip.")
    return GeometryReport(scale, rotation, offset, aniso, mirrored, folded, problems, notes)
