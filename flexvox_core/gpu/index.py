"""Device functions every kernel uses to find its element from its thread's flat index."""

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
