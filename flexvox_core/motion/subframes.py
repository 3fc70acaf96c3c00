"""Where the trajectory gathers compute: boxes around the selected voxels of a sub-frame."""

from __future__ import annotations

import numpy as np

BAND = 32
"""Rows per box of :func:`selected_boxes`."""


def selected_boxes(select: np.ndarray, pad: int, band: int = BAND):
    """Boxes that cover the True pixels of a 2-D mask: one per band of ``band`` rows that holds
    any, as ((y0, y1, x0, x1), (k0, k1)): the box padded by ``pad`` (what a computation with a
    blur of that reach must read) and the rows of it to keep (the band's own). Scattered moving
    regions then cost about their bands' area, not the whole frame's."""
    H, W = select.shape
    rows = select.any(axis=1)
    for b0 in range(0, H, band):
        b1 = min(H, b0 + band)
        if not rows[b0:b1].any():
            continue
        r = np.flatnonzero(rows[b0:b1]) + b0
        cols = np.flatnonzero(select[r[0]: r[-1] + 1].any(axis=0))
        box = (max(0, r[0] - pad), min(H, r[-1] + 1 + pad), max(0, cols[0] - pad), min(W, cols[-1] + 1 + pad))
        yield box, (int(r[0]), int(r[-1]) + 1)
