r"""GAP-TV (Yuan 2016): generalized alternating projection with total-variation denoising.

The peer baseline for the per-pixel-shutter forward model with *any* 0/1 code
(identity, multiplexed, or the random masks of the snapshot-compressive-imaging
benchmark). With the per-slot masks :math:`\Phi_k` (K, H, W), one camera frame is
:math:`y = \Phi x = \sum_k \Phi_k \odot x_k` and :math:`\Phi\Phi^\top = R =
\operatorname{diag}(\sum_k \Phi_k^2)` is diagonal, so the Euclidean projection onto
:math:`\{x : \Phi x = y\}` is cheap. GAP alternates that projection with a TV denoiser:

.. math::

    x^{(t)} &= \theta^{(t-1)} + \Phi^\top R^{-1} \bigl(y^{(t)} - \Phi \theta^{(t-1)}\bigr) \\
    \theta^{(t)} &= \operatorname{TV\text{-}denoise}_\lambda\bigl(x^{(t)}\bigr)

with :math:`y^{(t)} = y` (plain GAP) or, accelerated,
:math:`y^{(t)} = y^{(t-1)} + (y - \Phi \theta^{(t-1)})`, :math:`y^{(0)} = y`: the
residual is fed back, which speeds convergence a lot. The start is
:math:`\theta^{(0)} = \Phi^\top R^{-1} y`. Pixels never open in any slot (R = 0) get no
data term (:math:`R^{-1}` taken as 0 there) and are filled by the denoiser only.

The TV denoiser (:func:`tv_denoise`) is Chambolle's projection algorithm for
:math:`\min_u \tfrac12 \lVert u - f\rVert^2 + \lambda\,\mathrm{TV}(u)` with isotropic 2-D
TV on every sub-frame (as in Yuan's GAP-TV), run for a fixed small number of dual
updates from p = 0 at every call, step τ = 1/4.

**Counting TV iterations.** ``tv_iterations`` counts updates of the dual variable p.
The literature's GAP-TV figures use scikit-image's ``denoise_tv_chambolle(...,
max_num_iter=5)``, which returns the image computed *before* its 5th update, i.e. after
4 updates: the reference setting "5 TV iterations" is ``tv_iterations=4`` here (the
default). With 5 updates Runner/Drop lose 1.5 / 4.7 dB with the random mask.

**Intensity scale of the TV weight.** Chambolle's problem is scale-covariant:
denoising ``s·f`` with weight ``s·λ`` gives ``s·u``. flexvox videos are in [0, 1], and
``tv_weight`` is defined on that scale. The reference figures of docs/benchmarks.md (TV weight
0.3) are reproduced with the weight applied on the **0–1** scale (``tv_weight=0.3`` here,
4 dual updates): Runner 29.8 / Drop 35.0 dB with the random mask, 29.4 / 33.8 dB with
the 2×4 flexible-voxel code. Read on the 0–255 scale (``tv_weight=0.3/255`` here) the
denoiser does almost nothing: Runner falls to ~14 dB and Drop to ~6 dB with the random
mask (see ``bench/bench_gaptv_sci.py``).

References
----------
X. Yuan, "Generalized alternating projection based total variation minimization for
compressive sensing", ICIP 2016.
A. Chambolle, "An algorithm for total variation minimization and applications",
J. Math. Imaging Vis. 20, 2004.
"""

from __future__ import annotations

import logging

import numpy as np

from flexvox_core.codes import validate_code
from flexvox_core.forward import tiled_code
from flexvox_core.numbers import positive_number
from flexvox_core.reconstruct._common import check_dtype, check_frames

_logger = logging.getLogger(__name__)

__all__ = ["gap", "gap_tv", "gap_tv_masks", "tv_denoise"]

TV_STEP = 0.25


def _check_pos_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"`{name}` must be an integer >= {minimum}; got {value!r}")
    return int(value)


def _check_weight(value) -> float:
    return positive_number("`tv_weight`", value)


