"""Re-binning's closed-form estimate in plain numpy over whole volumes: the reference that
:mod:`flexvox_core.accuracy_rebin_kernel`'s compiled passes are compared against (it was the estimate until they
replaced it: about 250 bytes a voxel)."""

from __future__ import annotations

import math

import numpy as np

from flexvox_core.accuracy_rebin import (
    CLUSTER,
    Increments,
    RebinError,
    _blocks,
    _lags,
    _slots,
    fit_variogram,
    stencil,
    variogram,
)
from flexvox_core.divisions import Division


def _cluster_se(err: np.ndarray, cluster: np.ndarray) -> float:
    """The standard error of the mean of ``err`` (F', S', H, W) from the spread of its clusters' means (per
    camera frame and cluster of pixels)."""
    cells = []
    for e in err:
        m = e.mean(axis=0).ravel()
        cells.append(np.bincount(cluster, m) / np.maximum(np.bincount(cluster), 1))
    means = np.concatenate(cells)
    return float(np.std(means, ddof=1) / math.sqrt(means.size)) if means.size > 1 else 0.0


def increments_reference(frames: np.ndarray, code: np.ndarray, variance: np.ndarray, half: tuple[int, int, int],
                         dropped: np.ndarray | None = None) -> Increments:
    """:func:`~flexvox_core.accuracy_rebin.increments` in numpy, a frame pair and a lag at a time: the mean of
    ``(y_a − y_b)² − σ_a² − σ_b²`` over every pair of captured samples at each lag in the box
    ``|dt| ≤ T, |dy| ≤ Y, |dx| ≤ X`` (``half``), symmetric in the lag."""
    F, H, W = frames.shape
    K = code.shape[2]
    T, Y, X = half
    t = _slots(code, F, H, W)
    y = frames.astype(np.float64)
    var = variance.astype(np.float64)
    ok = np.ones(F, bool) if dropped is None else ~np.asarray(dropped, bool)
    total = np.zeros((2 * T + 1, 2 * Y + 1, 2 * X + 1))
    count = np.zeros_like(total)
    reach = T // K + 1
    for dy in range(-Y, Y + 1):
        for dx in range(-X, X + 1):
            a = (slice(max(0, -dy), H - max(0, dy)), slice(max(0, -dx), W - max(0, dx)))
            b = (slice(max(0, dy), H - max(0, -dy)), slice(max(0, dx), W - max(0, -dx)))
            for f in np.nonzero(ok)[0]:
                for g in range(max(0, f - reach), min(F, f + reach + 1)):
                    if not ok[g]:
                        continue
                    dt = (t[g][b] - t[f][a]).ravel()
                    inside = np.abs(dt) <= T
                    if not inside.any():
                        continue
                    d2 = ((y[g][b] - y[f][a]) ** 2 - var[g][b] - var[f][a]).ravel()
                    idx = dt[inside] + T
                    total[:, dy + Y, dx + X] += np.bincount(idx, d2[inside], minlength=2 * T + 1)
                    count[:, dy + Y, dx + X] += np.bincount(idx, minlength=2 * T + 1)
    mean = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    return Increments(mean, count)


