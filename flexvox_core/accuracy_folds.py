"""The accuracy estimate of a method whose sub-frames are reconstructed apart (GAP-TV on an identity code).

The estimate's internals, reached through :func:`~flexvox_core.accuracy.estimate_accuracy`, which checks its
inputs first; :func:`spacing_ratio` is measured by ``bench/bench_accuracy.py`` and not used by the estimate.

When the probe (:mod:`flexvox_core.accuracy`) finds that a sample's temporal neighbours do not respond to it,
each sub-frame is reconstructed from its own samples alone, and the leave-one-out needs no linearisation:

1. **Every sample, held out exactly.** The voxels ``(t0 ± 1, p)`` beside sample ``i`` at ``(t0, p)`` were
   reconstructed without it, and ``p`` is not sampled in their sub-frames, so they are two ordinary unsampled
   voxels. ``L_i = (½(v(t0−1, p) + v(t0+1, p)) − y_i)² − σ²`` is read at every pixel, so every position in the
   code's tile counts (a probe lattice whose step is the tile's would see only the positions it lands on).
   With ``e±`` the two voxels' errors and ``x`` the truth, ``E[L] = M·(1 + ρ)/2 + E[(½(x₋ + x₊) − x₀)²]``
   (``M`` the unsampled voxels' mean squared error, ``ρ`` the two errors' correlation; the noise is taken out
   and independent of both). The estimate takes ``ρ = 1`` and the truth's curvature over two sub-frames as
   negligible: ``M ≈ L``; the two neglected terms push opposite ways.
2. **The sampled voxel** keeps its sample under the projection: its error is Stein's unbiased risk estimate
   ``(v_i − y_i)² − σ² + 2·A·σ²`` (``A`` its response to its sample, the probe's mean).
3. **The clip**: one voxel in K holds a sample, so ``MSE = ((K − 1)·L + SURE)/K``.
4. **The pessimistic end, by k-fold hold-out** (:data:`FOLDS` reconstructions, where the method can run with
   a masked code, :func:`masked_run`): each fold, the samples of one tile in 2×2 (by tile-row and tile-column
   parity), is taken out of the code and predicted at its own voxel. A held-out voxel lies on its
   sub-frame's sample lattice, the farthest any voxel lies from the kept samples (their nearest, one tile
   away in rows, columns and diagonals, are all kept by this split), so its error ``H`` bounds ``M`` from above.
   The sparser neighbourhood a fold leaves (a quarter of the lattice, two tiles and more away) raises ``H``
   by a second-order amount: holding out half instead of a quarter changed it by 2 % on balls and fan, so
   ``H`` is used as it is (a bound made slightly wider). Without a masked run the bound is ``2·L``
   (``ρ ≥ 0``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from flexvox_core.forward import tiled_code

if TYPE_CHECKING:
    from flexvox_core.methods import Method

FOLDS = 4
"""Folds of the k-fold hold-out: the tiles by (row parity, column parity)."""
BLOCK = 16
"""Pixels per side of a cluster of held-out samples (the interval's spread is over these, per frame)."""


def masked_run(method: Method) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None:
    """``run(frames, code, keep)``: ``method``'s reconstruction with the samples of pixels where ``keep`` (H, W) is
    False taken out of the code (their rows of the capture zeroed too, so nothing of them is read), or None when
    the method cannot run so. GAP-TV can: it is :func:`~flexvox_core.reconstruct.gaptv.gap_tv_masks` one camera
    frame at a time, which takes any per-pixel mask."""
    if method.name != "gap-tv":
        return None
    from flexvox_core.methods.spec import keywords
    from flexvox_core.reconstruct.gaptv import gap_tv_masks

    kw = keywords(method.options)

    def run(frames: np.ndarray, code: np.ndarray, keep: np.ndarray) -> np.ndarray:
        _, H, W = frames.shape
        masks = tiled_code(code, H, W).astype(np.float32) * keep
        return np.concatenate([gap_tv_masks(np.where(keep, frames[f], 0).astype(np.float32)[None], masks, **kw)
                               for f in range(frames.shape[0])])

    return run


def folds(code: np.ndarray, H: int, W: int) -> list[np.ndarray]:
    """The held-out pixels (H, W) bool of each fold: the tiles by (row parity, column parity)."""
    m, n = code.shape[:2]
    ti, tj = np.mgrid[0:H, 0:W]
    which = ((ti // m) % 2) * 2 + (tj // n) % 2
    return [which == j for j in range(FOLDS)]


def held_out_error(frames: np.ndarray, code: np.ndarray, run: Callable[[np.ndarray, np.ndarray, np.ndarray],
                   np.ndarray], dropped: np.ndarray, variance: np.ndarray,
                   between: Callable[[], None] | None = None) -> float:
    """``H``: the mean squared error of every captured sample predicted by the fold that held it out (its noise
    variance, ``variance`` (F, H, W), taken out). ``between`` is called after each fold's run (an exception it
    raises stops there)."""
    F, H, W = frames.shape
    K = code.shape[2]
    slot = np.argmax(tiled_code(code, H, W), axis=0)
    yy, xx = np.mgrid[0:H, 0:W]
    total = count = 0.0
    for fold in folds(code, H, W):
        v = run(frames, code, ~fold)
        if between is not None:
            between()
        for f in np.nonzero(~dropped)[0]:
            y = frames[f].astype(np.float64)
            err = (v[f * K + slot, yy, xx].astype(np.float64) - y) ** 2 - variance[f]
            total += float(np.sum(err[fold]))
            count += int(fold.sum())
    return total / max(count, 1.0)


def independent_rows(v0: np.ndarray, frames: np.ndarray, code: np.ndarray, dropped: np.ndarray,
                     variance: np.ndarray, a_self: float) -> np.ndarray:
    """Rows (frame, cluster, MSE of the pixel's K voxels) of every sample whose two temporal neighbours lie in the
    clip and in captured frames: ``((K − 1)·L + SURE)/K`` (the module's steps 1 to 3)."""
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    slot = np.argmax(tiled_code(code, H, W), axis=0)
    yy, xx = np.mgrid[0:H, 0:W]
    cluster = (yy // BLOCK) * (W // BLOCK + 1) + xx // BLOCK
    rows = []
    for f in np.nonzero(~dropped)[0]:
        t0 = f * K + slot
        ok = (t0 >= 1) & (t0 + 1 < S)
        ok &= ~dropped[np.clip(t0 - 1, 0, S - 1) // K] & ~dropped[np.clip(t0 + 1, 0, S - 1) // K]
        y = frames[f].astype(np.float64)
        before = v0[np.clip(t0 - 1, 0, S - 1), yy, xx].astype(np.float64)
        after = v0[np.clip(t0 + 1, 0, S - 1), yy, xx].astype(np.float64)
        loo = (0.5 * (before + after) - y) ** 2 - variance[f]
        sure = (v0[t0, yy, xx].astype(np.float64) - y) ** 2 - variance[f] + 2.0 * a_self * variance[f]
        mse = ((K - 1) * loo + sure) / K
        rows.append(np.stack([np.full(int(ok.sum()), f, np.float64), cluster[ok], mse[ok], loo[ok]], axis=1))
    return np.concatenate(rows, axis=0) if rows else np.zeros((0, 4))


def spacing_ratio(frames: np.ndarray, code: np.ndarray, variance: np.ndarray,
                  dropped: np.ndarray | None = None) -> float:
    """The unsampled voxels' mean squared increment of the truth to their sub-frame's nearest sample, over a
    held-out voxel's to its nearest kept one (:func:`folds`), from the power variogram fitted to the capture's
    sample pairs within two sub-frames and two tiles (:func:`~flexvox_core.accuracy_rebin.fit_variogram`).

    A candidate correction of the k-fold hold-out's error ``H`` to the unsampled voxels' (``H·ratio``), scaling the
    error by the truth's increment over the distance to the nearest sample; measured against the truth
    (``bench/bench_accuracy.py --methods gap-tv``) it runs up to 2.78 dB high on Drop, so the estimate does not use
    it.

    Raises
    ------
    flexvox_core.accuracy_rebin.TooFewLags
        Too few lags spanned by pairs of samples to fit the variogram.
    """
    from flexvox_core.accuracy_rebin import fit_variogram, increments, variogram

    m, n, _ = code.shape
    inc = increments(frames.astype(np.float64), code, variance, (2, 2 * m, 2 * n), dropped)
    G, beta, _ = fit_variogram(inc, np.ones(inc.mean.shape))
    lattice = [(a * m, b * n) for a in (-1, 0, 1) for b in (-1, 0, 1)]  # the sub-frame's samples nearby

    def nearest(dy: int, dx: int, skip_own: bool) -> float:
        lags = np.array([[0.0, dy + a, dx + b] for a, b in lattice if not (skip_own and (a, b) == (0, 0))])
        return float(np.min(variogram(G, beta, lags)))

    held = nearest(0, 0, True)  # a held-out sample's nearest kept ones: the neighbouring tiles' (other folds)
    unsampled = [nearest(i - pi, j - pj, False) for pi in range(m) for pj in range(n)
                 for i in range(m) for j in range(n) if (i, j) != (pi, pj)]
    return float(np.mean(unsampled)) / max(held, 1e-30)
