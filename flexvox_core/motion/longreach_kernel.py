"""The long-reach gather compiled (numba): each trajectory read indexes the one pixel that can hold its sample.

An identity code samples sub-frame s = f·K + k at the pixels whose slot is k, from frame f unless that frame was
dropped. A bilinear read at (y, x) of sub-frame s touches the four pixels of the cell at (⌊y⌋, ⌊x⌋); which of them
hold slot k follows from (⌊y⌋ mod m, ⌊x⌋ mod n, k) alone (:func:`corner_table`): with a tile of at least 2×2 at
most one does, and with K = 16 none does three times in four. The kernel therefore reads the frames and the code
(no sample volume, no weight planes) and, for a cell that holds no sample, nothing at all. The sums are those of
the bilinear reads of the sample planes and their 0/1 mask, with exact bilinear weights (OpenCV's remap, which
:func:`~flexvox_core.motion.longreach.long_reach_nc` uses, rounds the position to 1/32 px).

With a tile of at least 2×2 (one pixel of a cell per slot) the reads at the offsets d ≠ 0 run branch-free over a
row's voxels (:func:`_row_reads`), which LLVM vectorizes (8 reads a step, one gather of the frame): each read
finds the pixel of its cell in the slot's row and column of the tile in float32 arithmetic, reads it (clamped in
the picture) and adds its weighted sample where the cell holds it, a select rather than a branch; the sample read
is the pixel itself (a held pixel's n/d, rounded, in the code before) and the range weight is
:func:`~flexvox_core.motion.exp_kernel.exp32`.
The sums are those of float32 rounding: within 3e-7 of the scalar reads on the 1-s balls clip. A 1×n or m×1 tile
(two pixels of a cell per slot) takes the scalar reads, :func:`_row_sums`.

``tests/flexvox_core/motion/longreach_reference.py`` is the same gather in plain numpy, which the tests compare
this against.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numba
import numba.core.compiler
import numpy as np

from flexvox_core.motion.exp_kernel import exp32
from flexvox_core.motion.flow_kernel import flow_at

CORNERS = ((0, 0), (0, 1), (1, 0), (1, 1))
"""The cell's pixels (dy, dx) in the bit order of :func:`corner_table`."""


