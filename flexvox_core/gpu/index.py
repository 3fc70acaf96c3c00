"""Device functions every kernel uses to find its element: from its thread's flat index, and past a border."""

from __future__ import annotations

from flexvox_core.gpu.launch import device


@device
def voxel(i, H, W):
    """The flat index ``i`` of an (N, H, W) array as (n, y, x)."""
    hw = H * W
    n = i // hw
    p = i - n * hw
    y = p // W
    return n, y, p - y * W


@device
def reflect(i, n):
    """Index ``i`` reflected into [0, n) with the edge repeated (… 1 0 | 0 1 … n-1 | n-1 …, OpenCV's
    ``BORDER_REFLECT``), however far outside; no integer division for an index already inside."""
    if 0 <= i < n:
        return i
    period = 2 * n
    j = i % period
    if j < 0:
        j += period
    if j >= n:
        j = period - 1 - j
    return j
