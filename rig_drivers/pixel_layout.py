"""How a projector's pixels sit: a square grid, or the staggered rows of a diamond-pixel DMD.

A pattern is an image of ``(Hp, Wp)`` projector pixels, indexed by row and column. On a square
DMD, pixel ``(r, c)`` sits at ``(x, y) = (c, r)`` in *mirror coordinates*, the plane in which
one homography maps the projector to the camera. The LightCrafter 4500's DMD is a diamond array
instead: its 912 × 1140 input pixels sit on rows that are staggered by half a pixel every other
row, so pixel ``(r, c)`` sits at ``(c + ½·(r mod 2), r)``. (Its rows are also at half the column
pitch. That is an affine scale, which the homography carries.) A model that ignores the stagger
puts every odd row half a pixel from where its mirrors are.

:func:`mirror_centres` gives each pixel's position in mirror coordinates and :func:`mirror_at`
the pixel that covers a point there. The layout is used only where a rig declares it: a rig
profile's ``[projector] pixel_layout``, or the simulated rig's ``pixel_layout``.
"""

from __future__ import annotations

import numpy as np

from rig_drivers.errors import SettingError

LAYOUTS = ("square", "diamond", "diamond-even")
"""``diamond``: odd rows sit half a pixel along; ``diamond-even``: the even rows do (the stagger the
other way round, up to a shift the homography takes). Which one a real DMD has, as its driver's
image flips leave it, is not verified on hardware: if the shutter check reports crosstalk with one,
calibrate with the other."""


def check_layout(layout) -> str:
    """Validate a layout name."""
    if layout not in LAYOUTS:
        raise SettingError(f"`pixel_layout` must be one of {', '.join(LAYOUTS)}; got {layout!r}")
    return layout


def row_offsets(rows: int, layout: str) -> np.ndarray:
    """The x offset of each pixel row in mirror coordinates: 0, or ½ on the odd rows of a diamond DMD."""
    check_layout(layout)
    offsets = np.zeros(int(rows))
    if layout == "diamond":
        offsets[1::2] = 0.5
    elif layout == "diamond-even":
        offsets[0::2] = 0.5
    return offsets


def mean_row_offset(layout: str) -> float:
    """The x offset averaged over rows: ¼ pixel on a diamond DMD.

    A camera pixel that spans several mirror rows decodes a projector column that averages those
    rows' offsets; adding this mean moves decoded index coordinates into mirror coordinates, to
    first order, before a homography is fitted to them."""
    return float(row_offsets(2, layout).mean())


def mirror_centres(size, layout: str = "square") -> np.ndarray:
    """Centres ``(Hp, Wp, 2)`` (x, y) of every projector pixel in mirror coordinates."""
    Hp, Wp = (int(v) for v in size)
    ys, xs = np.mgrid[0:Hp, 0:Wp].astype(np.float64)
    xs += row_offsets(Hp, layout)[:, None]
    return np.stack([xs, ys], axis=-1)


def mirror_at(x, y, size, layout: str = "square") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The projector pixel nearest to each point ``(x, y)`` in mirror coordinates.

    Returns ``(row, column, inside)``: integer arrays of the pixel indexes (0 where outside) and a
    bool array, True where the point lies on the projector. On a diamond DMD the row is found
    first, then the column within that row's staggered grid.
    """
    Hp, Wp = (int(v) for v in size)
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        row = np.rint(y)
        ok_row = np.isfinite(row) & (row >= 0) & (row < Hp)
        row_i = np.where(ok_row, row, 0).astype(np.intp)
        col = np.rint(x - row_offsets(Hp, layout)[row_i])
        inside = ok_row & np.isfinite(col) & (col >= 0) & (col < Wp)
    col_i = np.where(inside, col, 0).astype(np.intp)
    return np.where(inside, row_i, 0), col_i, inside
