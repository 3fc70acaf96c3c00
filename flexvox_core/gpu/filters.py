"""Separable filters on stacks of planes (N, H, W) on the GPU, each the twin of the OpenCV or scipy call named.

* :func:`blur` — ``cv2.GaussianBlur`` / ``cv2.sepFilter2D`` with given taps, reflecting (``BORDER_REFLECT``,
  the edge repeated) or zero borders, one pass per axis, on a stack of planes or a pair of stacks;
* :func:`tap_sum` — the one separable blur of one pixel along one axis, in OpenCV's summation order, that
  :func:`blur` and every GPU kernel fusing a blur with more work call (over :func:`reflected`, :func:`zeroed`
  or a value computed where it is read);
* :func:`dilate` — ``cv2.dilate`` with a square of ones (pixels outside the picture never count);
* :func:`sobel_slopes` — :func:`flexvox_core.slopes.slopes` after its blur: Sobel's 3×3 derivatives / 8;
* :func:`box_in_time` — ``scipy.ndimage.uniform_filter1d(v, K, axis=0, mode="nearest")``;
* :func:`gaussian_taps` — the taps ``cv2.GaussianBlur`` uses for a float picture and a σ.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import cv2
import numpy as np
from numba import cuda

from flexvox_core.gpu.index import reflect, voxel
from flexvox_core.gpu.launch import device, kernel, launch


@lru_cache(maxsize=64)
def gaussian_taps(sigma: float, size: int | None = None) -> np.ndarray:
    """The float32 taps ``cv2.GaussianBlur`` uses on a float32 picture with this σ (size round(8σ + 1), made odd,
    as OpenCV picks for float pictures; or ``size``)."""
    n = size if size is not None else int(round(sigma * 8 + 1)) | 1
    return np.ascontiguousarray(cv2.getGaussianKernel(n, sigma, ktype=cv2.CV_32F).ravel())


@device
def reflected(src, n, y, x, H, W):
    """``src[n, y, x]`` with the picture reflected past its edges (the edge repeated: ``BORDER_REFLECT``)."""
    return src[n, reflect(y, H), reflect(x, W)]


@device
def zeroed(src, n, y, x, H, W):
    """``src[n, y, x]``, 0 past the picture's edges (``BORDER_CONSTANT``)."""
    if y < 0 or y >= H or x < 0 or x >= W:
        return np.float32(0)
    return src[n, y, x]


@device
def tap_sum(value, src, n, y, x, H, W, taps, axis):
    """The blur of one pixel along one axis: the odd, symmetric float32 ``taps`` (h = len // 2 each side) centred
    on (y, x) of plane n, over ``value(src, n, y', x', H, W)`` (:func:`reflected`, :func:`zeroed`, or a value
    computed where it is read). Summed in float32 in OpenCV's order, the same in every kernel: along x (axis 2,
    OpenCV's row pass) left to right, Σ taps[t]·v[x + t − h]; along y (axis 1, its column pass of a symmetric
    kernel) the centre first, then taps[h + t]·(v[y − t] + v[y + t]) for t = 1 … h."""
    h = taps.shape[0] // 2
    if axis == 2:
        acc = np.float32(0)
        for t in range(taps.shape[0]):
            acc += taps[t] * value(src, n, y, x + t - h, H, W)
        return acc
    acc = taps[h] * value(src, n, y, x, H, W)
    for t in range(1, h + 1):
        acc += taps[h + t] * (value(src, n, y - t, x, H, W) + value(src, n, y + t, x, H, W))
    return acc


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1], float32[::1], int32, "
        "uint8, uint8)")
def _blur_pass(src, src2, dst, dst2, taps, axis, mirror, pair):
    """One pass of :func:`blur` along y (axis 1) or x (axis 2), reflecting (``mirror``) or zero borders; with
    ``pair``, the second stack too (one thread reads both; without, ``src2`` and ``dst2`` are not touched)."""
    i = cuda.grid(1)
    N, H, W = src.shape
    if i >= N * H * W:
        return
    n, y, x = voxel(i, H, W)
    if mirror:
        dst[n, y, x] = tap_sum(reflected, src, n, y, x, H, W, taps, axis)
        if pair:
            dst2[n, y, x] = tap_sum(reflected, src2, n, y, x, H, W, taps, axis)
    else:
        dst[n, y, x] = tap_sum(zeroed, src, n, y, x, H, W, taps, axis)
        if pair:
            dst2[n, y, x] = tap_sum(zeroed, src2, n, y, x, H, W, taps, axis)


def symmetric_taps(taps, name: str = "taps") -> np.ndarray:
    """``taps`` as a contiguous float32 array, checked odd in length and symmetric (what :func:`tap_sum` sums)."""
    t = np.ascontiguousarray(taps, np.float32)
    if t.ndim != 1 or t.size % 2 != 1 or not np.array_equal(t, t[::-1]):
        raise ValueError(f"`{name}` must be a 1-D kernel of odd length, symmetric about its centre; got {t!r}")
    return t


