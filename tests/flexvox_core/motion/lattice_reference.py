"""The trajectory gather's kernel a voxel at a time (:func:`lattice_sums_by_voxel`), as it was before
:func:`flexvox_core.motion.mcnc_kernel.lattice_sums` ran each row's voxels as a list with its offsets outside it
(numba's ``math.exp``), and variants of it (:func:`kernel_by_voxel`: every read clamped into the picture, as before
the cells wholly in the picture were read without clamping; the kernel's ``exp32``); the kernel with numba's exp
(:func:`rows_with_libm_exp`): for the tests' bit-for-bit comparisons and the benchmark's variants. Compiled by
numba, not cached on disk."""

import functools
import inspect
import math
import sys
import types
from typing import Any

import numba
import numpy as np

from flexvox_core.motion.mcnc_kernel import own_reach

FAST_PATH = "    if 0 <= y0 and y0 < H - 1 and 0 <= x0 and x0 < W - 1:"
CLAMPED = "    ya = min(max(y0, -1), H)"
LIBM_EXP = "e = np.float32(math.exp(-(one + u * u + v * v) * inv_4nc1))"
KERNEL_EXP = "e = exp32(-(one + u * u + v * v) * inv_4nc1)"


@numba.njit(inline="always", nogil=True, cache=False)
def _read(frames: Any, row_hit: Any, col_hit: Any, f: int, k: int, py: Any, px: Any, H: int, W: int
          ) -> tuple[Any, Any]:
    """Bilinear read at (py, px) of slot ``k``'s samples in frame ``f``, and of their mask. ``row_hit[k, y + 1]``
    (y from −1 to H) is 1 where row y holds slot k's samples, ``col_hit[k, x + 1]`` likewise, 0 outside the
    picture: a corner holds a sample where both are 1 (an identity code's slot: one pixel of each tile).
    Branch-free but for one test: a cell wholly in the picture is read as it is, another's four corners clamped
    into the picture (and onto the tables' 0 outside it); the corners are weighted by the tables."""
    y0 = int(py)  # the floor (py, px are finite): 20 % faster than math.floor here
    y0 -= py < y0
    x0 = int(px)
    x0 -= px < x0
    ay = np.float32(py - np.float32(y0))
    ax = np.float32(px - np.float32(x0))
    one = np.float32(1)
    if 0 <= y0 and y0 < H - 1 and 0 <= x0 and x0 < W - 1:  # the whole cell in the picture: no clamping
        wya = (one - ay) * row_hit[k, y0 + 1]
        wyb = ay * row_hit[k, y0 + 2]
        wxa = (one - ax) * col_hit[k, x0 + 1]
        wxb = ax * col_hit[k, x0 + 2]
        val = (wya * (wxa * frames[f, y0, x0] + wxb * frames[f, y0, x0 + 1])
               + wyb * (wxa * frames[f, y0 + 1, x0] + wxb * frames[f, y0 + 1, x0 + 1]))
        return val, (wya + wyb) * (wxa + wxb)
    ya = min(max(y0, -1), H)  # -1 and H: outside the picture, the tables' 0
    yb = min(max(y0 + 1, -1), H)
    xa = min(max(x0, -1), W)
    xb = min(max(x0 + 1, -1), W)
    wya = (one - ay) * row_hit[k, ya + 1]
    wyb = ay * row_hit[k, yb + 1]
    wxa = (one - ax) * col_hit[k, xa + 1]
    wxb = ax * col_hit[k, xb + 1]
    ia = min(max(ya, 0), H - 1)
    ib = min(max(yb, 0), H - 1)
    ja = min(max(xa, 0), W - 1)
    jb = min(max(xb, 0), W - 1)
    val = (wya * (wxa * frames[f, ia, ja] + wxb * frames[f, ia, jb])
           + wyb * (wxa * frames[f, ib, ja] + wxb * frames[f, ib, jb]))
    return val, (wya + wyb) * (wxa + wxb)



