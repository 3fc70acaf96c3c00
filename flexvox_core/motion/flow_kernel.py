"""A sub-frame's flow read at single voxels in compiled code, from its full-size plane or from the small plane a
:class:`~flexvox_core.flow.estimate.ScaledFlow` holds (the same bits: no full-size plane made for a few voxels)."""

from __future__ import annotations

from typing import Any

import numba
import numba.extending


def flow_at(flow_t: Any, y: int, x: int) -> tuple[Any, Any]:
    """(u, v) at the voxel (y, x) of a sub-frame's flow ``flow_t``: its full-size plane (H, W, 2), or
    :meth:`~flexvox_core.flow.estimate.ScaledFlow.scaled`'s tuple (the small plane and the resize's tables), read as
    :func:`~flexvox_core.flow.estimate.resize_at` reads it (the same bits as the plane). Compiled code takes the
    overload below; this is the same in Python (float32 numpy scalars)."""
    if not isinstance(flow_t, tuple):
        return flow_t[y, x, 0], flow_t[y, x, 1]
    p, rows0, rows1, wy0, wy1, cols0, cols1, wx0, wx1 = flow_t
    r0, r1, c0, c1 = rows0[y], rows1[y], cols0[x], cols1[x]
    a0, a1, b0, b1 = wx0[x], wx1[x], wy0[y], wy1[y]
    u = (p[r0, c0, 0] * a0 + p[r0, c1, 0] * a1) * b0 + (p[r1, c0, 0] * a0 + p[r1, c1, 0] * a1) * b1
    v = (p[r0, c0, 1] * a0 + p[r0, c1, 1] * a1) * b0 + (p[r1, c0, 1] * a0 + p[r1, c1, 1] * a1) * b1
    return u, v


@numba.extending.overload(flow_at, inline="always")
def _flow_at(flow_t, y, x):  # type: ignore[no-untyped-def]  # numba: the implementations' names, unannotated
    if isinstance(flow_t, numba.types.Array):
        def plane(flow_t, y, x):  # type: ignore[no-untyped-def]
            return flow_t[y, x, 0], flow_t[y, x, 1]

        return plane

    def small(flow_t, y, x):  # type: ignore[no-untyped-def]
        p, rows0, rows1, wy0, wy1, cols0, cols1, wx0, wx1 = flow_t
        r0 = rows0[y]
        r1 = rows1[y]
        c0 = cols0[x]
        c1 = cols1[x]
        a0 = wx0[x]
        a1 = wx1[x]
        b0 = wy0[y]
        b1 = wy1[y]
        u = (p[r0, c0, 0] * a0 + p[r0, c1, 0] * a1) * b0 + (p[r1, c0, 0] * a0 + p[r1, c1, 0] * a1) * b1
        v = (p[r0, c0, 1] * a0 + p[r0, c1, 1] * a1) * b0 + (p[r1, c0, 1] * a0 + p[r1, c1, 1] * a1) * b1
        return u, v

    return small