def corner_table(order: np.ndarray) -> np.ndarray:
    """Which pixels of a bilinear cell hold slot k: uint8 ``(m, n, K)``, bit i set when the pixel
    ``CORNERS[i]`` of the cell whose top-left pixel is at (y, x) ≡ (i, j) mod (m, n) has slot k.

    ``order``: the slot of each pixel of the tile, int ``(m, n)`` (:func:`~flexvox_core.codes.order_from_code`).
    """
    order = np.asarray(order)
    m, n = order.shape
    K = m * n
    table = np.zeros((m, n, K), np.uint8)
    i, j = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
    for bit, (dy, dx) in enumerate(CORNERS):
        slot = order[(i + dy) % m, (j + dx) % n]
        table[i, j, slot] |= np.uint8(1 << bit)
    return table


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def _velocity(flow_t: Any, y: int, x: int) -> tuple[Any, Any]:
    """(u, v) of the voxel (``flow_t``: its sub-frame's plane, or :func:`flow_at`'s small one), NaN or infinity
    read as still (as the GPU's ``velocity``)."""
    u, v = flow_at(flow_t, y, x)
    if not (math.isfinite(u) and math.isfinite(v)):
        return np.float32(0), np.float32(0)
    return u, v


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _row_sums(frames: Any, lat: Any, flow_t: Any, guide: Any, t: int, y: int, xs: Any, count: int, time_w: Any,
              scale: Any, num: Any, den: Any, scratch: Any) -> None:
    """Range-weighted sums (into ``num``, ``den``: row y of sub-frame t) along the trajectories of the voxels
    (t, y, xs[:count]), whose velocity is ``flow_t`` (H, W, 2) at them. ``lat``: the lattice's tables
    (:func:`_lattice`: no division in the loops). The offsets d run outside the voxels: along a row the cells'
    slots repeat, so whether a cell holds the sample is a branch the processor predicts."""
    cells, row_base, col_base, slot_of, frame_of, single = lat[:6]
    S, H, W = guide.shape
    zero = np.float32(0)
    one = np.float32(1)
    us, vs, gs, acc_n, acc_d = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    k = slot_of[t]
    f = frame_of[t]
    own = row_base[y + 1] + k
    for i in range(count):
        x = xs[i]
        u, v = _velocity(flow_t, y, x)
        us[i] = u
        vs[i] = v
        g = guide[t, y, x]
        gs[i] = g
        acc_n[i] = zero
        acc_d[i] = zero
        if k >= 0 and cells[own + col_base[x + 1]] & 1:  # d = 0: the voxel's own sample
            s = frames[f, y, x]
            r = s - g
            e = np.float32(math.exp(scale * r * r)) * time_w[0]
            acc_n[i] = s * e
            acc_d[i] = e
    fy = np.float32(y)
    hi_y = np.float32(H)
    hi_x = np.float32(W)
    lo = np.float32(-1)
    for d in range(1, len(time_w)):
        tw = time_w[d]
        for side in range(2):
            step = d if side == 0 else -d
            tt = t + step
            if tt < 0 or tt >= S:
                continue
            kk = slot_of[tt]
            if kk < 0:  # a dropped frame
                continue
            ff = frame_of[tt]
            fstep = np.float32(step)
            for i in range(count):
                py = fy + fstep * vs[i]
                px = np.float32(xs[i]) + fstep * us[i]
                if not (lo < py < hi_y and lo < px < hi_x):  # no pixel of the cell in the picture (or NaN)
                    continue
                y0 = int(py + one) - 1  # the floor (py > -1)
                x0 = int(px + one) - 1
                bits = cells[row_base[y0 + 1] + col_base[x0 + 1] + kk]
                if bits == 0:
                    continue
                ay = py - np.float32(y0)
                ax = px - np.float32(x0)
                n1 = zero
                d1 = zero
                b = single[bits]
                if b >= 0:  # one pixel of the cell holds the sample (a tile of at least 2×2: always)
                    yy = y0 + (b >> 1)
                    xx = x0 + (b & 1)
                    if 0 <= yy < H and 0 <= xx < W:
                        d1 = (ay if b >> 1 else one - ay) * (ax if b & 1 else one - ax)
                        n1 = d1 * frames[ff, yy, xx]
                else:
                    for b in range(4):
                        if bits & (1 << b):
                            yy = y0 + (b >> 1)
                            xx = x0 + (b & 1)
                            if 0 <= yy < H and 0 <= xx < W:
                                w = (ay if b >> 1 else one - ay) * (ax if b & 1 else one - ax)
                                n1 += w * frames[ff, yy, xx]
                                d1 += w
                if d1 > zero:
                    r = n1 / d1 - gs[i]
                    e = np.float32(math.exp(scale * r * r)) * tw
                    acc_n[i] += n1 * e
                    acc_d[i] += d1 * e
    for i in range(count):
        num[xs[i]] = acc_n[i]
        den[xs[i]] = acc_d[i]


