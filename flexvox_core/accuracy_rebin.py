"""The accuracy estimate of re-binning, in closed form (no run).

The estimate's internals: they are reached through :func:`~flexvox_core.accuracy.estimate_accuracy` (and
``estimate_recording``), which checks the frames (integer counts read as relative units, a wrong shape refused),
the code, the method, the noise and the missing frames before them, and they take float arrays as it passes them.

Interpolated re-binning (:func:`~flexvox_core.reconstruct.rebin.rebin` with ``interpolate=True``) is a known
linear interpolator: each block's one sample is placed at the block's centre and every voxel ``u`` is the
trilinear mix ``v_u = Σ_j w_j(u)·y_j`` of the (up to 8) surrounding blocks' samples, ``Σ_j w_j(u) = 1``. The
weights follow from the code and the division alone (:func:`stencil`), so the estimate needs no extra
reconstruction:

1. **The error, exactly, in terms of the truth's increments.** With ``y_j = x_j + n_j`` (noise of variance
   ``σ_j²``, independent) and weights summing to one, the error at ``u`` expands (the kriging identity) into

   ``E(v_u − x_u)² = Σ_j w_j·D(u, j) − ½·Σ_j Σ_k w_j·w_k·D(j, k) + Σ_j w_j²·σ_j²``,

   ``D(a, b) = E(x_a − x_b)²``, the truth's squared increment between two voxels.
2. **Between two samples** ``D(j, k)`` is read off the capture, per pair: ``(y_j − y_k)² − σ_j² − σ_k²``.
3. **Between a voxel and a sample** ``D(u, j)`` is the clip's mean increment at their space-time lag
   ``h = u − j`` (the clip's MSE is a mean over every voxel, so a mean increment per lag is what it needs; the
   stencil repeats with the code's tile, so each lag is drawn from the whole frame). Lags that some pair of
   samples spans are read off those pairs (:func:`increments`). Others are not spanned by any pair: a tile
   holds each slot once, so no two samples share a pixel within K sub-frames or a sub-frame within a tile —
   the lags ``(dt, 0, 0)`` and ``(0, dy, dx)`` that every voxel has to its block's samples. For those:

   the anisotropic power variogram ``D(h) = (hᵀ·G·h)^(β/2)`` (``G`` a space-time structure tensor, ``β`` in
   (0, 2]: 2 for a smooth field, about 1 with edges) fitted to the spanned lags the interpolation uses, each
   weighted by its share of the weights (:func:`fit_variogram`): a moving edge gives increments that grow along
   its motion, which ``G`` holds. About two thirds of the weights fall on unspanned lags.
4. **Interval**: the unspanned lags' increments moved by ``± z`` times the fit's relative misfit on the spanned
   ones (as if its error there were the same, and of one sign everywhere), and by ``z`` standard errors of the
   clip's error over clusters of pixels (per camera frame).

Re-binning without interpolation (each block filled by its sample) has the one-block stencil and the same
expansion; its voxels reach their sample only at lags inside a block, which few pairs span (:data:`NEAREST`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flexvox_core.divisions import Division
from flexvox_core.forward import tiled_order

CLUSTER = 16
"""Pixels per side of a cluster (the interval's spread is over clusters, per camera frame)."""
MIN_PAIRS = 16
"""Sample pairs a lag needs to be read off the capture; a lag with fewer is taken as not spanned."""


@dataclass(frozen=True)
class Increments:
    """The truth's mean squared increment per space-time lag, read off a capture's sample pairs.

    ``mean[dt + T, dy + Y, dx + X]`` holds ``D`` at lag ``(dt, dy, dx)`` (``count`` its pairs, 0 where no pair
    spans it; ``T, Y, X`` the box's half-sides).
    """

    mean: np.ndarray
    count: np.ndarray

    @property
    def half(self) -> tuple[int, int, int]:
        """The box's half-sides ``(T, Y, X)``."""
        t, y, x = self.mean.shape
        return t // 2, y // 2, x // 2

    @property
    def spanned(self) -> np.ndarray:
        """Lags read off at least :data:`MIN_PAIRS` pairs (the zero lag counts as spanned: ``D = 0``)."""
        ok: np.ndarray = self.count >= MIN_PAIRS
        T, Y, X = self.half
        ok[T, Y, X] = True
        return ok


class TooFewLags(ValueError):
    """Too few lags the interpolation uses are spanned by pairs of samples to fit the increments."""


def _slots(code: np.ndarray, F: int, H: int, W: int) -> np.ndarray:
    """The sub-frame of every sample (F, H, W)."""
    K = code.shape[2]
    out: np.ndarray = np.arange(F)[:, None, None] * K + tiled_order(code, H, W)[None]
    return out


def increments(frames: np.ndarray, code: np.ndarray, variance: np.ndarray, half: tuple[int, int, int],
               dropped: np.ndarray | None = None) -> Increments:
    """The mean of ``(y_a − y_b)² − σ_a² − σ_b²`` over every pair of captured samples at each lag in the box
    ``|dt| ≤ T, |dy| ≤ Y, |dx| ≤ X`` (``half``), symmetric in the lag (compiled,
    :func:`~flexvox_core.accuracy_rebin_kernel.pair_increments`, a row lag per item on the threads)."""
    from flexvox_core.accuracy_rebin_kernel import pair_increments
    from flexvox_core.threads import for_each

    F, H, W = frames.shape
    K = code.shape[2]
    T, Y, X = half
    slots = np.ascontiguousarray(_slots(code, F, H, W), np.int64)
    y = np.ascontiguousarray(frames, np.float64)
    var = np.ascontiguousarray(variance, np.float64)
    ok = np.ones(F, bool) if dropped is None else ~np.asarray(dropped, bool)
    total = np.zeros((2 * T + 1, 2 * Y + 1, 2 * X + 1))
    count = np.zeros_like(total)
    for_each(lambda i: pair_increments(i - Y, slots, y, var, ok, half, T // K + 1, total, count), 2 * Y + 1)
    mean = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    return Increments(mean, count)


def _lags(half: tuple[int, int, int]) -> np.ndarray:
    """Every lag of the box, (n, 3), in ``mean``'s order."""
    T, Y, X = half
    grid = np.mgrid[-T:T + 1, -Y:Y + 1, -X:X + 1]
    out: np.ndarray = grid.reshape(3, -1).T.astype(np.float64)
    return out


def fit_variogram(inc: Increments, mass: np.ndarray) -> tuple[np.ndarray, float, float]:
    """``(G, β, misfit)``: ``D(h) = (hᵀ·G·h)^(β/2)`` fitted to the spanned lags that the stencil uses, each
    weighted by its weight ``mass`` (``Σ_u Σ_j w_j(u)`` over the voxel-sample pairs at that lag, its mirror
    added), the errors relative (``2·(model − D)/(model + D)``, bounded where ``D`` is near 0); ``G`` (3, 3)
    positive semi-definite in (dt, dy, dx). ``misfit``: the mass-weighted root mean square of those relative errors.

    Raises
    ------
    TooFewLags
        Fewer than 8 such lags.
    """
    from scipy.optimize import least_squares

    h = _lags(inc.half)
    d = inc.mean.ravel()
    n = inc.count.ravel()
    m = (mass + mass[::-1, ::-1, ::-1]).ravel()
    use = (n >= MIN_PAIRS) & (np.abs(h).sum(axis=1) > 0) & (d > 0) & (m > 0)
    if use.sum() < 8:
        raise TooFewLags(f"only {int(use.sum())} lags the interpolation uses are spanned by {MIN_PAIRS} or more "
                         "sample pairs; at least 8 are needed to fit the increments")
    h, d, m = h[use], d[use], m[use]
    weight = np.sqrt(m / m.sum())

    def model(p: np.ndarray) -> np.ndarray:
        L = np.array([[p[0], 0, 0], [p[1], p[2], 0], [p[3], p[4], p[5]]])
        q = np.sum((h @ L) ** 2, axis=1)
        out: np.ndarray = np.maximum(q, 1e-30) ** (p[6] / 2)
        return out

    def resid(p: np.ndarray) -> np.ndarray:
        mp = model(p)
        r: np.ndarray = weight * 2.0 * (mp - d) / (mp + d)
        return r

    # starts: an isotropic G of the mean increment per unit lag, at β = ½, 1 and 2; the best fit is kept
    r = np.sqrt(np.sum(h**2, axis=1))
    fits = []
    for b0 in (0.5, 1.0, 2.0):
        g0 = float(np.mean(d ** (1 / b0) / r))
        fits.append(least_squares(resid, np.array([g0, 0, g0, 0, 0, g0, b0]),
                                  bounds=([-np.inf] * 6 + [0.05], [np.inf] * 6 + [2.0])))
    fit = min(fits, key=lambda f: float(f.cost))
    p = fit.x
    L = np.array([[p[0], 0, 0], [p[1], p[2], 0], [p[3], p[4], p[5]]])
    return L @ L.T, float(p[6]), float(np.sqrt(np.sum(resid(p) ** 2)))


def variogram(G: np.ndarray, beta: float, h: np.ndarray) -> np.ndarray:
    """``(hᵀ·G·h)^(β/2)`` at lags ``h`` (..., 3)."""
    q = np.einsum("...i,ij,...j->...", h, G, h)
    out: np.ndarray = np.maximum(q, 0.0) ** (beta / 2)
    return out


@dataclass(frozen=True)
class Stencil:
    """Interpolated re-binning's weights: for each of the 8 corners, the block each voxel reads and its weight.

    ``block[c]`` (S, H, W) int: flat index into the blocks ``(F·TR, Hb, Wb)``; ``weight[c]`` (S, H, W). ``cell``
    (S, H, W): each voxel's cell of the block grid (its lower corner's block), and ``corner[c]`` (blocks,): the
    block corner ``c`` of each cell reads, so that ``block[c] == corner[c][cell]``."""

    block: list[np.ndarray]
    weight: list[np.ndarray]
    cell: np.ndarray
    corner: list[np.ndarray]


def _axis(n_out: int, size: int, nb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(i0, i1, w1)`` of linear interpolation from ``nb`` block centres of ``size`` to ``n_out`` points (as
    :func:`~flexvox_core.reconstruct.rebin.rebin`)."""
    pos = np.clip((np.arange(n_out) - (size - 1) / 2.0) / size, 0.0, nb - 1)
    i0 = np.floor(pos).astype(np.intp)
    return i0, np.minimum(i0 + 1, nb - 1), pos - i0


def stencil(shape: tuple[int, int, int], division: Division, blocks: tuple[int, int, int], *,
            interpolate: bool = True) -> Stencil:
    """The weights of re-binning a video ``shape`` (S, H, W) from ``blocks`` (F·TR, Hb, Wb): with ``interpolate``
    the 8 corners of the trilinear interpolation between block centres, else the one block that holds the voxel
    (weight 1)."""
    S, H, W = shape
    nt, nh, nw = blocks
    if not interpolate:
        flat = ((np.arange(S) // division.c)[:, None, None] * nh + (np.arange(H) // division.a)[None, :, None]) * nw
        flat = flat + (np.arange(W) // division.b)[None, None, :]
        return Stencil([flat], [np.ones((S, H, W))], flat, [np.arange(nt * nh * nw)])
    axes = [_axis(S, division.c, nt), _axis(H, division.a, nh), _axis(W, division.b, nw)]
    out_b, out_w, corner = [], [], []
    gt, gy, gx = np.arange(nt)[:, None, None], np.arange(nh)[None, :, None], np.arange(nw)[None, None, :]
    for ct in (0, 1):
        for cy in (0, 1):
            for cx in (0, 1):
                idx = []
                wts = []
                for (i0, i1, w1), c in zip(axes, (ct, cy, cx), strict=True):
                    idx.append(i1 if c else i0)
                    wts.append(w1 if c else 1.0 - w1)
                flat = (idx[0][:, None, None] * nh + idx[1][None, :, None]) * nw + idx[2][None, None, :]
                out_b.append(flat)
                out_w.append(wts[0][:, None, None] * wts[1][None, :, None] * wts[2][None, None, :])
                corner.append(((np.minimum(gt + ct, nt - 1) * nh + np.minimum(gy + cy, nh - 1)) * nw
                               + np.minimum(gx + cx, nw - 1)).ravel())
    cell = (axes[0][0][:, None, None] * nh + axes[1][0][None, :, None]) * nw + axes[2][0][None, None, :]
    return Stencil(out_b, out_w, cell, corner)


def _blocks(values: np.ndarray, code: np.ndarray, division: Division) -> np.ndarray:
    """Per-pixel ``values`` (F, H, W) placed in re-binning's blocks (its border fill included), float64."""
    from flexvox_core.reconstruct.rebin import rebin_blocks

    out: np.ndarray = rebin_blocks(values.astype(np.float64), code, division, dtype=np.float64)
    return out


@dataclass(frozen=True)
class RebinError:
    """The clip's estimated mean squared error of interpolated re-binning (see the module).

    Attributes
    ----------
    mse : float
        The estimate.
    low, high : float
        The MSE with the unspanned lags' increments moved by ``∓ z·misfit`` (relative), and the clusters' spread.
    per_frame : ndarray (F,)
        The estimate per camera frame (NaN for a dropped one).
    samples : int
        Samples the pair terms rest on.
    beta, misfit, unspanned : float
        The fitted variogram's exponent, its relative misfit on the spanned lags, and the share of
        ``Σ w·D(u, j)`` that falls on unspanned lags.
    """

    mse: float
    low: float
    high: float
    per_frame: np.ndarray
    samples: int
    beta: float
    misfit: float
    unspanned: float


def _cluster_means(err: np.ndarray, cluster: np.ndarray) -> np.ndarray:
    """The means of one camera frame's ``err`` (S', H, W) over its sub-frames, then over each cluster of pixels."""
    m = err.mean(axis=0).ravel()
    out: np.ndarray = np.bincount(cluster, m) / np.maximum(np.bincount(cluster), 1)
    return out


def _spread(cells: list[np.ndarray]) -> float:
    """The standard error of the clip's mean from the spread of its clusters' means (per camera frame and cluster
    of pixels: :func:`_cluster_means`)."""
    means = np.concatenate(cells) if cells else np.zeros(0)
    return float(np.std(means, ddof=1) / math.sqrt(means.size)) if means.size > 1 else 0.0


def rebin_error(frames: np.ndarray, code: np.ndarray, division: Division, variance: np.ndarray, *,
                interpolate: bool = True, dropped: np.ndarray | None = None, z: float = 1.96,
                table: np.ndarray | None = None) -> RebinError:
    """The clip's MSE of re-binning at ``division`` (interpolated, or each block filled by its sample), from the
    capture ``frames`` (F, H, W), its identity ``code`` and its samples' noise ``variance`` (F, H, W) alone (the
    module's steps 1 to 4); ``dropped`` (F,) frames are left out of the clip's mean; ``z`` sets the interval.
    ``table`` (2·2c + 1, 2·2a + 1, 2·2b + 1), when given, is ``D`` at every lag of the box ``|dt| ≤ 2c, |dy| ≤ 2a,
    |dx| ≤ 2b`` in place of the capture's increments and the fit (a reference: the identity is then exact).

    Each voxel's terms are made a voxel at a time by :mod:`~flexvox_core.accuracy_rebin_kernel` (compiled), one camera
    frame's sub-frames held at a time: the memory is the blocks' and one frame's (about 40 MB at 640×480, K = 16),
    whatever the clip's length.

    Raises
    ------
    TooFewLags
        Too few lags the interpolation uses are spanned by pairs of samples to fit the increments.
    """
    from flexvox_core.accuracy_rebin_kernel import frame_error, lag_mass
    from flexvox_core.threads import for_each, workers

    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    half = (2 * division.c, 2 * division.a, 2 * division.b)
    T, Y, X = half
    keep = np.ones(F, bool) if dropped is None else ~np.asarray(dropped, bool)
    inc = increments(frames, code, variance, half, ~keep)
    yb = _blocks(frames, code, division).ravel()
    vb = _blocks(variance, code, division).ravel()
    rows = np.broadcast_to(np.arange(H)[None, :, None], (F, H, W))
    cols = np.broadcast_to(np.arange(W)[None, None, :], (F, H, W))
    # each block's sample: its sub-frame, row and column
    pos_t, pos_y, pos_x = (_blocks(a, code, division).ravel().astype(np.int64)
                           for a in (_slots(code, F, H, W), rows, cols))
    blocks = (F * (K // division.c), -(-H // division.a), -(-W // division.b))
    axes = _axes((S, H, W), division, blocks, interpolate=interpolate)
    corners = 8 if interpolate else 1
    kept = np.repeat(keep, K)
    box = (2 * T + 1) * (2 * Y + 1) * (2 * X + 1)
    per_corner = np.zeros((corners, box))
    for_each(lambda c: lag_mass(c, (S, H, W), axes, blocks, pos_t, pos_y, pos_x, half, kept, per_corner[c]), corners)
    mass = np.zeros(box)
    for m in per_corner:  # the corners' sums added in their order
        mass += m
    mass = mass.reshape(inc.mean.shape) / max(int(kept.sum()) * H * W, 1)
    if table is None:
        G, beta, misfit = fit_variogram(inc, mass)
        spanned = inc.spanned
        model = variogram(G, beta, _lags(half)).reshape(inc.mean.shape)
    else:
        beta, misfit, spanned, model = math.nan, 0.0, np.zeros(inc.mean.shape, bool), np.asarray(table, np.float64)
    est = np.where(spanned, inc.mean, model).ravel()
    unsp = np.where(spanned, 0.0, model).ravel()
    per_frame = np.full(F, np.nan)
    cluster = ((np.arange(H)[:, None] // CLUSTER) * (W // CLUSTER + 1) + np.arange(W)[None, :] // CLUSTER).ravel()
    frames_kept = [int(f) for f in np.nonzero(keep)[0]]
    sums = np.zeros(len(frames_kept))
    cells: list[np.ndarray] = [np.zeros(0)] * len(frames_kept)
    n = min(workers(), len(frames_kept))

    def share(w: int) -> None:  # every n-th kept frame, into this worker's own frame of errors
        err = np.empty((K, H, W))
        for i in range(w, len(frames_kept), n):
            f = frames_kept[i]
            frame_error(f * K, (S, H, W), axes, corners, blocks, pos_t, pos_y, pos_x, half, yb, vb, est, err)
            per_frame[f] = float(np.mean(err))
            sums[i] = float(np.sum(err))
            cells[i] = _cluster_means(err, cluster)

    for_each(share, n)
    mse = float(np.sum(sums) / max(len(frames_kept) * K * H * W, 1))
    moved = float(np.sum(mass.ravel() * unsp))  # the unspanned lags' share of the error
    se = _spread(cells)
    total = float(np.sum(mass.ravel() * est))
    return RebinError(mse=mse, low=mse - z * (misfit * moved + se), high=mse + z * (misfit * moved + se),
                      per_frame=per_frame, samples=int(keep.sum()) * H * W, beta=beta, misfit=misfit,
                      unspanned=moved / max(total, 1e-30))


def _axes(shape: tuple[int, int, int], division: Division, blocks: tuple[int, int, int], *,
          interpolate: bool) -> tuple[np.ndarray, ...]:
    """:func:`stencil`'s axis tables for the kernels: ``(i0, i1, w1)`` of time, rows and columns (int64, int64,
    float64); without interpolation each voxel's block on both corners, ``w1`` 0."""
    out: list[np.ndarray] = []
    for n_out, size, nb in zip(shape, (division.c, division.a, division.b), blocks, strict=True):
        if interpolate:
            i0, i1, w1 = _axis(n_out, size, nb)
        else:
            i0 = i1 = np.arange(n_out) // size
            w1 = np.zeros(n_out)
        out += [np.ascontiguousarray(i0, np.int64), np.ascontiguousarray(i1, np.int64),
                np.ascontiguousarray(w1, np.float64)]
    return tuple(out)


NEAREST = ("re-binning without interpolation (each block's sample fills its block) is estimated by the same closed "
           "form, but it lies 0.24 to 1.29 dB above the truth (8 of 12 runs within 1 dB; interval covers 1 of 12; "
           "bench/bench_accuracy.py): its voxels reach their block's sample only at the lags within a block, which "
           "few pairs of samples span, so the fitted increments rest on few lags and the interval on their "
           "near-exact fit; estimate it with interpolate=True")
"""Why re-binning without interpolation is refused (the figures: ``bench/bench_accuracy.py``)."""
DROPPED = ("re-binning's closed-form estimate has not been checked on captures with dropped frames (the runner fills "
           "them from their neighbours before re-binning, so their blocks hold no samples); unchecked=True estimates "
           "it by the probe")
"""Why re-binning is refused on a capture with dropped frames."""


OTHER_DIVISIONS = ("re-binning's estimate met the acceptance at the code's default division (2x2x4 at a 4x4 tile, "
                   "2x2x2 at 2x4: 12 of 12 runs within 1 dB) but not at the others: -1.83 to +1.23 dB off the truth, "
                   "49 of 68 runs within 1 dB, interval covering 51 (bench/bench_accuracy.py); unchecked=True "
                   "estimates it all the same")
"""Why re-binning at a division other than the code's default is refused."""


def refusal(interpolate: bool) -> str | None:
    """Why re-binning with these options cannot be estimated, or None."""
    return None if interpolate else NEAREST
