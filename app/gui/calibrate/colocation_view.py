"""Co-location live: the camera image with the projector's grid drawn where the current homography puts it.

:func:`projector_grid` is the Qt-free geometry: the projector's border, its grid lines (every
``1 / divisions`` of its width and height) and its centre cross, in projector pixels, mapped to
camera pixels through the projector→camera homography (a homography maps lines to lines, so
each segment's two ends are enough). :class:`ColocationView` draws them with pyqtgraph over
the camera image as each live measurement arrives.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt

from flexvox_app.gui.widgets.image_panel import ImagePanel

GRID_PEN = (80, 220, 255)
BORDER_PEN = (255, 200, 60)
CENTRE_PEN = (255, 80, 80)


def apply_homography(h: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Points ``(N, 2)`` (x, y) through the 3×3 homography ``h``."""
    xy = np.asarray(xy, np.float64)
    p = np.c_[xy, np.ones(len(xy))] @ np.asarray(h, np.float64).T
    return p[:, :2] / p[:, 2:3]


def projector_grid(projector_size: tuple[int, int], homography, *, divisions: int = 8) -> dict[str, np.ndarray]:
    """Segments ``(N, 2, 2)`` (segment, end, x/y) in camera pixels: ``"grid"``, ``"border"``, ``"centre"``.

    Projector pixel centres are at integer coordinates; the border runs along the outer pixel edges
    (−0.5 and W − 0.5).

    Examples
    --------
    >>> g = projector_grid((4, 6), np.eye(3), divisions=2)
    >>> g["border"][0].tolist()
    [[-0.5, -0.5], [5.5, -0.5]]
    """
    if divisions < 1:
        raise ValueError(f"`divisions` must be >= 1; got {divisions}")
    Hp, Wp = (int(v) for v in projector_size)
    x0, x1, y0, y1 = -0.5, Wp - 0.5, -0.5, Hp - 0.5
    xs = np.linspace(x0, x1, divisions + 1)[1:-1]
    ys = np.linspace(y0, y1, divisions + 1)[1:-1]
    grid = [((x, y0), (x, y1)) for x in xs] + [((x0, y), (x1, y)) for y in ys]
    border = [((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)), ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))]
    cx, cy, arm = (Wp - 1) / 2, (Hp - 1) / 2, min(Wp, Hp) / 20
    centre = [((cx - arm, cy), (cx + arm, cy)), ((cx, cy - arm), (cx, cy + arm))]
    out = {}
    for name, segs in (("grid", grid), ("border", border), ("centre", centre)):
        a = np.asarray(segs, np.float64).reshape(-1, 2, 2) if segs else np.zeros((0, 2, 2))
        out[name] = apply_homography(homography, a.reshape(-1, 2)).reshape(-1, 2, 2)
    return out


def _pairs(segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    flat = segments.reshape(-1, 2)
    return flat[:, 0], flat[:, 1]


class ColocationView(ImagePanel):
    """The camera image with the expected projector grid overlaid (``show(image, homography, projector_size)``)."""

    def __init__(self, title: str = "co-location live: off", *, divisions: int = 8, parent=None):
        super().__init__(title, parent=parent)
        self.divisions = int(divisions)
        self.curves = {}
        for name, colour, width, style in (("grid", GRID_PEN, 1, Qt.PenStyle.DashLine),
                                           ("border", BORDER_PEN, 2, Qt.PenStyle.SolidLine),
                                           ("centre", CENTRE_PEN, 2, Qt.PenStyle.SolidLine)):
            curve = pg.PlotCurveItem(connect="pairs", pen=pg.mkPen(colour, width=width, style=style))
            curve.setZValue(20)
            self.view.addItem(curve)
            self.curves[name] = curve
        self.camera_centre = pg.ScatterPlotItem(symbol="o", size=16, pen=pg.mkPen((255, 255, 255), width=2),
                                                brush=None)
        self.camera_centre.setZValue(21)
        self.view.addItem(self.camera_centre)
        self.segments: dict[str, np.ndarray] | None = None
        self.clear("tick “measure continuously” to see the camera with the projector's grid")

    def show_alignment(self, image: np.ndarray | None, homography, projector_size) -> None:
        """Show ``image`` (H, W) and the projector grid through ``homography`` (None: no grid)."""
        if image is not None:
            img = np.asarray(image, np.float32)
            finite = img[np.isfinite(img)]
            lo, hi = (float(v) for v in np.percentile(finite, [0.5, 99.5])) if finite.size else (0.0, 1.0)
            self.set_image(img, levels=(lo, hi if hi > lo else lo + 1))
            H, W = img.shape[:2]
            self.camera_centre.setData([(W - 1) / 2], [(H - 1) / 2])
        if homography is None:
            self.segments = None
            for curve in self.curves.values():
                curve.setData([], [])
            return
        self.segments = projector_grid(projector_size, homography, divisions=self.divisions)
        for name, curve in self.curves.items():
            curve.setData(*_pairs(self.segments[name]))
        self._frame_all()

    def _frame_all(self) -> None:
        """Show the whole camera image and the whole projector border, whichever is larger."""
        pts = [self.segments["border"].reshape(-1, 2)] if self.segments is not None else []
        if self._shape is not None:
            H, W = self._shape
            pts.append(np.array([[0.0, 0.0], [W, H]]))
        if not pts:
            return
        p = np.concatenate(pts)
        p = p[np.isfinite(p).all(axis=1)]
        if len(p):
            self.view.setRange(xRange=(p[:, 0].min(), p[:, 0].max()), yRange=(p[:, 1].min(), p[:, 1].max()),
                               padding=0.03)
