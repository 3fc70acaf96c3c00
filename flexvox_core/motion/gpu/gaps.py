"""Dropped frames bridged on the GPU: :func:`flexvox_core.gaps.bridge_flow` and :func:`flexvox_core.gaps.bridge`
(with the flow) on device arrays.

For each gap the host works out which sub-frames change and the two sides they blend (a few numbers per
sub-frame); one launch per gap then writes all of that gap's voxels (a gap reads only the sub-frames outside it,
and a later gap may read what an earlier one wrote, as on the CPU). The video's sides are read where the voxel
was at that time, bilinear with the picture's edge repeated (OpenCV's ``BORDER_REPLICATE``).
"""

from __future__ import annotations

import numpy as np
from numba import cuda

from flexvox_core.gaps import find_gaps
from flexvox_core.gpu.launch import kernel, launch
from flexvox_core.motion.gpu.vardiff import _clamped_bilinear


@kernel("void(float32[:, :, :, ::1], int32, int32, int32, int32)")
def _bridge_flow_span(flow, lo, hi, a, b):
    """Sub-frames lo < t < hi: the straight line between the flows at a and b (one side held past an end)."""
    i = cuda.grid(1)
    S, H, W, _ = flow.shape
    n = hi - lo - 1
    if i >= n * H * W:
        return
    t = lo + 1 + i // (H * W)
    p = i - (t - lo - 1) * (H * W)
    y = p // W
    x = p - y * W
    for c in range(2):
        if a < 0 and b >= S:
            flow[t, y, x, c] = 0
        elif a < 0:
            flow[t, y, x, c] = flow[b, y, x, c]
        elif b >= S:
            flow[t, y, x, c] = flow[a, y, x, c]
        else:
            w = np.float32((t - a) / (b - a))
            flow[t, y, x, c] = (np.float32(1) - w) * flow[a, y, x, c] + w * flow[b, y, x, c]


def bridge_flow(flow, missing, K: int, margin: int) -> None:
    """:func:`flexvox_core.gaps.bridge_flow` on the device flow (S, H, W, 2), in place."""
    S, H, W, _ = flow.shape
    for g in find_gaps(missing):
        a, b = g.start * K - 1 - margin, g.stop * K + margin
        lo, hi = max(a, -1), min(b, S)
        launch(_bridge_flow_span, (hi - lo - 1) * H * W, flow, np.int32(lo), np.int32(hi), np.int32(a), np.int32(b))


@kernel("void(float32[:, :, ::1], float32[:, :, :, ::1], int32, int32, int32, int32)")
def _bridge_gap(video, flow, t0, t1, a, b):
    """Sub-frames t0 <= t < t1 of a gap between sub-frames a and b (−1: no side there)."""
    i = cuda.grid(1)
    S, H, W = video.shape
    if i >= (t1 - t0) * H * W:
        return
    t = t0 + i // (H * W)
    p = i - (t - t0) * (H * W)
    y = p // W
    x = p - y * W
    one = np.float32(1)
    if b < 0:
        w = np.float32(0)
    elif a < 0:
        w = one
    else:
        w = np.float32((t - a) / (b - a))
    u = np.float32(0)
    v = np.float32(0)
    if a >= 0:
        u += (one - w) * flow[a, y, x, 0]
        v += (one - w) * flow[a, y, x, 1]
    if b >= 0:
        u += w * flow[b, y, x, 0]
        v += w * flow[b, y, x, 1]
    out = np.float32(0)
    if a >= 0 and w != one:
        steps = np.float32(t - a)
        out += (one - w) * _clamped_bilinear(video, a, np.float32(y) - steps * v, np.float32(x) - steps * u, H, W)
    if b >= 0 and w != 0:
        steps = np.float32(t - b)
        out += w * _clamped_bilinear(video, b, np.float32(y) - steps * v, np.float32(x) - steps * u, H, W)
    video[t, y, x] = out
    flow[t, y, x, 0] = u
    flow[t, y, x, 1] = v


def bridge(video, flow, missing, K: int) -> None:
    """:func:`flexvox_core.gaps.bridge` with the flow, on device arrays, in place (``video`` (S, H, W) and
    ``flow`` (S, H, W, 2) float32)."""
    m = np.asarray(missing, bool)
    S, H, W = video.shape
    if S != len(m) * K:
        raise ValueError(f"`video` has {S} sub-frames; {len(m)} frames at K = {K} make {len(m) * K}")
    for g in find_gaps(m):
        a, b = g.start * K - 1, g.stop * K
        if a < 0 and b >= S:
            raise ValueError("every frame is missing: there is no side to bridge from")
        launch(_bridge_gap, (g.stop - g.start) * K * H * W, video, flow, np.int32(g.start * K), np.int32(g.stop * K),
               np.int32(a), np.int32(b if b < S else -1))