def _tv_kernel(f: np.ndarray, weight: float, iterations: int) -> np.ndarray:
    """Chambolle's projection on every ``(H, W)`` plane of ``f`` (N, H, W), vectorised."""
    dt = f.dtype.type
    tau = dt(TV_STEP)
    px = np.zeros_like(f)
    py = np.zeros_like(f)
    div = np.zeros_like(f)
    z = np.empty_like(f)
    gx = np.zeros_like(f)
    gy = np.zeros_like(f)
    norm = np.empty_like(f)
    f_over = f * dt(1.0 / weight)
    for _ in range(iterations):
        np.subtract(div, f_over, out=z)  # z = div p − f/λ
        np.subtract(z[:, :, 1:], z[:, :, :-1], out=gx[:, :, :-1])  # forward differences,
        np.subtract(z[:, 1:, :], z[:, :-1, :], out=gy[:, :-1, :])  # 0 at the last column/row
        np.multiply(gx, gx, out=norm)
        norm += gy * gy
        np.sqrt(norm, out=norm)
        norm *= tau
        norm += dt(1)
        px += tau * gx
        px /= norm
        py += tau * gy
        py /= norm
        # div p = −∇ᵀp (backward differences, the adjoint of the gradient above)
        div[:, :, 0] = px[:, :, 0]
        np.subtract(px[:, :, 1:-1], px[:, :, :-2], out=div[:, :, 1:-1])
        div[:, :, -1] = -px[:, :, -2] if f.shape[2] > 1 else 0
        div[:, 0, :] += py[:, 0, :]
        div[:, 1:-1, :] += py[:, 1:-1, :] - py[:, :-2, :]
        if f.shape[1] > 1:
            div[:, -1, :] -= py[:, -2, :]
    return f - dt(weight) * div


