"""Normalized convolution along time alone (a tensor (0, 0, c_t)), compiled (numba): one pass per output row.

With no spatial blur each pixel's estimate depends only on its own samples: one per camera frame, at
its slot. The time Gaussian then reaches a handful of them per sub-frame (2 r / K + 1 at K slots and
kernel radius r), instead of blurring the whole volume of mostly-zero sub-frames along time. The
weights depend only on the sub-frame s, the pixel's slot k and the frame f: a small table
``weight[s, k, b]`` for frames f = ``first[s]`` + b, normalised (divided by their sum, the blurred
mask). Each voxel is written once, from a float64 sum in a fixed order: the output bits do not depend on the number of
threads. :func:`flexvox_core.reconstruct.diffusion.diffuse` keeps the general path (spatial blur of
every sub-frame, then the time blur) as the reference the tests compare this against.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(nogil=True, cache=True)
def time_only_rows(frames, order, weight, first, lo, hi, out, y0, y1):
    """Rows [y0, y1) of every sub-frame of ``out`` (S, H, W): Σ_b weight[s, k, b] · frames[first[s] + b]
    (k = order[y, x], the weights normalised to sum 1), clipped to [lo, hi]. ``order`` repeats every
    m rows (a tiled code: m = its first axis)."""
    S = out.shape[0]
    W = out.shape[2]
    B = weight.shape[2]
    m = order.shape[0]
    row_w = np.empty((m, B, W), np.float64)  # a sub-frame's weights along each row of the tile
    acc = np.empty(W, np.float64)
    for s in range(S):
        f0 = first[s]
        for ym in range(m):
            for b in range(B):
                for x in range(W):
                    row_w[ym, b, x] = weight[s, order[ym, x], b]
        for y in range(y0, y1):
            w = row_w[y % m]
            for x in range(W):
                acc[x] = 0.0
            for b in range(B):  # each row a contiguous pass: the compiler vectorises it
                src = frames[f0 + b, y]
                wb = w[b]
                for x in range(W):
                    acc[x] += wb[x] * src[x]
            dst = out[s, y]
            for x in range(W):
                dst[x] = min(max(acc[x], lo), hi)


def warm_up() -> None:
    """Compile (or load from the cache) the kernel for float32 output."""
    time_only_rows(np.zeros((1, 1, 1), np.float32), np.zeros((1, 1), np.int64), np.ones((1, 1, 1)),
                   np.zeros(1, np.int64), 0.0, 1.0, np.empty((1, 1, 1), np.float32), 0, 1)
