r"""Long-reach trajectory gather for slow motion, with samples weighted by how well they agree.

Where things stand still or move slowly, a pixel's own samples (one every K sub-frames) and
its neighbours' along an accurate trajectory describe the same scene point for a long time,
so the estimate may reach far in time and hardly at all in space — the limit c → (0, 0, 1) of
Eq. 4's tensor, which keeps texture down to the pixel. A long reach also collects samples from
across an occlusion or a wrong flow vector. Each sample is therefore weighted, besides its
trajectory weight, by its agreement with a short-reach ``guide`` (a *range* weight, as in a
bilateral filter):

.. math::

    w = \exp\left(-\frac{d^2}{2\sigma_t^2}\right) \exp\left(-\frac{(s - g)^2}{2h^2}\right),

d the sub-frame offset, s the sample read at x + d·(u, v) (bilinear: with an identity code
at most one of the four pixels read holds a sample of sub-frame t + d, so s is that sample),
g the guide at (x, t); then a spatial Gaussian blur σ_s across the trajectories.

Two implementations compute it: :func:`long_reach`, which the engines run, reads the camera frames and
the code and, for each read, only the pixel that can hold its sample (compiled:
:mod:`~flexvox_core.motion.longreach_kernel`); :func:`long_reach_nc` remaps a sample volume and its
mask (OpenCV, positions rounded to 1/32 px), as the engines did before, and stays as a second
reference for the tests and the benchmarks' "before".

Measured on the accuracy benchmark (96×128, K = 16, slow voxels only): the slow pan gains
2 dB over the short-reach gather; without the range weight (h → ∞) the same reach *loses*
0.5–0.9 dB on the bouncing balls and the drummer (samples from across the balls' edges).

References
----------
C. Tomasi, R. Manduchi, "Bilateral filtering for gray and color images", ICCV 1998, pp. 839–846.
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Flexible voxels for motion-aware videography",
ECCV 2010 (the paper).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from flexvox_core.motion.subframes import flow_at, sample_planes
from flexvox_core.threads import for_each

MIN_WEIGHT = 1e-6


@dataclass(frozen=True)
class LongReachPlan:
    """The long-reach gather's parameters, checked, as both engines run them (:meth:`of`)."""

    reach: int
    """Largest |d| in sub-frames, at most S − 1."""
    sigma_t: float
    sigma_s: float
    h: float

    @classmethod
    def of(cls, S: int, *, reach: int, sigma_t: float, sigma_s: float = 0.3, h: float = 0.1) -> LongReachPlan:
        """The plan over ``S`` sub-frames; a value out of its range raises ValueError naming it."""
        for name, value, ok in (("reach", reach, isinstance(reach, int | np.integer) and reach >= 0),
                                ("sigma_t", sigma_t, math.isfinite(sigma_t) and sigma_t > 0),
                                ("sigma_s", sigma_s, math.isfinite(sigma_s) and sigma_s >= 0),
                                ("h", h, math.isfinite(h) and h > 0)):
            if not ok:
                raise ValueError(f"`{name}` must be a finite number > 0 (`reach`, `sigma_s`: >= 0); got {value!r}")
        return cls(min(int(reach), S - 1), float(sigma_t), float(sigma_s), float(h))

    @property
    def radius(self) -> int:
        """The spatial blur's radius in pixels (0: no blur, for σ_s up to 0.05)."""
        return int(math.ceil(3 * self.sigma_s)) if self.sigma_s > 0.05 else 0

    @property
    def time_weights(self) -> np.ndarray:
        """The trajectory weights exp(−d²/2σ_t²) for d = 0 … ``reach``: float32 ``(reach + 1,)``."""
        d = np.arange(self.reach + 1, dtype=np.float64)
        return np.exp(-d * d / (2 * self.sigma_t * self.sigma_t)).astype(np.float32)

    @property
    def range_scale(self) -> float:
        """−1/2h²: the range weight is exp(``range_scale`` · (s − g)²)."""
        return -0.5 / (self.h * self.h)

    @property
    def taps(self) -> np.ndarray:
        """The spatial blur's taps, float32 ``(2·radius + 1,)``: ``cv2.GaussianBlur``'s for σ_s ([1] for none)."""
        if not self.radius:
            return np.ones(1, np.float32)
        return np.ascontiguousarray(cv2.getGaussianKernel(2 * self.radius + 1, self.sigma_s, ktype=cv2.CV_32F).ravel())