def _without_aliases(dispatcher: Any) -> Any:
    """``dispatcher`` compiling with its array arguments marked ``noalias`` (numba's ``noalias`` flag, which its
    options do not expose): LLVM then vectorizes a loop that stores into one array and gathers from another,
    which it cannot check at run time. The caller passes arrays that share no memory (rows of one array count as
    such: only their data is read or written). A numba without the flag compiles as numba does (the same sums,
    not vectorized)."""
    compiler: Any = getattr(dispatcher, "_compiler", None)
    customize = getattr(compiler, "_customize_flags", None)
    if customize is None or not hasattr(numba.core.compiler.Flags, "noalias"):
        return dispatcher

    def with_noalias(flags: Any) -> Any:
        flags = customize(flags)
        flags.noalias = True
        return flags

    compiler._customize_flags = with_noalias
    return dispatcher


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _row_reads_py(flat: Any, slot_of: Any, frame_of: Any, ky_of: Any, kx_of: Any, vs: Any, us: Any, fx: Any, gs: Any,
                  acc_n: Any, acc_d: Any, count: int, y: int, t: int, time_w: Any, scale: Any, m: int, n: int, H: int,
                  W: int) -> None:
    """The reads at offsets d = 1 .. reach of a row's voxels (:func:`_row_sums_one`), added into ``acc_n``,
    ``acc_d``; ``flat`` the frames (F·H·W,). Branch-free over the voxels, in float32 arithmetic but for the one
    read of the frame: the pixel of the read's cell that can hold the wanted slot's sample is the one in the
    slot's row and column of the tile, (``ky_of``, ``kx_of``)."""
    S = len(slot_of)
    zero = np.float32(0)
    one = np.float32(1)
    half = np.float32(0.5)
    hi_y = np.float32(H)
    hi_x = np.float32(W)
    top_y = np.float32(H - 1)
    top_x = np.float32(W - 1)
    lo = np.float32(-1)
    fm = np.float32(m)
    fn = np.float32(n)
    inv_m = np.float32(one / fm)
    inv_n = np.float32(one / fn)
    fy = np.float32(y)
    for d in range(1, len(time_w)):
        tw = time_w[d]
        for side in range(2):
            step = d if side == 0 else -d
            tt = t + step
            if tt < 0 or tt >= S:
                continue
            kk = slot_of[tt]
            if kk < 0:  # a dropped frame
                continue
            base = frame_of[tt] * (H * W)
            ky = ky_of[kk]
            kx = kx_of[kk]
            cy = np.float32(fm - half - ky)
            cx = np.float32(fn - half - kx)
            fstep = np.float32(step)
            for i in range(count):
                py = fy + fstep * vs[i]
                px = fx[i] + fstep * us[i]
                inside = (lo < py) & (py < hi_y) & (lo < px) & (px < hi_x)
                y0 = np.float32(np.floor(min(max(py, lo), hi_y)))
                x0 = np.float32(np.floor(min(max(px, lo), hi_x)))
                # The slot's row >= y0, ky + m·ceil((y0 − ky)/m) (exact: the floor's argument is half a step from
                # a whole number), and its column; the cell holds the sample when they are within it.
                yy = ky + fm * np.float32(np.floor((y0 + cy) * inv_m))
                xx = kx + fn * np.float32(np.floor((x0 + cx) * inv_n))
                hit = inside & (yy <= y0 + one) & (xx <= x0 + one) & (yy >= zero) & (yy <= top_y) & (
                    xx >= zero) & (xx <= top_x)
                at = min(max(yy, zero), top_y) * hi_x + min(max(xx, zero), top_x)  # exact below 2**24 pixels
                s = flat[base + np.int32(at)]
                ay = py - y0
                ax = px - x0
                w = (ay if yy > y0 else one - ay) * (ax if xx > x0 else one - ax)
                r = s - gs[i]
                e = exp32(scale * r * r) * tw
                acc_n[i] += (w * s) * e if hit else zero
                acc_d[i] += w * e if hit else zero


