"""Textures with real high-frequency detail (the paper's point: spatial detail where nothing moves)."""

from __future__ import annotations

import math

import cv2
import numpy as np


def fine_texture(height: int, width: int, rng: np.random.Generator, *, contrast: float = 1.0) -> np.ndarray:
    """A wall-like texture in [0, 1]: multi-octave noise plus fine grain and thin lines.

    Energy is spread down to the pixel scale (single-pixel grain, 2–3 px stripes), so a
    reconstruction that trades spatial resolution away where nothing moves shows it.
    """
    tex = np.zeros((height, width), np.float32)
    for octave, weight in ((32, 0.35), (8, 0.25), (3, 0.2)):
        small = rng.random((max(2, height // octave + 2), max(2, width // octave + 2))).astype(np.float32)
        tex += weight * cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    tex += 0.2 * rng.random((height, width)).astype(np.float32)  # pixel-scale grain
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    lines = 0.5 + 0.5 * np.sin(2 * np.pi * (xx * 0.31 + yy * 0.13))
    tex = 0.8 * tex + 0.2 * lines
    tex -= tex.min()
    tex /= max(float(tex.max()), 1e-6)
    return (0.5 + contrast * (tex - 0.5)).clip(0, 1).astype(np.float32)


def shift_image(img: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Translate by a sub-pixel amount (bilinear, wrapping at the borders)."""
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_WRAP)


def disc_coverage(height: int, width: int, cx: float, cy: float, r: float, supersample: int = 4) -> np.ndarray:
    """Fraction of each pixel covered by a disc (anti-aliased by supersampling)."""
    out = np.zeros((height, width), np.float32)
    rows, cols = _box(height, width, cx - r, cy - r, cx + r, cy + r)
    if rows.start < rows.stop and cols.start < cols.stop:
        yy, xx = _samples(rows, cols, supersample)
        inside = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
        out[rows, cols] = inside.mean(axis=(2, 3))
    return out


def bar_coverage(height: int, width: int, x0: float, y0: float, x1: float, y1: float,
                 half_width: float, supersample: int = 3) -> np.ndarray:
    """Fraction of each pixel covered by a thick segment from (x0, y0) to (x1, y1)."""
    out = np.zeros((height, width), np.float32)
    rows, cols = _box(height, width, min(x0, x1) - half_width, min(y0, y1) - half_width,
                      max(x0, x1) + half_width, max(y0, y1) + half_width)
    if rows.start < rows.stop and cols.start < cols.stop:
        yy, xx = _samples(rows, cols, supersample)
        dx, dy = x1 - x0, y1 - y0
        length2 = max(dx * dx + dy * dy, 1e-9)
        t = np.clip(((xx - x0) * dx + (yy - y0) * dy) / length2, 0, 1)
        dist2 = (xx - x0 - t * dx) ** 2 + (yy - y0 - t * dy) ** 2
        out[rows, cols] = (dist2 <= half_width**2).mean(axis=(2, 3))
    return out


def _box(height: int, width: int, left: float, top: float, right: float, bottom: float) -> tuple[slice, slice]:
    """The pixels a shape within ``[left, right] × [top, bottom]`` can cover (a pixel's samples lie within half a
    pixel of its centre; one pixel of margin more), clipped to the image. Outside them the coverage is 0."""
    rows = slice(max(0, math.floor(top) - 1), min(height, math.ceil(bottom) + 2))
    cols = slice(max(0, math.floor(left) - 1), min(width, math.ceil(right) + 2))
    return rows, cols


def _samples(rows: slice, cols: slice, supersample: int) -> tuple[np.ndarray, np.ndarray]:
    """The supersampled positions (y, x) of the pixels ``rows × cols``, shaped (h, w, s, s) by broadcasting."""
    offs = (np.arange(supersample, dtype=np.float32) + 0.5) / supersample - 0.5
    yy = np.arange(rows.start, rows.stop, dtype=np.float32)[:, None, None, None] + offs[None, None, :, None]
    xx = np.arange(cols.start, cols.stop, dtype=np.float32)[None, :, None, None] + offs[None, None, None, :]
    return yy, xx