def long_reach(frames, code, flow, guide, select, plan: LongReachPlan, *, missing=None,
               out: np.ndarray | None = None, write_samples: bool = False) -> np.ndarray:
    """Range-weighted trajectory gather at the voxels in ``select``, read from the camera frames (compiled).

    The gather of :func:`long_reach_nc` (the same sums, with exact bilinear weights), each read indexing only
    the pixel of its cell that holds the wanted slot's sample (:mod:`~flexvox_core.motion.longreach_kernel`).

    Parameters
    ----------
    frames : ndarray (F, H, W)
        Camera frames of the identity ``code`` (m, n, K); S = F·K.
    code : ndarray (m, n, K)
        Identity code (a multiplexed one raises ValueError).
    flow : ndarray (S, H, W, 2)
        Velocity, pixels per sub-frame; NaN or infinity reads as still. Or a volume read a sub-frame at a time
        (:class:`~flexvox_core.planes.Bands`: ``shape`` and ``band``); a
        :class:`~flexvox_core.flow.estimate.ScaledFlow` is read at the voxels from its small planes (the same bits).
    guide : ndarray (S, H, W)
        Short-reach estimate the samples are compared with; the value wherever no sample is in reach
        and outside ``select``.
    select : ndarray (S, H, W) bool
        Voxels to estimate (or a :class:`~flexvox_core.planes.Bands` of them).
    plan : LongReachPlan
        Reach, σ_t, σ_s and h.
    missing : ndarray (F,) bool, optional
        Dropped frames: their sub-frames hold no samples.
    out : ndarray (S, H, W) float32, optional
        Where to write the result; may be ``guide`` itself.
    write_samples : bool
        Also write every sample at its voxel (the frames where captured).

    Returns
    -------
    ndarray (S, H, W) float32: the estimate in ``select``, ``guide`` elsewhere (and the samples, with
    ``write_samples``).
    """
    from flexvox_core import threads
    from flexvox_core.codes import order_from_code
    from flexvox_core.motion.longreach_kernel import corner_table, long_reach_kernel

    fr = np.ascontiguousarray(frames, np.float32)
    order = order_from_code(code)
    F, H, W = fr.shape
    S = F * order.size
    g = np.ascontiguousarray(guide, np.float32)
    # Arrays, or volumes made a sub-frame at a time (planes.band): the kernel reads one sub-frame's at a time.
    sel = select if hasattr(select, "band") else np.ascontiguousarray(select, bool)
    f = flow if hasattr(flow, "band") else np.ascontiguousarray(flow, np.float32)
    if g.shape != (S, H, W) or tuple(sel.shape) != g.shape or tuple(f.shape) != (S, H, W, 2):
        raise ValueError(f"`guide`, `select` (S, H, W) = {(S, H, W)} and `flow` (S, H, W, 2) must match the frames "
                         f"{fr.shape} of a K = {order.size} code; got {g.shape}, {tuple(sel.shape)}, "
                         f"{tuple(f.shape)}")
    present = np.ones(F, bool) if missing is None else ~np.asarray(missing, bool)
    if present.shape != (F,):
        raise ValueError(f"`missing` must be one flag per frame, shape ({F},); got {present.shape}")
    if out is None:
        out = g.copy()
    elif out is not guide:
        if out.shape != g.shape or out.dtype != np.float32 or not out.flags.c_contiguous:
            raise ValueError(f"`out` must be C-contiguous float32 of shape {g.shape}; got {out.dtype} {out.shape}")
        np.copyto(out, g)
    elif out is not g:
        raise ValueError("`out` may be `guide` only when `guide` is C-contiguous float32")
    chunks = max(1, min(S, threads.workers()))
    num = np.empty((chunks, H, W), np.float32)
    den = np.empty((chunks, H, W), np.float32)
    long_reach_kernel(fr, order, corner_table(order), present, f, g, sel, plan.time_weights,
                      np.float32(plan.range_scale), plan.taps, np.float32(MIN_WEIGHT), out, num, den,
                      bool(write_samples))
    return out


