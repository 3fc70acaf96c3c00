"""Resizing stacks of planes on the GPU as ``cv2.resize`` does, and the flow's uint8 conversion.

* :func:`resize_area` — ``INTER_AREA`` when shrinking: each destination pixel the mean of the source area it
  covers, partial pixels weighted by their covered share (OpenCV's area tables, computed on the host);
* :func:`resize_linear` — ``INTER_LINEAR``: source position (d + ½)·scale − ½, clamped at the edges, bilinear;
  for flow (N, H, W, 2) each component multiplied by its own factor (the resize ratio) on the way;
* :func:`to_uint8` — :func:`flexvox_core.flow.estimate.to_uint8`.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import cuda

from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import device, kernel, launch


@lru_cache(maxsize=64)
def area_table(src: int, dst: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OpenCV's ``INTER_AREA`` weights from ``src`` pixels down to ``dst`` cells along one axis (src ≥ dst):
    (start (dst,) int32, count (dst,) int32, weight (dst, n) float32), cell d the sum of weight[d, j] times
    pixel start[d] + j; a partial pixel at either end of a cell weighs the share of it the cell covers."""
    scale = 1.0 / (dst / src)
    rows = []
    for d in range(dst):
        lo = d * scale
        hi = lo + scale
        width = min(scale, src - lo)
        s1, s2 = math.ceil(lo), math.floor(hi)
        s2 = min(s2, src - 1)
        s1 = min(s1, s2)
        taps = []
        if s1 - lo > 1e-3:
            taps.append((s1 - 1, (s1 - lo) / width))
        taps += [(s, 1.0 / width) for s in range(s1, s2)]
        if hi - s2 > 1e-3:
            taps.append((s2, min(min(hi - s2, 1.0), width) / width))
        rows.append(taps)
    n = max(len(t) for t in rows)
    start = np.array([t[0][0] for t in rows], np.int32)
    count = np.array([len(t) for t in rows], np.int32)
    weight = np.zeros((dst, n), np.float32)
    for d, taps in enumerate(rows):
        weight[d, :len(taps)] = [np.float32(w) for _, w in taps]
    return start, count, weight



@kernel("void(float32[:, :, ::1], float32[:, :, ::1], int32[::1], float32[:, ::1], int32[::1], float32[:, ::1])")
def _area(src, dst, y0, wy, x0, wx):
    i = cuda.grid(1)
    N, h, w = dst.shape
    if i >= N * h * w:
        return
    n, y, x = voxel(i, h, w)
    H = src.shape[1]
    W = src.shape[2]
    acc = np.float32(0)
    for a in range(wy.shape[1]):
        row = np.float32(0)
        yy = min(y0[y] + a, H - 1)  # taps past a cell's own weigh 0
        for b in range(wx.shape[1]):
            row += wx[x, b] * src[n, yy, min(x0[x] + b, W - 1)]
        acc += wy[y, a] * row
    dst[n, y, x] = acc


def resize_area(ws, src, dst, *, tag: str = "area") -> None:
    """``dst`` (N, h, w) = ``src`` (N, H, W) shrunk by ``INTER_AREA`` (h <= H, w <= W)."""
    N, H, W = src.shape
    _, h, w = dst.shape
    if h > H or w > W:
        raise ValueError(f"resize_area shrinks only: ({H}, {W}) to ({h}, {w})")
    y0, _, wy = area_table(H, h)
    x0, _, wx = area_table(W, w)
    launch(_area, N * h * w, src, dst, ws.put(f"{tag}.y0", y0), ws.put(f"{tag}.wy", wy), ws.put(f"{tag}.x0", x0),
           ws.put(f"{tag}.wx", wx))