def blur(ws, src, dst, taps_y, taps_x, *, reflect: bool = True, tag: str = "blur", scratch=None) -> None:
    """``dst`` = ``src`` (N, H, W) float32 filtered along x by ``taps_x``, then along y by ``taps_y`` (host float32
    arrays, odd and symmetric; None: not along that axis), as ``cv2.sepFilter2D(src, -1, taps_x, taps_y)`` with
    ``BORDER_REFLECT`` (``reflect``) or ``BORDER_CONSTANT`` (0) and float32 sums in its order (:func:`tap_sum`).
    ``dst`` may be ``src``. Two stacks at once: ``src`` and ``dst`` pairs of stacks of one shape. ``scratch``:
    the plane stack (a pair with pairs) between the passes; None: the workspace's ``{tag}.tmp``."""
    pair = isinstance(src, tuple)
    srcs: tuple[Any, ...] = src if pair else (src,)
    dsts: tuple[Any, ...] = dst if pair else (dst,)
    passes = [(2, t) for t in (taps_x,) if t is not None] + [(1, t) for t in (taps_y,) if t is not None]
    if not passes:
        for s, d in zip(srcs, dsts, strict=True):
            if d is not s:
                d.copy_to_device(s)
        return
    shape = tuple(srcs[0].shape)
    if scratch is None:
        tmps = tuple(ws.get(f"{tag}.tmp{'' if k == 0 else k + 1}", shape) for k in range(len(srcs)))
    else:
        tmps = tuple(scratch) if pair else (scratch,)
    n = int(math.prod(shape))
    cur: tuple[Any, ...] = srcs
    for k, (axis, taps) in enumerate(passes):
        last = k == len(passes) - 1
        out = dsts if last and dsts[0] is not cur[0] else tmps
        if out[0] is cur[0]:  # one pass in place: through the scratch planes
            out = tmps
        src2, dst2 = (cur[1], out[1]) if pair else (cur[0], out[0])
        launch(_blur_pass, n, cur[0], src2, out[0], dst2,
               ws.put(f"{tag}.taps{axis}", symmetric_taps(taps, "taps_x" if axis == 2 else "taps_y")),
               np.int32(axis), np.uint8(reflect), np.uint8(pair))
        cur = out
    for c, d in zip(cur, dsts, strict=True):
        if c is not d:
            d.copy_to_device(c)


@kernel("void(uint8[:, :, ::1], uint8[:, :, ::1], int32, int32)")
def _max_pass(src, dst, radius, axis):
    i = cuda.grid(1)
    N, H, W = src.shape
    if i >= N * H * W:
        return
    n, y, x = voxel(i, H, W)
    found = 0
    if axis == 1:
        for t in range(max(0, y - radius), min(H, y + radius + 1)):
            if src[n, t, x]:
                found = 1
                break
    else:
        for t in range(max(0, x - radius), min(W, x + radius + 1)):
            if src[n, y, t]:
                found = 1
                break
    dst[n, y, x] = found


def dilate(ws, mask, out, radius: int, *, tag: str = "dilate") -> None:
    """``out`` = ``mask`` (N, H, W) uint8 dilated by a (2·radius + 1)² square (``out`` is not ``mask``)."""
    if radius <= 0:
        out.copy_to_device(mask)
        return
    tmp = ws.get(f"{tag}.tmp", mask.shape, np.uint8)
    n = int(math.prod(mask.shape))
    launch(_max_pass, n, mask, tmp, np.int32(radius), np.int32(1))
    launch(_max_pass, n, tmp, out, np.int32(radius), np.int32(2))


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1])")
def _sobel(p, gx, gy):
    i = cuda.grid(1)
    N, H, W = p.shape
    if i >= N * H * W:
        return
    n, y, x = voxel(i, H, W)
    ym, yp, xm, xp = reflect(y - 1, H), reflect(y + 1, H), reflect(x - 1, W), reflect(x + 1, W)
    # Sobel: derivative [-1, 0, 1] along the axis, smoothing [1, 2, 1] across it; scaled by 1/8.
    dx = (p[n, ym, xp] - p[n, ym, xm]) + np.float32(2) * (p[n, y, xp] - p[n, y, xm]) + (p[n, yp, xp] - p[n, yp, xm])
    dy = (p[n, yp, xm] - p[n, ym, xm]) + np.float32(2) * (p[n, yp, x] - p[n, ym, x]) + (p[n, yp, xp] - p[n, ym, xp])
    gx[n, y, x] = dx * np.float32(0.125)
    gy[n, y, x] = dy * np.float32(0.125)


def sobel_slopes(ws, picture, gx, gy, sigma: float, *, tag: str = "slopes") -> None:
    """(∂x, ∂y) of each plane of ``picture`` (N, H, W) blurred by ``sigma`` px, as
    :func:`flexvox_core.slopes.slopes` (reflecting borders), into ``gx``, ``gy``."""
    taps = gaussian_taps(sigma)
    smooth = ws.get(f"{tag}.smooth", picture.shape)
    blur(ws, picture, smooth, taps, taps, tag=tag)
    launch(_sobel, int(math.prod(picture.shape)), smooth, gx, gy)


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], int32)")
def _box_in_time(src, dst, size):
    i = cuda.grid(1)
    S, H, W = src.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    acc = 0.0
    for t in range(s - size // 2, s - size // 2 + size):
        acc += src[min(max(t, 0), S - 1), y, x]
    dst[s, y, x] = acc / size


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], int32)")
def _box_in_time_2(src, dst, size):
    i = cuda.grid(1)
    S, H, W, C = src.shape
    if i >= S * H * W * C:
        return
    s = i // (H * W * C)
    p = i - s * (H * W * C)
    y = p // (W * C)
    x = (p // C) % W
    c = p % C
    acc = 0.0
    for t in range(s - size // 2, s - size // 2 + size):
        acc += src[min(max(t, 0), S - 1), y, x, c]
    dst[s, y, x, c] = acc / size


def box_in_time(src, dst, size: int) -> None:
    """``dst`` = the moving average of ``size`` sub-frames of ``src`` (S, H, W) or (S, H, W, 2) float32, edges
    held (``uniform_filter1d(src, size, axis=0, mode="nearest")``: sub-frames s − size//2 … s − size//2 +
    size − 1), summed in float64."""
    n = int(math.prod(src.shape))
    launch(_box_in_time if len(src.shape) == 3 else _box_in_time_2, n, src, dst, np.int32(size))