_row_reads = _without_aliases(_row_reads_py)


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _row_sums_one(frames: Any, lat: Any, flow_t: Any, guide: Any, t: int, y: int, xs: Any, count: int,
                  time_w: Any, scale: Any, num: Any, den: Any, scratch: Any) -> None:
    """:func:`_row_sums` where a cell holds at most one pixel of each slot (a tile of at least 2×2): the voxels' own
    samples here, the reads at d ≠ 0 by :func:`_row_reads` over the voxels padded to whole vectors of 8 (the
    padding reads outside the picture). ``scratch`` (6, W + 8)."""
    cells, row_base, col_base, slot_of, frame_of = lat[:5]
    ky_of, kx_of, m, n = lat[6], lat[7], lat[8], lat[9]
    S, H, W = guide.shape
    zero = np.float32(0)
    us, vs, gs, acc_n, acc_d, fx = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4], scratch[5]
    k = slot_of[t]
    f = frame_of[t]
    own = row_base[y + 1] + k
    for i in range(count):
        x = xs[i]
        u, v = _velocity(flow_t, y, x)
        us[i] = u
        vs[i] = v
        fx[i] = np.float32(x)
        g = guide[t, y, x]
        gs[i] = g
        acc_n[i] = zero
        acc_d[i] = zero
        if k >= 0 and cells[own + col_base[x + 1]] & 1:  # d = 0: the voxel's own sample
            s = frames[f, y, x]
            r = s - g
            e = exp32(scale * r * r) * time_w[0]
            acc_n[i] = s * e
            acc_d[i] = e
    padded = (count + 7) & ~7  # whole vectors of 8: the padding's reads fall outside the picture
    for i in range(count, padded):
        us[i] = zero
        vs[i] = zero
        fx[i] = np.float32(-2)
        gs[i] = zero
        acc_n[i] = zero
        acc_d[i] = zero
    _row_reads(frames.reshape(frames.size), slot_of, frame_of, ky_of, kx_of, vs, us, fx, gs, acc_n, acc_d, padded,
               y, t, time_w, scale, m, n, H, W)
    for i in range(count):
        num[xs[i]] = acc_n[i]
        den[xs[i]] = acc_d[i]


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _lattice(corners: Any, present: Any, S: int, H: int, W: int) -> tuple[Any, ...]:
    """Lookup tables of the lattice: the flat corner table, its offsets for a cell's top-left row y0 (at y0 + 1,
    y0 from −1) and column, each sub-frame's slot (−1 where its frame was dropped) and frame, the corner that
    each one-bit cell names, each slot's row and column in the tile (float32), the tile's shape (m, n), and whether
    :func:`_row_sums_one` applies (a tile of at least 2×2, positions exact in float32: fewer than 2**24 pixels)."""
    m, n, K = corners.shape
    cells = corners.ravel().copy()
    row_base = np.empty(H + 1, np.int64)
    for i in range(H + 1):
        row_base[i] = ((i - 1 + m) % m) * n * K
    col_base = np.empty(W + 1, np.int64)
    for i in range(W + 1):
        col_base[i] = ((i - 1 + n) % n) * K
    slot_of = np.empty(S, np.int64)
    frame_of = np.empty(S, np.int64)
    for tt in range(S):
        frame_of[tt] = tt // K
        slot_of[tt] = tt % K if present[tt // K] else -1
    single = np.full(16, -1, np.int64)  # the corner a cell's bits name when they name one (−1: none, or several)
    for b in range(4):
        single[1 << b] = b
    ky_of = np.empty(K, np.float32)  # the tile's pixel of each slot
    kx_of = np.empty(K, np.float32)
    for i in range(m):
        for j in range(n):
            kk = 0
            for s in range(K):
                if corners[i, j, s] & 1:
                    kk = s
            ky_of[kk] = i
            kx_of[kk] = j
    ones = m >= 2 and n >= 2 and H * W < (1 << 24)
    return cells, row_base, col_base, slot_of, frame_of, single, ky_of, kx_of, m, n, ones


@numba.njit(nogil=True, cache=True, error_model="numpy")
def _subframe(frames: Any, order: Any, lat: Any, flow_t: Any, guide: Any, sel: Any, act: Any, t: int, time_w: Any,
              scale: Any, taps: Any, min_weight: Any, out: Any, num: Any, den: Any, rows: Any, xs: Any,
              scratch: Any, write_samples: bool) -> None:
    """Sub-frame ``t``, its flow ``flow_t`` (H, W, 2), selection ``sel`` (H, W) and the voxels within the blur's
    reach of it ``act`` (H, W; nonzero there: ``sel`` dilated by the blur's square): the sums at ``act`` (into
    ``num``, ``den``), blurred and divided at the selected voxels into ``out[t]``, then (``write_samples``) the
    samples written."""
    S, H, W = guide.shape
    m, n = order.shape
    r = (len(taps) - 1) // 2
    found = False
    for y in range(H):
        rows[y] = False
        for x in range(W):
            if sel[y, x]:
                rows[y] = True
                found = True
                break
    if found:
        for y in range(H):
            count = 0
            for x in range(W):  # the voxels within the blur's reach of `sel`: `act`, its square dilation
                if act[y, x]:
                    xs[count] = x
                    count += 1
            if count:
                if lat[10]:
                    _row_sums_one(frames, lat, flow_t, guide, t, y, xs, count, time_w, scale, num[y], den[y],
                                  scratch)
                else:
                    _row_sums(frames, lat, flow_t, guide, t, y, xs, count, time_w, scale, num[y], den[y], scratch)
        # Blurred (zero outside the picture; every neighbour of a selected voxel was summed) and divided.
        for y in range(H):
            if not rows[y]:
                continue
            for x in range(W):
                if not sel[y, x]:
                    continue
                bn = np.float32(0)
                bd = np.float32(0)
                for i in range(len(taps)):
                    yy = y + i - r
                    if yy < 0 or yy >= H:
                        continue
                    rn = np.float32(0)
                    rd = np.float32(0)
                    for j in range(len(taps)):
                        xx = x + j - r
                        if 0 <= xx < W:
                            rn += taps[j] * num[yy, xx]
                            rd += taps[j] * den[yy, xx]
                    bn += taps[i] * rn
                    bd += taps[i] * rd
                if bd > min_weight:
                    out[t, y, x] = bn / bd
    f = lat[4][t]
    k = lat[3][t]
    if write_samples and k >= 0:
        for y in range(H):
            for j in range(n):
                if order[y % m, j] == k:
                    for x in range(j, W, n):
                        out[t, y, x] = frames[f, y, x]


def long_reach_kernel(frames: Any, order: Any, corners: Any, present: Any, flow: Any, guide: Any, select: Any,
                      time_w: Any, scale: Any, taps: Any, min_weight: Any, out: Any, num: Any, den: Any,
                      write_samples: bool) -> None:
    """The long-reach gather of every sub-frame (see the module's docstring) into ``out`` (may be ``guide``).

    ``frames`` (F, H, W) float32; ``order`` (m, n) int the tile's slots, ``corners`` their
    :func:`corner_table`; ``present`` (F,) bool; ``flow`` (S, H, W, 2) float32 and ``select`` (S, H, W) bool,
    arrays or volumes read a sub-frame at a time (:func:`flexvox_core.planes.band`), a flow with a ``scaled``
    method (:class:`~flexvox_core.flow.estimate.ScaledFlow`) read at the voxels from its small planes
    (:mod:`~flexvox_core.motion.flow_kernel`); ``guide`` (S, H, W) float32; ``time_w`` (reach + 1,) the
    trajectory weights exp(−d²/2σ_t²); ``scale`` −1/2h²; ``taps`` the blur's (odd length); ``num``, ``den`` (C, H, W)
    float32 scratch, one plane pair per chunk of sub-frames run side by
    side (any content) by :func:`flexvox_core.threads.for_each`, each sub-frame one compiled call that releases
    the GIL (:func:`long_reach_subframe`) with its own planes of ``flow`` and ``select``. ``write_samples``: write
    each sub-frame's samples into ``out`` after it. Each voxel's sums are made in one order by one thread: the
    output bits do not depend on the number of chunks or threads.

    The chunks run on Python's threads rather than numba's ``parallel=True``: the parallel kernel took about
    10 s to compile on first use (a fresh install, or a new numba cache) against about 1 s for this one.
    """
    from flexvox_core.planes import band
    from flexvox_core.threads import for_each

    chunks = num.shape[0]
    S, H, W = guide.shape
    frames = np.ascontiguousarray(frames)  # read as planes of H·W pixels
    lat = _lattice(corners, present, S, H, W)

    r = (len(taps) - 1) // 2
    square = np.ones((2 * r + 1, 2 * r + 1), np.uint8)

    def chunk(c: int) -> None:  # sub-frames c, c + chunks, ... (interleaved: a run of busy ones is shared out)
        rows = np.empty(H, np.bool_)
        xs = np.empty(W, np.int64)
        scratch = np.empty((6, W + 8), np.float32)
        act = np.empty((H, W), np.uint8)
        for t in range(c, S, chunks):
            sel = np.ascontiguousarray(band(select, t, t + 1)[0], np.bool_)
            busy = sel.any()
            flow_t: Any = _NO_FLOW
            if busy:  # a flow held small is read at the voxels alone (no full-size plane made: the same bits)
                scaled = getattr(flow, "scaled", None)
                flow_t = scaled(t) if scaled is not None else None
                if flow_t is None:
                    flow_t = np.ascontiguousarray(band(flow, t, t + 1)[0], np.float32)
            if busy:  # within the blur's reach of `sel` (OpenCV's dilation: no pixel outside the picture counts)
                cv2.dilate(sel.view(np.uint8), square, dst=act) if r else np.copyto(act, sel.view(np.uint8))
            long_reach_subframe(frames, order, lat, flow_t, guide, sel, act, t, time_w, scale, taps, min_weight,
                                out, num[c], den[c], rows, xs, scratch, write_samples)

    for_each(chunk, chunks)


_NO_FLOW = np.zeros((1, 1, 2), np.float32)
"""The flow plane passed for a sub-frame without a selected voxel (not read)."""


@numba.njit(nogil=True, cache=True, error_model="numpy")
def long_reach_subframe(frames: Any, order: Any, lat: Any, flow_t: Any, guide: Any, sel: Any, act: Any, t: int,
                        time_w: Any, scale: Any, taps: Any, min_weight: Any, out: Any, num: Any, den: Any,
                        rows: Any, xs: Any, scratch: Any, write_samples: bool) -> None:
    """Sub-frame ``t`` of :func:`long_reach_kernel`: its flow ``flow_t`` (H, W, 2), selection ``sel`` (H, W) and
    the voxels within the blur's reach of it ``act`` (H, W uint8, read only where ``sel`` has a voxel), the
    lattice's tables ``lat`` (:func:`_lattice`), scratch ``num``, ``den`` (H, W), ``rows``, ``xs`` (W,) and ``scratch``
    (6, W + 8)."""
    _subframe(frames, order, lat, flow_t, guide, sel, act, t, time_w, scale, taps, min_weight, out, num, den,
              rows, xs, scratch, write_samples)