@lru_cache(maxsize=64)
def linear_table(src: int, dst: int) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's ``INTER_LINEAR`` resampling from ``src`` pixels to ``dst`` along one axis: (left (dst,) int32,
    weights (dst, 2) float32) of pixels left and min(left + 1, src − 1); x = (d + ½)·scale − ½ in float32,
    the weights (1 − frac, frac), clamped to the first and last pixel (weight (1, 0)) beyond the centres."""
    scale = 1.0 / (dst / src)
    left = np.empty(dst, np.int32)
    weight = np.empty((dst, 2), np.float32)
    for d in range(dst):
        fx = np.float32((d + 0.5) * scale - 0.5)
        sx = math.floor(fx)
        fx = np.float32(fx - np.float32(sx))
        if sx < 0:
            fx, sx = np.float32(0), 0
        if sx >= src - 1:
            fx, sx = np.float32(0), src - 1
        left[d] = sx
        weight[d] = (np.float32(1) - fx, fx)
    return left, weight



@device
def _source(sy, ay, sx, ax, y, x, H, W):
    """The four source pixels of destination pixel (y, x) and the weights of the lower and right ones."""
    y0 = sy[y]
    x0 = sx[x]
    return y0, min(y0 + 1, H - 1), x0, min(x0 + 1, W - 1), ay[y], ax[x]


@device
def _blend(p00, p01, p10, p11, b, a):
    one = np.float32(1)
    return (p00 * (one - a) + p01 * a) * (one - b) + (p10 * (one - a) + p11 * a) * b


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], int32[::1], float32[::1], int32[::1], float32[::1])")
def _linear(src, dst, sy, ay, sx, ax):
    i = cuda.grid(1)
    N, h, w = dst.shape
    if i >= N * h * w:
        return
    n, y, x = voxel(i, h, w)
    y0, y1, x0, x1, b, a = _source(sy, ay, sx, ax, y, x, src.shape[1], src.shape[2])
    dst[n, y, x] = _blend(src[n, y0, x0], src[n, y0, x1], src[n, y1, x0], src[n, y1, x1], b, a)


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32[::1], float32[::1], int32[::1], float32[::1], "
        "float32, float32)")
def _linear_flow(src, dst, sy, ay, sx, ax, mx, my):
    i = cuda.grid(1)
    N, h, w, _ = dst.shape
    if i >= N * h * w:
        return
    n, y, x = voxel(i, h, w)
    y0, y1, x0, x1, b, a = _source(sy, ay, sx, ax, y, x, src.shape[1], src.shape[2])
    for c in range(2):
        m = mx if c == 0 else my
        dst[n, y, x, c] = _blend(src[n, y0, x0, c] * m, src[n, y0, x1, c] * m, src[n, y1, x0, c] * m,
                                 src[n, y1, x1, c] * m, b, a)


def resize_linear(ws, src, dst, *, scale=None, tag: str = "linear") -> None:
    """``dst`` = ``src`` resized by ``INTER_LINEAR``: planes (N, H, W) or flow (N, H, W, 2); for flow,
    ``scale`` = (factor of u, factor of v) multiplies the components first (default 1, 1)."""
    H, W = src.shape[1:3]
    h, w = dst.shape[1:3]
    sy, wy = linear_table(H, h)
    sx, wx = linear_table(W, w)
    ay, ax = np.ascontiguousarray(wy[:, 1]), np.ascontiguousarray(wx[:, 1])
    tables = (ws.put(f"{tag}.sy", sy), ws.put(f"{tag}.ay", ay), ws.put(f"{tag}.sx", sx), ws.put(f"{tag}.ax", ax))
    n = dst.shape[0] * h * w
    if len(src.shape) == 4:
        mx, my = (1.0, 1.0) if scale is None else scale
        launch(_linear_flow, n, src, dst, *tables, np.float32(mx), np.float32(my))
    else:
        launch(_linear, n, src, dst, *tables)


@kernel("void(float32[:, :, ::1], uint8[:, :, ::1])")
def _to_uint8(src, dst):
    i = cuda.grid(1)
    N, H, W = src.shape
    if i >= N * H * W:
        return
    n, y, x = voxel(i, H, W)
    v = src[n, y, x] * np.float32(255) + np.float32(0.5)
    dst[n, y, x] = np.uint8(min(max(v, np.float32(0)), np.float32(255)))


def to_uint8(src, dst) -> None:
    """``dst`` (N, H, W) uint8 = ``src`` in [0, 1] scaled to 0..255, rounded, clipped."""
    launch(_to_uint8, int(math.prod(src.shape)), src, dst)