def long_reach_nc(sparse, mask, flow, guide, select, *, reach: int, sigma_t: float, sigma_s: float = 0.3,
                  h: float = 0.1, out: np.ndarray | None = None) -> np.ndarray:
    """Range-weighted trajectory gather over ±``reach`` sub-frames for the voxels in ``select``.

    Parameters
    ----------
    sparse, mask : ndarray (S, H, W)
        Sampled values (0 elsewhere) and where the samples are.
    flow : ndarray (S, H, W, 2)
        Velocity, pixels per sub-frame (straight trajectories).
    guide : ndarray (S, H, W)
        Short-reach estimate the samples are compared with; also the value wherever no sample
        is in reach and outside ``select``.
    select : ndarray (S, H, W) bool
        Voxels to estimate (the gather runs over each sub-frame's bounding box of them).
    reach : int
        Largest |d| in sub-frames.
    sigma_t, sigma_s : float
        Temporal (along the trajectory) and spatial standard deviations.
    h : float
        Range-weight scale, in the samples' units (> 0).
    out : ndarray (S, H, W) float32, optional
        Where to write the result; may be ``guide`` itself (each sub-frame's guide is read
        before that sub-frame is written).

    Returns
    -------
    ndarray (S, H, W) float32: the estimate in ``select``, ``guide`` elsewhere.
    """
    vals = np.asarray(sparse, np.float32)
    m = np.asarray(mask, bool)
    f = np.asarray(flow, np.float32)
    g_all = np.asarray(guide, np.float32)
    sel = np.asarray(select, bool)
    S, H, W = vals.shape
    if m.shape != vals.shape or g_all.shape != vals.shape or sel.shape != vals.shape or f.shape != (S, H, W, 2):
        raise ValueError(f"`sparse`, `mask`, `guide`, `select` (S, H, W) and `flow` (S, H, W, 2) must match; got "
                         f"{vals.shape}, {m.shape}, {g_all.shape}, {sel.shape}, {f.shape}")
    plan = LongReachPlan.of(S, reach=reach, sigma_t=sigma_t, sigma_s=sigma_s, h=h)
    if not np.isfinite(f.sum(dtype=np.float64)):  # one pass, no (S, H, W, 2) temporary
        f = np.where(np.isfinite(f), f, 0).astype(np.float32)
    reach, sigma_t, sigma_s, h = plan.reach, plan.sigma_t, plan.sigma_s, plan.h
    # Value·mask and mask as separate planes: two one-channel remaps cost a third of one
    # two-channel remap and interpolate exactly (OpenCV 5, measured at 640×480).
    value, weight = sample_planes(vals, m)  # unsampled voxels may hold anything, even NaN
    if out is None:
        out = g_all.copy()
    elif out is not g_all:
        if out.shape != vals.shape or out.dtype != np.float32:
            raise ValueError(f"`out` must be float32 of shape {vals.shape}; got {out.dtype} {out.shape}")
        np.copyto(out, g_all)
    radius = plan.radius
    kernel = np.ones((2 * radius + 1,) * 2, np.uint8)
    scale = -0.5 / (h * h)
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    def one(t):
        if not sel[t].any():
            return
        act = sel[t] if not radius else cv2.dilate(sel[t].view(np.uint8), kernel) > 0
        rows, cols = np.flatnonzero(act.any(axis=1)), np.flatnonzero(act.any(axis=0))
        y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        n_act = np.count_nonzero(act[y0:y1, x0:x1])
        if n_act > DENSE * (y1 - y0) * (x1 - x0):
            # Dense: the box as it is.
            box = (slice(y0, y1), slice(x0, x1))
            grids = [np.array(a, np.float32) for a in (gx[box], gy[box], f[t][box][..., 0], f[t][box][..., 1],
                                                       g_all[t][box], value[t][box], weight[t][box])]
            num, den = _gather_grid(t, value, weight, *grids, reach, sigma_t, scale)
            if radius:
                for plane in (num, den):  # neighbours outside the box are beyond the kernel's reach of `sel`
                    cv2.GaussianBlur(plane, (2 * radius + 1,) * 2, sigma_s, dst=plane, borderType=cv2.BORDER_CONSTANT)
            keep = sel[t][box] & (den > MIN_WEIGHT)
            out[t][box][keep] = num[keep] / den[keep]
            return
        # Sparse: only the selected voxels (and, for the blur, their neighbours), as a list, read
        # and written through flat indices (one index array, not two).
        ys, xs = np.nonzero(act[y0:y1, x0:x1])
        at = ys * (x1 - x0) + xs  # in the box
        ys += y0
        xs += x0
        flat = ys * W + xs  # in the sub-frame
        u, v = flow_at(f[t], flat)
        grids = [_as_grid(a) for a in (xs, ys, u, v, g_all[t].reshape(-1)[flat],
                                       value[t].reshape(-1)[flat], weight[t].reshape(-1)[flat])]
        num, den = (a.reshape(-1)[: len(ys)] for a in _gather_grid(t, value, weight, *grids, reach, sigma_t, scale))
        if radius:
            planes = np.zeros((2, (y1 - y0) * (x1 - x0)), np.float32)
            planes[0, at], planes[1, at] = num, den
            for plane in planes.reshape(2, y1 - y0, x1 - x0):  # outside `act` zero: beyond the kernel's reach of `sel`
                cv2.GaussianBlur(plane, (2 * radius + 1,) * 2, sigma_s, dst=plane, borderType=cv2.BORDER_CONSTANT)
            keep = sel[t].reshape(-1)[flat]
            flat, at = flat[keep], at[keep]
            num, den = planes[0, at], planes[1, at]
        ok = den > MIN_WEIGHT
        out[t].put(flat[ok], num[ok] / den[ok])  # flat indices into any layout

    for_each(one, S)
    return out