def rebin_error_reference(frames: np.ndarray, code: np.ndarray, division: Division, variance: np.ndarray, *,
                interpolate: bool = True, dropped: np.ndarray | None = None, z: float = 1.96,
                table: np.ndarray | None = None) -> RebinError:
    """:func:`~flexvox_core.accuracy_rebin.rebin_error` over whole volumes (every corner's blocks, weights and lags for
    every voxel, float64): the clip's MSE of re-binning at ``division`` (interpolated, or each block filled by its
    sample), from the capture ``frames`` (F, H, W), its identity ``code`` and its samples' noise ``variance``
    (F, H, W) alone (the module's steps 1 to 4); ``dropped`` (F,) frames are left out of the clip's mean; ``z`` sets
    the interval.
    ``table`` (2·2c + 1, 2·2a + 1, 2·2b + 1), when given, is ``D`` at every lag of the box ``|dt| ≤ 2c, |dy| ≤ 2a,
    |dx| ≤ 2b`` in place of the capture's increments and the fit (a reference: the identity is then exact).

    Raises
    ------
    TooFewLags
        Too few lags the interpolation uses are spanned by pairs of samples to fit the increments.
    """
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    half = (2 * division.c, 2 * division.a, 2 * division.b)
    T, Y, X = half
    keep = np.ones(F, bool) if dropped is None else ~np.asarray(dropped, bool)
    inc = increments_reference(frames, code, variance, half, ~keep)
    yb = _blocks(frames, code, division).ravel()
    vb = _blocks(variance, code, division).ravel()
    rows = np.broadcast_to(np.arange(H)[None, :, None], (F, H, W))
    cols = np.broadcast_to(np.arange(W)[None, None, :], (F, H, W))
    pos = [_blocks(a, code, division).ravel().astype(np.intp) for a in (_slots(code, F, H, W), rows, cols)]
    nt, nh, nw = F * (K // division.c), -(-H // division.a), -(-W // division.b)
    st = stencil((S, H, W), division, (nt, nh, nw), interpolate=interpolate)
    tt, yy, xx = np.mgrid[0:S, 0:H, 0:W]
    kept = np.repeat(keep, K)
    lags = []
    mass = np.zeros((2 * T + 1) * (2 * Y + 1) * (2 * X + 1))
    base = np.zeros((S, H, W))  # noise less the pairs' increments, per voxel
    for c, (b, w) in enumerate(zip(st.block, st.weight, strict=True)):
        lag = ((np.clip(tt - pos[0][b], -T, T) + T) * (2 * Y + 1) + np.clip(yy - pos[1][b], -Y, Y) + Y) * (
            2 * X + 1) + np.clip(xx - pos[2][b], -X, X) + X
        lags.append(lag)
        mass += np.bincount(lag[kept].ravel(), w[kept].ravel(), minlength=mass.size)
        base += w * w * vb[b]
        for c2 in range(c + 1, len(st.block)):  # the pair's increment per cell of the grid, read per voxel
            j, k = st.corner[c], st.corner[c2]
            base -= w * st.weight[c2] * ((yb[j] - yb[k]) ** 2 - vb[j] - vb[k])[st.cell]
    mass = mass.reshape(inc.mean.shape) / max(int(kept.sum()) * H * W, 1)
    if table is None:
        G, beta, misfit = fit_variogram(inc, mass)
        spanned = inc.spanned
        model = variogram(G, beta, _lags(half)).reshape(inc.mean.shape)
    else:
        beta, misfit, spanned, model = math.nan, 0.0, np.zeros(inc.mean.shape, bool), np.asarray(table, np.float64)
    est = np.where(spanned, inc.mean, model).ravel()
    unsp = np.where(spanned, 0.0, model).ravel()
    err = base.copy()
    for c, lag in enumerate(lags):
        err += st.weight[c] * est[lag]
    per_frame = np.full(F, np.nan)
    blocks = err.reshape(F, K, H, W)
    for f in np.nonzero(keep)[0]:
        per_frame[f] = float(np.mean(blocks[f]))
    mse = float(np.mean(blocks[keep]))
    moved = float(np.sum(mass.ravel() * unsp))  # the unspanned lags' share of the error
    cluster = ((yy[0] // CLUSTER) * (W // CLUSTER + 1) + xx[0] // CLUSTER).ravel()
    se = _cluster_se(blocks[keep], cluster)
    total = float(np.sum(mass.ravel() * est))
    return RebinError(mse=mse, low=mse - z * (misfit * moved + se), high=mse + z * (misfit * moved + se),
                      per_frame=per_frame, samples=int(keep.sum()) * H * W, beta=beta, misfit=misfit,
                      unspanned=moved / max(total, 1e-30))