def tv_denoise(f, *, weight: float = 0.1, iterations: int = 4, dtype=np.float32) -> np.ndarray:
    r"""Isotropic 2-D TV denoising of every plane by Chambolle's projection algorithm.

    .. math::

        u = \arg\min_u \tfrac12 \lVert u - f \rVert^2 + \lambda \sum |\nabla u|,
        \qquad u = f - \lambda \operatorname{div} p

    Parameters
    ----------
    f : ndarray, shape (N, H, W) or (H, W)
        Planes to denoise (each independently).
    weight : float, keyword-only
        λ > 0, on the intensity scale of ``f``.
    iterations : int, keyword-only
        Dual (p) updates from p = 0 (τ = 1/4); 0 returns ``f``.
    dtype : float32 or float64, keyword-only

    Returns
    -------
    u : ndarray, shape of ``f``

    Examples
    --------
    >>> import numpy as np
    >>> u = tv_denoise(np.full((4, 4), 0.5), weight=0.2)
    >>> bool(np.allclose(u, 0.5))
    True
    """
    arr = np.asarray(f)
    if arr.ndim not in (2, 3):
        raise ValueError(f"`f` must have shape (N, H, W) or (H, W); got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("`f` holds NaN or infinite values")
    w = _check_weight(weight)
    it = _check_pos_int("iterations", iterations, 0)
    dt = check_dtype(dtype)
    planes = arr.astype(dt).reshape((-1,) + arr.shape[-2:])
    return _tv_kernel(planes, w, it).reshape(arr.shape)


def gap(y: np.ndarray, masks: np.ndarray, denoise, iterations: int, *, accelerate: bool = True,
        start: np.ndarray | None = None) -> np.ndarray:
    """Generalized alternating projection with any ``denoise`` (the loop of the module notes).

    Parameters
    ----------
    y : ndarray (F, H, W)
        Measurements, float32 or float64 (the working precision).
    masks : ndarray (K, H, W)
        Per-slot masks.
    denoise : callable
        ``(F·K, H, W) -> (F·K, H, W)``: the prior (TV here; a Gaussian or a motion-compensated
        one in :mod:`flexvox_core.reconstruct.multiplexed`).
    iterations : int
    accelerate : bool
        Feed the residual back.
    start : ndarray (F, K, H, W), optional
        θ⁽⁰⁾ (default ``Φᵀ R⁻¹ y``).

    Returns
    -------
    theta : ndarray (F, K, H, W)
    """
    dt = y.dtype.type
    phi = masks.astype(y.dtype)[None]  # (1, K, H, W)
    R = phi[0].sum(axis=0)
    r_inv = np.zeros_like(R)
    np.divide(dt(1), R, out=r_inv, where=R > 0)
    F = y.shape[0]
    K, H, W = masks.shape
    theta = phi * (y * r_inv)[:, None] if start is None else start.astype(y.dtype)
    y_acc = y.copy()
    for _ in range(iterations):
        resid = y - (phi * theta).sum(axis=1)  # y − Φθ
        if accelerate:
            y_acc += resid
            resid = y_acc - (y - resid)  # y^(t) − Φθ
        x = theta + phi * (resid * r_inv)[:, None]
        theta = denoise(x.reshape(F * K, H, W)).reshape(F, K, H, W)
    return theta


def _gap_kernel(y: np.ndarray, masks: np.ndarray, iterations: int, weight: float,
                tv_iterations: int, accelerate: bool) -> np.ndarray:
    """GAP-TV for measurements ``y`` (F, H, W) and masks (K, H, W); returns (F, K, H, W)."""
    return gap(y, masks, lambda v: _tv_kernel(v, weight, tv_iterations), iterations, accelerate=accelerate)


def gap_tv_masks(frames, masks, *, iterations: int = 40, tv_weight: float = 0.3,
                 tv_iterations: int = 4, accelerate: bool = True, dtype=np.float32) -> np.ndarray:
    """GAP-TV with a per-slot mask volume (e.g. the SCI benchmark's random mask).

    Parameters
    ----------
    frames : ndarray, shape (F, H, W) or (H, W)
        Measurements ``y[f] = Σ_k masks[k] · video[f·K + k]``, intensities on the 0–1 scale.
    masks : ndarray, shape (K, H, W)
        Per-slot masks, any nonnegative values (0/1 for a shutter). The SCI benchmark
        stores its mask as (H, W, K): pass ``mask.transpose(2, 0, 1)``.
    iterations : int, keyword-only
        GAP iterations (40 in the reference figures).
    tv_weight : float, keyword-only
        λ of the TV denoiser on the 0–1 intensity scale (see the module notes).
    tv_iterations : int, keyword-only
        Chambolle dual updates per denoising call (4 = the literature's "5 TV
        iterations", see the module notes).
    accelerate : bool, keyword-only
        Feed the residual back (accelerated GAP).
    dtype : float32 or float64, keyword-only

    Returns
    -------
    video : ndarray, shape (F·K, H, W)
        Clipped to ``[0, max(frames)]`` when the measurements are nonnegative (each
        voxel is nonnegative and at most any measurement it contributes to).

    Examples
    --------
    >>> import numpy as np
    >>> masks = np.ones((2, 4, 4)); y = np.full((4, 4), 1.0)
    >>> bool(np.allclose(gap_tv_masks(y, masks, iterations=5), 0.5))
    True
    """
    arr = np.asarray(frames)
    if arr.ndim == 2:
        arr = arr[None]
    f = check_frames(arr)
    m = np.asarray(masks)
    if m.ndim != 3 or m.shape[1:] != f.shape[1:]:
        raise ValueError(f"`masks` must have shape (K, H, W) with (H, W) = {f.shape[1:]}; got {m.shape}")
    if not (np.issubdtype(m.dtype, np.number) or m.dtype == bool) or not np.isfinite(m).all() or (m < 0).any():
        raise ValueError("`masks` must hold finite nonnegative numbers")
    it = _check_pos_int("iterations", iterations, 0)
    tv_it = _check_pos_int("tv_iterations", tv_iterations, 0)
    w = _check_weight(tv_weight)
    dt = check_dtype(dtype)
    y = f.astype(dt)
    out = _gap_kernel(y, m, it, w, tv_it, bool(accelerate))
    F, K, H, W = out.shape
    out = out.reshape(F * K, H, W)
    if y.min() >= 0:
        np.clip(out, 0, y.max(), out=out)
    _logger.debug("gap_tv: %d frames, K = %d, %d iterations", F, K, it)
    return out


def gap_tv(frames, code, *, iterations: int = 40, tv_weight: float = 0.3,
           tv_iterations: int = 4, accelerate: bool = True, dtype=np.float32) -> np.ndarray:
    """GAP-TV for a flexvox capture with any 0/1 ``code`` (identity or multiplexed).

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        Camera frames, 0–1 intensity scale.
    code : ndarray, shape (m, n, K)
        The shutter code (tiled over the sensor, partial border tiles allowed).
    iterations, tv_weight, tv_iterations, accelerate, dtype
        As in :func:`gap_tv_masks`.

    Returns
    -------
    video : ndarray, shape (F·K, H, W)
    """
    f = check_frames(frames)
    c = validate_code(code)
    _, H, W = f.shape
    return gap_tv_masks(f, tiled_code(c, H, W), iterations=iterations, tv_weight=tv_weight,
                        tv_iterations=tv_iterations, accelerate=accelerate, dtype=dtype)
