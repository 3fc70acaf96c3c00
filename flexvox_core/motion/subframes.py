"""Per-sub-frame work of the trajectory gathers: where to compute, and on how many threads."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

BAND = 32
"""Rows per box of :func:`selected_boxes`."""


def workers() -> int:
    """Threads for per-sub-frame work: the machine's cores, at most 8."""
    return max(1, min(os.cpu_count() or 1, 8))


def for_each_subframe(fn: Callable[[int], None], count: int) -> None:
    """Call ``fn(t)`` for t in range(count) on :func:`workers` threads (each writes its own sub-frame).

    OpenCV releases the GIL and runs most element-wise operations on one thread: two sub-frames
    at a time nearly halve a gather's time on two cores (39 -> 21 ms per 640×480 sub-frame,
    measured). OpenCV's own thread pool is switched off meanwhile (``cv2.setNumThreads(1)``,
    restored after): its workers wait for work by spinning, and beside these threads that cost
    a 640×480 gather 30 % of its time in system calls (measured). An exception in any call is
    raised here.
    """
    n = workers()
    if n == 1 or count < 2:
        for t in range(count):
            fn(t)
        return
    saved = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ThreadPoolExecutor(max_workers=n) as pool:
            list(pool.map(fn, range(count)))  # consumes the results, so an exception is raised here
    finally:
        cv2.setNumThreads(saved)


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