@numba.njit(nogil=True, cache=False)
def lattice_sums_by_voxel(frames: Any, present: Any, row_hit: Any, col_hit: Any, flow_t: Any, near: Any, y0: int,
                          x0: int, t: int, S: int, inv_4nc1: Any, reach: int, num: Any, den: Any,
                          thresholds: Any) -> None:
    """:func:`~flexvox_core.motion.mcnc_kernel.lattice_sums` a voxel at a time (its offsets inside the voxel's
    loop), as it was before it ran a row's voxels as a list: the same arguments, the same bits (a test)."""
    K = row_hit.shape[0]
    H = frames.shape[1]
    W = frames.shape[2]
    h, w = near.shape
    one = np.float32(1)
    f_t = t // K
    k_t = t - f_t * K
    own = present[f_t]
    for i in range(h):
        y = y0 + i
        own_row = own and row_hit[k_t, y + 1] > 0
        for j in range(w):
            if not near[i, j]:
                num[i, j] = 0
                den[i, j] = 0
                continue
            x = x0 + j
            u = flow_t[y, x, 0]
            v = flow_t[y, x, 1]
            if not (math.isfinite(u) and math.isfinite(v)):
                u = np.float32(0)
                v = np.float32(0)
            e = np.float32(math.exp(-(one + u * u + v * v) * inv_4nc1))
            if len(thresholds):
                r = 0
                for d in range(1, reach + 1):  # own_reach(e, reach), branch-free
                    r += e >= thresholds[d]
            else:
                r = own_reach(e, reach)
            acc_n = np.float32(0)
            acc_d = np.float32(0)
            if own_row and col_hit[k_t, x + 1] > 0:
                acc_n = frames[f_t, y, x]
                acc_d = one
            e2 = e * e
            wd = one
            step = e
            fx = np.float32(x)
            fy = np.float32(y)
            bx = np.float32(x)
            by = np.float32(y)
            # The frame and slot of sub-frames t + d and t - d, stepped along with d (no division per read).
            ff = bf = f_t
            fk = bk = k_t
            for d in range(1, r + 1):
                wd *= step
                step *= e2
                fx += u
                fy += v
                bx -= u
                by -= v
                fk += 1
                if fk == K:
                    fk = 0
                    ff += 1
                bk -= 1
                if bk < 0:
                    bk = K - 1
                    bf -= 1
                if t + d < S and present[ff]:
                    a, b = _read(frames, row_hit, col_hit, ff, fk, fy, fx, H, W)
                    acc_n += wd * a
                    acc_d += wd * b
                if t - d >= 0 and present[bf]:
                    a, b = _read(frames, row_hit, col_hit, bf, bk, by, bx, H, W)
                    acc_n += wd * a
                    acc_d += wd * b
            num[i, j] = acc_n
            den[i, j] = acc_d


@functools.cache
def kernel_by_voxel(*, clamped: bool = False, exp32: bool = False):
    """:func:`lattice_sums_by_voxel` compiled from this module's source: with every read clamped (without the path
    of the cells wholly in the picture), and/or with :func:`~flexvox_core.motion.exp_kernel.exp32` for
    numba's ``math.exp`` (the kernel's exp since it was vectorized: the tests' bit-for-bit references)."""
    source = inspect.getsource(sys.modules[__name__])
    if clamped:
        start, end = source.index(FAST_PATH), source.index(CLAMPED)
        source = source[:start] + source[end:]
    if exp32:
        kernel = source.index("def lattice_sums_by_voxel(")
        assert source[kernel:].count(LIBM_EXP) == 1
        source = (source[:kernel].replace("import own_reach", "import exp32, own_reach")
                  + source[kernel:].replace(LIBM_EXP, KERNEL_EXP))
    module = types.ModuleType("lattice_reference_variant")
    exec(compile(source, "<lattice_reference, a variant>", "exec"), module.__dict__)  # noqa: S102
    return module.lattice_sums_by_voxel


def clamped_lattice_sums():
    """:func:`lattice_sums_by_voxel` with every read clamped: the kernel before the cells wholly in the picture
    were read without clamping."""
    return kernel_by_voxel(clamped=True)


@functools.cache
def rows_with_libm_exp():
    """:func:`~flexvox_core.motion.mcnc_kernel.lattice_sums` with numba's ``math.exp`` for ``exp32`` (compiled from
    that module's source): the kernel before its exp was vectorized."""
    from flexvox_core.motion import mcnc_kernel

    source = inspect.getsource(mcnc_kernel).replace("cache=True", "cache=False")
    assert source.count(KERNEL_EXP) == 1
    source = source.replace(KERNEL_EXP, LIBM_EXP)
    module = types.ModuleType("mcnc_kernel_libm_exp")
    exec(compile(source, "<mcnc_kernel, libm exp>", "exec"), module.__dict__)  # noqa: S102
    return module.lattice_sums