DENSE = 0.5
"""Selections filling more than this fraction of their bounding box are gathered as the box."""
LIST_WIDTH = 4096
"""Voxel lists are gathered as rows of this many (cv2.remap takes maps up to 32767 wide)."""


def _as_grid(a):
    """A 1-D list as a (rows, LIST_WIDTH) float32 image, padded with its last entry."""
    n = len(a)
    shape = (-(-n // LIST_WIDTH), min(n, LIST_WIDTH))
    grid = np.empty(shape[0] * shape[1], np.float32)
    grid[:n] = a
    grid[n:] = a[-1]
    return grid.reshape(shape)


def _gather_grid(t, value, weight, fwd_x, fwd_y, u, v, g, acc_num, acc_den, reach, sigma_t, scale):
    """Range-weighted sums (numerator, weight) along the trajectories of the voxels whose
    positions are ``fwd_x``, ``fwd_y`` at sub-frame ``t`` (any 2-D layout: a box or a list;
    ``acc_num``, ``acc_den`` hold their own sub-frame's samples and are overwritten)."""
    S = len(value)
    shape = fwd_x.shape
    back_x, back_y = fwd_x.copy(), fwd_y.copy()
    num, den, r = (np.empty(shape, np.float32) for _ in range(3))
    for d in range(0, reach + 1):
        if d:
            cv2.add(fwd_x, u, dst=fwd_x)
            cv2.add(fwd_y, v, dst=fwd_y)
            cv2.subtract(back_x, u, dst=back_x)
            cv2.subtract(back_y, v, dst=back_y)
        log_w = -d * d / (2 * sigma_t * sigma_t)  # the trajectory weight, folded into the exp
        for sd, mx, my in (((0, None, None),) if d == 0 else ((d, fwd_x, fwd_y), (-d, back_x, back_y))):
            if not 0 <= t + sd < S:
                continue
            if sd == 0:  # the sub-frame's own samples (the voxel's, and its neighbours' for the blur)
                num[...], den[...] = acc_num, acc_den
                acc_num[...], acc_den[...] = 0, 0
            else:
                cv2.remap(value[t + sd], mx, my, cv2.INTER_LINEAR, dst=num, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0)
                cv2.remap(weight[t + sd], mx, my, cv2.INTER_LINEAR, dst=den, borderMode=cv2.BORDER_CONSTANT,
                          borderValue=0)
            # At most one of the four pixels read holds a sample of this sub-frame: num / den is it.
            cv2.max(den, 1e-12, dst=r)  # no sample read: num = 0, and its weight den = 0 too
            cv2.divide(num, r, dst=r)
            cv2.subtract(r, g, dst=r)
            cv2.multiply(r, r, dst=r, scale=scale)
            cv2.add(r, log_w, dst=r)
            cv2.exp(r, dst=r)
            cv2.accumulateProduct(num, r, acc_num)
            cv2.accumulateProduct(den, r, acc_den)
    return acc_num, acc_den
