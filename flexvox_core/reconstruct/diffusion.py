r"""Constant-tensor diffusion (the paper's §3.1): a continuum from high SR to high TR.

The missing voxels of the sparse sample volume are filled by the diffusion

.. math::

    \frac{\partial I}{\partial n} = \operatorname{trace}(T H), \qquad
    T = \operatorname{diag}(c_x, c_y, c_t),

whose solution after diffusion time ``n`` is a convolution with the Gaussian of
covariance :math:`2 n T` (the paper's Eq. 3): standard deviations
:math:`\sigma_i = \sqrt{2 n c_i}` pixels (sub-frames for t). The tensor is not
normalised: ``(cx, cy, ct)`` and ``time`` only enter as ``time · c_i``. Tensors with
:math:`c_t \gg c_x, c_y` (e.g. (0, 0, 1)) smooth along time and keep spatial detail
(high SR, low TR); :math:`c_t \ll c_x, c_y` (e.g. (1, 1, 0)) the opposite.

The diffusion time ``n`` is an accuracy knob, not a convergence tolerance: too little
leaves the sampling lattice visible, too much blurs (and the steady state, ``n → ∞``
with the samples held fixed, is worse than stopping early — docs/architecture.md, "Facts the
design rests on").

Solvers (one interface, :func:`diffuse`):

``"nc"`` — normalized convolution (Knutsson & Westin 1993), the one-pass form of Eq. 3
    with missing data: :math:`\hat I = (G * (M \cdot I_0)) / (G * M)` with ``M`` the
    sample mask. Separable Gaussians: along time over each pixel's own samples (a few per
    sub-frame; compiled, :mod:`~flexvox_core.reconstruct.nc_time_kernel`), then OpenCV float32
    blurs for the spatial axes. Kernels are sampled Gaussians truncated at 4 σ (as
    ``scipy.ndimage.gaussian_filter``); an axis with ``c_i = 0`` is not blurred.
    Boundaries reflect (``BORDER_REFLECT``, edge duplicated). Where ``G * M`` is zero or
    tiny (below :data:`NC_MIN_WEIGHT`: no sample within the truncated kernel, e.g.
    ``c_x = c_y = 0`` and a short time), the voxel takes the value of its nearest sample
    in the tensor's metric (distance along axis i divided by σᵢ; zero-variance axes
    count 1000× the smallest nonzero σ), so the result is never NaN and tends to the
    nearest-neighbour interpolation as ``n → 0``.
``"explicit"`` — Eq. 2 iterated on the missing voxels only with the monotone 7-point
    stencil :math:`\sum_i c_i [I(x + e_i) - 2 I(x) + I(x - e_i)]` and time step
    :math:`dt = n / \lceil n / dt_{max} \rceil`, :math:`dt_{max} = 1 / (2 \sum_i c_i)`.
    Under this bound every update is a convex combination of the old values, so the
    iteration obeys the discrete maximum principle at any anisotropy (unlike the
    centred 19-point stencil for full tensors, docs/architecture.md). Reflecting boundary
    (ghost voxel = edge voxel). Started from ``nc`` with the same tensor and time
    (``init="nc"``, the default: nc followed by the same amount of data-consistent
    diffusion) or from the samples' mean (``init="mean"``).
``"steady"`` — the steady state :math:`\sum_i c_i \partial_i^2 I = 0` at the missing
    voxels, samples as Dirichlet data, reflecting boundary: a sparse SPD system solved by
    Jacobi-preconditioned conjugate gradients (scipy), started from ``nc``. ``time`` only
    sets that starting point. It is here to show that the steady state is not the goal.

``keep_samples`` (data consistency) writes the measured voxels back unchanged; it only
changes ``nc``, the other two solvers never move a sample. Every solver's output lies in
``[min(samples), max(samples)]`` (``nc`` is clipped to it, to absorb rounding).

References
----------
H. Knutsson, C.-F. Westin, "Normalized and differential convolution: methods for interpolation and filtering of
incomplete and uncertain data", CVPR 1993, pp. 515–523.
J. Weickert, *Anisotropic Diffusion in Image Processing*, Teubner, Stuttgart, 1998.
D. Tschumperlé, R. Deriche, "Vector-valued image regularization with PDEs", PAMI 2005.
"""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.gaps import as_missing, captured
from flexvox_core.numbers import positive_number
from flexvox_core.reconstruct._common import check_dtype, check_frames, check_identity_code
from flexvox_core.threads import for_each

_logger = logging.getLogger(__name__)

__all__ = ["NC_MIN_WEIGHT", "SOLVERS", "diffuse", "diffuse_where", "gaussian", "sigmas", "stability_bound"]

SOLVERS = ("nc", "explicit", "steady")

NC_MIN_WEIGHT = 1e-12
"""Blurred-mask values at or below this (relative to the kernel's peak weight product,
at most 1) are treated as "no sample nearby": those voxels take the nearest sample."""

TRUNCATE = 4.0
"""Gaussian kernels are cut at ``TRUNCATE`` standard deviations (as scipy.ndimage)."""

_CHUNK = 16384  # columns per cv2 call for the time axis (a wide thin image filters slowly)
PARALLEL_ENDS_TAPS = 49
"""Time kernels shorter than this blur the two ends of :class:`_PeriodicDenominator` on two threads."""

_BLUR_AT_FINISH = True
"""nc's general path blurs a sub-frame's numerator in space just before it finishes it (False: every sub-frame
blurred in a pass of its own first; ``bench/bench_motion_throughput.py --ab nc-blur-apart``)."""

SELECT_BAND = 16
"""Sub-frames of a selection read at a time by :func:`diffuse_where` when it is given as bands."""

MAX_SIGMA = 10000.0
"""The largest blur (σ, pixels or sub-frames) a tensor and time may ask for: far beyond any recording's extent
(the blur is then flat), and short of kernels that would not fit in memory (4 σ taps each side)."""

MAX_EXPLICIT_STEPS = 20000
"""``explicit`` refuses runs longer than this many steps (``time · 2·Σc`` of them)."""

STEADY_RTOL = 1e-6
STEADY_MAXITER = 5000


# --------------------------------------------------------------------------- validation


def check_tensor(tensor) -> tuple[float, float, float]:
    try:
        vals = tuple(float(v) for v in tensor)
    except (TypeError, ValueError):
        raise ValueError(f"`tensor` must be three numbers (cx, cy, ct); got {tensor!r}") from None
    if len(vals) != 3:
        raise ValueError(f"`tensor` must be three numbers (cx, cy, ct); got {len(vals)}: {tensor!r}")
    if not all(math.isfinite(v) and v >= 0 for v in vals):
        raise ValueError(f"`tensor` entries must be finite and >= 0; got {tensor!r}")
    if max(vals) == 0:
        raise ValueError(f"`tensor` must have at least one positive entry; got {tensor!r}")
    return vals  # type: ignore[return-value]


def _check_time(time) -> float:
    return positive_number("`time`", time)


def sigmas(tensor, time) -> tuple[float, float, float]:
    """Gaussian standard deviations ``(σx, σy, σt) = sqrt(2·time·c)`` of Eq. 3.

    Examples
    --------
    >>> sigmas((1, 1, 0), 2.0)
    (2.0, 2.0, 0.0)
    """
    c = check_tensor(tensor)
    t = _check_time(time)
    sig = tuple(math.sqrt(2.0 * t * ci) for ci in c)
    if not all(s <= MAX_SIGMA for s in sig):  # inf and NaN too (time · c overflows)
        raise ValueError(f"time {time!r} with tensor {tuple(c)} asks for a blur of σ = sqrt(2·time·c) = "
                         f"({', '.join(f'{s:.3g}' for s in sig)}); at most {MAX_SIGMA:g} (pixels or sub-frames) each: "
                         "take a smaller time or tensor")
    return sig  # type: ignore[return-value]


def stability_bound(tensor) -> float:
    """Largest stable, monotone explicit time step ``1 / (2·(cx + cy + ct))``.

    Examples
    --------
    >>> stability_bound((1, 1, 1))
    0.16666666666666666
    """
    return 1.0 / (2.0 * sum(check_tensor(tensor)))


# --------------------------------------------------------------------------- nc kernels


def gaussian_kernel(sigma: float, dtype) -> np.ndarray | None:
    """Sampled Gaussian, truncated at TRUNCATE σ and normalised; None when no blur."""
    radius = int(TRUNCATE * sigma + 0.5)
    if sigma <= 0 or radius == 0:
        return None
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-0.5 * (x / sigma) ** 2)
    return (g / g.sum()).astype(dtype)


def _fold_matrix(g: np.ndarray, length: int, rows: tuple[int, int] | None = None) -> np.ndarray:
    """The ``length × length`` matrix of a 1-D blur with kernel ``g`` and reflecting ends (only
    its ``rows`` [r0, r1) when given).

    Used when the kernel is longer than the axis (the reflection then wraps many times), and
    for a few output rows (:func:`diffuse`'s ``subframes``).
    """
    r = g.size // 2
    r0, r1 = (0, length) if rows is None else rows
    period = 2 * length
    idx = (np.arange(r0, r1)[:, None] + np.arange(-r, r + 1)[None, :]) % period
    idx = np.where(idx >= length, period - 1 - idx, idx)  # reflect: ... 1 0 | 0 1 ... L-1 | L-1 ...
    mat = np.zeros((r1 - r0, length), dtype=np.float64)
    np.add.at(mat, (np.repeat(np.arange(r1 - r0), g.size), idx.ravel()), np.tile(g.astype(np.float64), r1 - r0))
    return mat.astype(g.dtype)


_ONE = {np.float32: np.ones(1, np.float32), np.float64: np.ones(1, np.float64)}


def _blur_rows(img2d: np.ndarray, g: np.ndarray | None, out: np.ndarray) -> None:
    """Blur a 2-D array along axis 0 (rows) with reflecting ends, into ``out``."""
    if g is None:
        if out is not img2d:
            out[...] = img2d
        return
    L = img2d.shape[0]
    if g.size // 2 >= L:
        out[...] = _fold_matrix(g, L) @ img2d
        return
    one = _ONE[img2d.dtype.type]
    # One column chunk at a time: two at a time (for_each) was measured slower for long time kernels
    # (0.95 -> 1.54 s for the still voxels' pass at 640x480), memory-bound.
    for c0 in range(0, img2d.shape[1], _CHUNK):
        sl = slice(c0, c0 + _CHUNK)
        cv2.sepFilter2D(img2d[:, sl], -1, one, g, dst=out[:, sl], borderType=cv2.BORDER_REFLECT)


def _blur_plane(img: np.ndarray, gy: np.ndarray | None, gx: np.ndarray | None, out: np.ndarray) -> None:
    """Separable 2-D blur of one ``(H, W)`` plane with reflecting borders, into ``out``."""
    H, W = img.shape
    one = _ONE[img.dtype.type]
    fold_y = gy is not None and gy.size // 2 >= H
    fold_x = gx is not None and gx.size // 2 >= W
    if fold_y or fold_x or gx is None and gy is None:
        tmp = img if gy is None else (_fold_matrix(gy, H) @ img if fold_y else
                                      cv2.sepFilter2D(img, -1, one, gy, borderType=cv2.BORDER_REFLECT))
        if gx is None:
            out[...] = tmp
        elif fold_x:
            out[...] = tmp @ _fold_matrix(gx, W).T
        else:
            cv2.sepFilter2D(np.ascontiguousarray(tmp), -1, gx, one, dst=out, borderType=cv2.BORDER_REFLECT)
        return
    cv2.sepFilter2D(img, -1, one if gx is None else gx, one if gy is None else gy, dst=out,
                    borderType=cv2.BORDER_REFLECT)


def gaussian(volume, tensor, time) -> np.ndarray:
    """Eq. 3 on a full volume ``(S, H, W)``: the Gaussian of covariance ``2·time·diag(cx, cy, ct)``.

    What :func:`diffuse`'s ``nc`` is when every voxel is sampled (the same separable kernels,
    truncated at :data:`TRUNCATE` σ, reflecting borders), e.g. the denoiser of
    :mod:`flexvox_core.reconstruct.multiplexed`. Returns a new array of the input's float dtype
    (float32 for other numbers); a constant volume comes back unchanged.
    """
    v = np.asarray(volume)
    if v.ndim != 3:
        raise ValueError(f"`volume` must have shape (S, H, W); got {v.shape}")
    dt = v.dtype.type if v.dtype in (np.float32, np.float64) else np.float32
    out = np.array(v, dtype=dt, copy=True)
    gx, gy, gt = (gaussian_kernel(s, dt) for s in sigmas(tensor, time))
    S, H, W = out.shape
    if gx is not None or gy is not None:
        for s in range(S):
            _blur_plane(out[s], gy, gx, out[s])
    flat = out.reshape(S, H * W)
    _blur_rows(flat, gt, flat)
    return out


def _nearest_fill(values: np.ndarray, mask: np.ndarray, where: np.ndarray, sig) -> None:
    """Give the voxels ``where`` the value of their nearest sample (tensor metric), in place."""
    from scipy.ndimage import distance_transform_edt  # scipy where it is needed: not a cost of every import

    pos = [s for s in sig if s > 0]
    smallest = min(pos)
    sampling = [1.0 / (s if s > 0 else 1e-3 * smallest) for s in (sig[2], sig[1], sig[0])]
    idx = distance_transform_edt(~mask, sampling=sampling, return_distances=False, return_indices=True)
    values[where] = values[tuple(i[where] for i in idx)]


def _sample_volume(frames: np.ndarray, code: np.ndarray, dtype) -> tuple[np.ndarray, np.ndarray]:
    """Sparse values ``(S, H, W)`` (0 off-sample) and the slot of every pixel."""
    F, H, W = frames.shape
    K = code.shape[2]
    order = tiled_order(code, H, W)
    slots = np.arange(K)[:, None, None] == order[None]  # (K, H, W): one True per pixel
    vals = np.zeros((F, K, H, W), dtype=dtype)
    np.copyto(vals, frames.astype(dtype, copy=False)[:, None], where=slots[None])
    return vals.reshape(F * K, H, W), order


def _sample_mask(order: np.ndarray, F: int, K: int) -> np.ndarray:
    """Bool ``(F·K, H, W)``: True at the sampled voxels."""
    return np.tile(np.arange(K)[:, None, None] == order[None], (F, 1, 1))


def self_weights(g: np.ndarray | None, length: int) -> np.ndarray:
    """Weight (float64, ``length``) each position gives itself in a 1-D blur with kernel ``g`` and reflecting
    ends (edge duplicated, as every blur here): the kernel's centre, more near an end where the kernel
    folds back onto the position. 1 without a blur (None)."""
    if g is None:
        return np.ones(length)
    r = g.size // 2
    period = 2 * length
    pos = np.arange(length)
    idx = (pos[:, None] + np.arange(-r, r + 1)[None, :]) % period
    idx = np.where(idx >= length, period - 1 - idx, idx)
    return ((idx == pos[:, None]) * g.astype(np.float64)[None, :]).sum(axis=1)


def _mask_planes(order: np.ndarray, K: int, gy, gx, dtype) -> np.ndarray:
    """The sample mask's K distinct sub-frames (slot k open where ``order`` is k), each blurred in space."""
    H, W = order.shape
    den_k = np.empty((K, H, W), dtype=dtype)
    for k in range(K):
        _blur_plane((order == k).astype(dtype), gy, gx, den_k[k])
    return den_k


def _peak(kernels) -> float:
    """The largest weight of the separable kernel made of ``kernels`` (None: no blur on that axis)."""
    peak = 1.0
    for g in kernels:
        if g is not None:
            peak *= float(g.max())
    return peak


def _nc_kernel(frames, code, sig, keep_samples: bool, dtype, present=None, loo=None) -> np.ndarray:
    """Normalized convolution; ``present`` (F,) bool or None: frames without samples are left out.
    ``loo`` (F, H, W) float32, optional: filled with each sample's leave-one-out estimate (NaN where no
    other sample is in reach, or the frame is missing)."""
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    gx, gy, gt = (gaussian_kernel(s, dtype) for s in sig)
    if present is not None:  # a dropped frame's row holds no samples: nothing of it enters the sums
        frames = np.where(present[:, None, None], frames, 0).astype(frames.dtype, copy=False)
    if gx is None and gy is None and gt is not None and loo is None:
        fast = _nc_time_only(frames, code, sig[2], keep_samples, dtype, present)
        if fast is not None:
            return fast
    spatial = gx is not None or gy is not None
    if gt is not None:
        # Numerator: each pixel's samples blurred in time (a few per sub-frame: compiled, no volume of
        # mostly-zero sub-frames blurred), then every sub-frame in space. The blurs commute: the same sums up to
        # float rounding (and the same with ``loo``, so that nc_leave_one_out's video stays diffuse's, bit for bit).
        num, order = _time_blurred_samples(frames, code, sig[2], dtype, present)
        late = spatial and loo is None and _BLUR_AT_FINISH  # sub-frames blurred in space as they are finished
    else:
        num, order = _sample_volume(frames, code, dtype)
        # Numerator: spatial blur of every sub-frame (two at a time: OpenCV releases the GIL), then time.
        if spatial:
            for_each(lambda s: _blur_plane(num[s], gy, gx, num[s]), S)
        flat = num.reshape(S, H * W)
        _blur_rows(flat, gt, flat)
        late = False
    # Denominator: the mask has only K distinct sub-frames; blur those in space, then time. The sub-frames the
    # last pass finishes (all, or the interior the blurred mask's ends leave) are blurred in space there, while in
    # cache; the others (the ends' sub-frames, finished as their blurred mask is made) here, beside the mask's planes.
    finished_last = range(S) if present is not None or loo is not None else _interior(S, K, gt)
    early = [] if not spatial or gt is None else [s for s in range(S) if not late or s not in finished_last]
    blur_late = np.zeros(S, bool)
    blur_late[finished_last] = late
    den_k = np.empty((K, H, W), dtype=dtype)
    slots: list[np.ndarray] = [np.empty(0, bool)] * K  # each slot's sample mask, row-major (order may be a view)

    def first(i: int, den_k: np.ndarray = den_k) -> None:
        if i < K:
            slots[i] = np.ascontiguousarray(order == i)
            _blur_plane(slots[i].astype(dtype), gy, gx, den_k[i])
        else:
            s = early[i - K]
            _blur_plane(num[s], gy, gx, num[s])

    for_each(first, K + len(early))
    peak = _peak((gx, gy, gt))
    floor = NC_MIN_WEIGHT * peak
    samples = np.ascontiguousarray(frames, dtype=dtype)  # read a plane at a time, flat, by the finish
    kept = captured(samples, None if present is None else ~present)
    lo, hi = kept.min(), kept.max()
    # The voxels without a sample in reach (rare): zeroed pages cost nothing until a sub-frame writes its own.
    low = np.zeros((S, H, W), bool)
    any_low = np.zeros(S, bool)

    floor_t = num.dtype.type(floor)  # numpy compares a float32 plane with a Python float in float32

    def finish(s: int, d: np.ndarray, cols: slice | None = None) -> None:
        # A sub-frame divided, clipped to the samples' range and given its samples back in one pass (compiled,
        # :func:`_finish_plane`), while it is in cache; on every core. Its columns `cols` of the flattened plane
        # alone (element by element: the same bits whichever columns at a time).
        part = slice(None) if cols is None else cols
        n = num[s].reshape(-1)[part]
        d = d.reshape(-1)
        give = keep_samples and (present is None or present[s // K])
        if _finish_plane(n, d, floor_t, lo, hi, samples[s // K].reshape(-1)[part], slots[s % K].reshape(-1)[part],
                         give):
            low[s].reshape(-1)[cols] = d <= floor_t  # only then: a sub-frame's pages of `low` are touched only if
            any_low[s] = True  # it has any

    if present is not None:
        den = _gapped_denominator(den_k, present, gt)
    else:  # without the leave-one-out the ends' sub-frames are finished as their blurred mask is made, not held
        den = _PeriodicDenominator(den_k, F, gt, ends=finish if loo is None else None)
    del den_k  # the denominator holds what it reads
    if loo is not None:
        _leave_one_out(loo, num, den, frames, order, (gx, gy, gt), floor, present)
    rows = range(S) if present is not None else den.interior

    def last(i: int) -> None:
        s = rows[i]
        if blur_late[s]:
            _blur_plane(num[s], gy, gx, num[s])
        finish(s, den[s])

    for_each(last, len(rows))
    if any_low.any():
        # A sample's blurred mask holds at least its own weight: no sample is among these voxels, and the
        # nearest sample's value needs no clipping.
        _logger.debug("nc: %d voxels without a sample in reach take the nearest sample", int(low.sum()))
        _put_samples(num, samples, order, present)
        mask = _sample_mask(order, F, K)
        if present is not None:
            mask &= np.repeat(present, K)[:, None, None]
        _nearest_fill(num, mask, low, sig)
    return num


def _finish_numpy(num, den, floor, lo, hi, own, slot, keep: bool) -> int:
    """:func:`~flexvox_core.reconstruct.nc_time_kernel.finish_plane` in numpy (its reference, the same bits): ``num``
    divided by ``den`` where it is above ``floor``, clipped to [lo, hi], ``own`` written at ``slot`` with ``keep``;
    in place (1-D). Returns how many voxels are at or below ``floor``."""
    low = den <= floor
    count = int(np.count_nonzero(low))
    if count:
        np.divide(num, den, out=num, where=~low)
    else:
        np.divide(num, den, out=num)
    np.clip(num, lo, hi, out=num)
    if keep:
        np.copyto(num, own, where=slot)
    return count


def _finish_plane(num, den, floor, lo, hi, own, slot, keep: bool) -> int:
    """nc's last steps on one sub-frame (or a band of its columns), compiled:
    :func:`~flexvox_core.reconstruct.nc_time_kernel.finish_plane` (:func:`_finish_numpy` its reference)."""
    from flexvox_core.reconstruct.nc_time_kernel import finish_plane

    return finish_plane(num, den, floor, lo, hi, own, slot, keep)


def time_weights(g: np.ndarray, K: int, F: int, present) -> tuple[np.ndarray, np.ndarray]:
    """The time blur ``g`` (reflecting ends) of an ``F·K``-sub-frame clip as weights on each pixel's samples:
    ``weight[s, k, b]`` (float64) that sub-frame s gives the sample of frame ``first[s] + b`` of a pixel of
    slot k (0 for frames not ``present``)."""
    S = F * K
    r = g.size // 2
    period = 2 * S
    j = (np.arange(S)[:, None] + np.arange(-r, r + 1)[None, :]) % period
    j = np.where(j >= S, period - 1 - j, j)  # reflect, as _fold_matrix
    f, k = j // K, j % K
    first, last = f.min(axis=1), f.max(axis=1)
    span = int((last - first).max()) + 1
    first = np.minimum(first, F - span)
    weight = np.zeros((S, K, span), np.float64)
    s_idx = np.broadcast_to(np.arange(S)[:, None], j.shape)
    np.add.at(weight, (s_idx, k, f - first[:, None]), np.broadcast_to(g.astype(np.float64)[None, :], j.shape))
    if present is not None:
        weight *= np.asarray(present, bool)[first[:, None, None] + np.arange(span)[None, None, :]]
    return weight, first


def _time_pass(samples, code, weight, first, lo: float, hi: float, dtype, *, keep=None, out=None,
               select=None) -> np.ndarray:
    """``out[s, y, x]`` = Σ_b weight[s, order[y, x], b] · samples[first[s] + b, y, x], clipped to [lo, hi]
    (:mod:`~flexvox_core.reconstruct.nc_time_kernel`, bands of rows spread over the cores). ``keep`` (F,)
    bool: those frames' samples are written at their voxels instead (``keep_samples``). ``out``: written
    in place (a new volume when None); ``select`` (S, H, W) bool, an object holding it packed (``packed``: see
    :func:`diffuse_where`), read by the kernel as it is, or one read a band of sub-frames at a time (``band(s0, s1)``,
    :data:`SELECT_BAND` of them): only those voxels of it."""
    from flexvox_core.reconstruct.nc_time_kernel import time_only_rows

    F, H, W = samples.shape
    m, _, K = code.shape
    S = F * K
    order = tiled_order(code, min(H, m), W).astype(np.int64)  # repeats every m rows
    if out is None:
        out = np.empty((S, H, W), dtype)
    rows = 32

    def run(s0: int, s1: int, chosen, packed=None) -> None:
        for_each(lambda i: time_only_rows(samples, order, weight, first, lo, hi, out, i * rows,
                                          min(H, (i + 1) * rows), keep, chosen, s0, s1, packed), -(-H // rows))

    if select is None or isinstance(select, np.ndarray):
        run(0, S, select)
        return out
    packed = getattr(select, "packed", None)
    if packed is not None:  # every sub-frame in one pass, the bits read where they are
        packed = np.asarray(packed)
        if packed.shape != (S, H, (W + 7) // 8) or packed.dtype != np.uint8 or not packed.flags.c_contiguous:
            raise ValueError(f"`where`.packed must be a C-contiguous uint8 array of shape {(S, H, (W + 7) // 8)}; "
                             f"got {packed.dtype} {packed.shape}")
        run(0, S, None, packed)
        return out
    for s0 in range(0, S, SELECT_BAND):  # a band of the selection at a time: never the whole bool volume
        s1 = min(S, s0 + SELECT_BAND)
        chosen = np.ascontiguousarray(select.band(s0, s1), dtype=bool)
        if chosen.shape != (s1 - s0, H, W):
            raise ValueError(f"`where`.band({s0}, {s1}) must have shape {(s1 - s0, H, W)}; got {chosen.shape}")
        if chosen.any():
            run(s0, s1, chosen)
    return out


def _time_blurred_samples(frames, code, sigma_t: float, dtype, present) -> tuple[np.ndarray, np.ndarray]:
    """The sparse sample volume blurred in time, and the slot of every pixel (:func:`_sample_volume`
    followed by the time blur, the same up to float rounding)."""
    F, H, W = frames.shape
    weight, first = time_weights(gaussian_kernel(sigma_t, np.float64), code.shape[2], F, present)
    samples = np.ascontiguousarray(frames, dtype=dtype)
    return _time_pass(samples, code, weight, first, -math.inf, math.inf, dtype), tiled_order(code, H, W)


def _nc_time_only(frames, code, sigma_t: float, keep_samples: bool, dtype, present, *, out=None,
                  select=None) -> np.ndarray | None:
    """:func:`_nc_kernel` for a tensor without spatial blur: each pixel's own samples weighed in time
    (:mod:`~flexvox_core.reconstruct.nc_time_kernel`), the same values up to float rounding. None where a
    voxel has no sample in reach (the general path then gives it its nearest sample). ``out``, ``select``:
    the result written into ``out`` at the voxels ``select`` alone (as :func:`_time_pass`)."""
    F, H, W = frames.shape
    weight, first = time_weights(gaussian_kernel(sigma_t, np.float64), code.shape[2], F, present)
    den = weight.sum(axis=2)
    if (den <= NC_MIN_WEIGHT * float(gaussian_kernel(sigma_t, dtype).max())).any():
        return None
    weight /= den[:, :, None]
    samples = np.ascontiguousarray(frames, dtype=dtype)
    kept = captured(samples, None if present is None else ~present)
    keep = (np.ones(F, bool) if present is None else np.asarray(present, bool)) if keep_samples else None
    return _time_pass(samples, code, weight, first, float(kept.min()), float(kept.max()), dtype, keep=keep,
                      out=out, select=select)


def _leave_one_out(loo, num, den, frames, order, kernels, floor, present) -> None:
    """Fill ``loo`` (F, H, W) with each sample's leave-one-out estimate (N − c·y)/(D − c) from the blurred
    samples ``num`` (S, H, W, before the division) and mask ``den`` (indexable by sub-frame), a frame at a
    time: its pixels' own sub-frames taken at once (NaN where D − c <= ``floor``, and in missing frames)."""
    F, H, W = frames.shape
    K = len(num) // F
    gx, gy, gt = kernels
    own_t = self_weights(gt, len(num))
    own_yx = self_weights(gy, H)[:, None] * self_weights(gx, W)[None, :]
    pick = order[None].astype(np.intp)
    slots = [order == k for k in range(K)]
    d_at = np.empty((H, W), num.dtype)
    loo[...] = np.nan
    for f in range(F):
        if present is not None and not present[f]:
            continue
        span = slice(f * K, (f + 1) * K)
        n_at = np.take_along_axis(num[span], pick, axis=0)[0]
        for k in range(K):  # each pixel's own sub-frame of the blurred mask (no stack of K planes: fresh memory)
            np.copyto(d_at, den[f * K + k], where=slots[k])
        c = (own_yx * own_t[f * K + order]).astype(num.dtype)
        rest = d_at - c
        ok = rest > floor
        loo[f] = np.where(ok, (n_at - c * frames[f].astype(num.dtype)) / np.where(ok, rest, 1), np.nan)


def _nc_rows(frames, code, sig, keep_samples: bool, dtype, present, rows: tuple[int, int]) -> np.ndarray:
    """Sub-frames [r0, r1) of :func:`_nc_kernel`'s result, computed alone: the spatial blur of the
    sub-frames the time kernel reaches from them, and the time blur as a small matrix product
    (the rows of the reflecting blur's matrix). The same values up to float rounding; where a
    voxel has no sample in reach, the whole kernel runs and is cut."""
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    r0, r1 = rows
    gx, gy, gt = (gaussian_kernel(s, dtype) for s in sig)
    mat = np.eye(S, dtype=dtype)[r0:r1] if gt is None else _fold_matrix(gt, S, rows=(r0, r1))
    reached = np.flatnonzero(mat.any(axis=0))
    c0, c1 = int(reached[0]), int(reached[-1]) + 1
    mat = mat[:, c0:c1]
    order = tiled_order(code, H, W)
    if present is not None:  # a dropped frame's row holds no samples: nothing of it enters the sums
        mat = mat * np.repeat(present, K)[c0:c1][None, :].astype(dtype)
    samples = frames.astype(dtype, copy=False)
    num = np.empty((c1 - c0, H, W), dtype)

    def one(i):
        s = c0 + i
        plane = np.where(order == s % K, samples[s // K], 0).astype(dtype)
        _blur_plane(plane, gy, gx, num[i])

    for_each(one, c1 - c0)
    out = (mat @ num.reshape(c1 - c0, H * W)).reshape(r1 - r0, H, W)
    # Denominator: the mask has K distinct sub-frames; the matrix's columns summed per phase weigh them.
    den_k = _mask_planes(order, K, gy, gx, dtype)
    per_phase = np.zeros((r1 - r0, K), dtype)
    for j in range(c1 - c0):
        per_phase[:, (c0 + j) % K] += mat[:, j]
    den = (per_phase @ den_k.reshape(K, H * W)).reshape(r1 - r0, H, W)
    peak = _peak((gx, gy, gt))
    if (den <= NC_MIN_WEIGHT * peak).any():  # a voxel needs its nearest sample: the whole kernel's way
        return _nc_kernel(frames, code, sig, keep_samples, dtype, present)[r0:r1]
    np.divide(out, den, out=out)
    kept = captured(samples, None if present is None else ~present)
    np.clip(out, kept.min(), kept.max(), out=out)
    if keep_samples:
        for s in range(r0, r1):
            if present is None or present[s // K]:
                np.copyto(out[s - r0], samples[s // K], where=order == s % K)
    return out


def _gapped_denominator(den_k: np.ndarray, present: np.ndarray, gt: np.ndarray | None) -> np.ndarray:
    """The blurred sample mask ``(F·K, H, W)`` when some frames have no samples (not periodic:
    built whole, one more volume)."""
    K, H, W = den_k.shape
    F = len(present)
    den = np.zeros((F * K, H, W), den_k.dtype)
    for f in np.flatnonzero(present):
        den[f * K: (f + 1) * K] = den_k
    flat = den.reshape(F * K, H * W)
    _blur_rows(flat, gt, flat)
    return den


def _interior(S: int, K: int, gt: np.ndarray | None) -> range:
    """:attr:`_PeriodicDenominator.interior` of an ``S``-sub-frame clip with time kernel ``gt``, its ends handed over
    (``ends``), before it is made."""
    r = 0 if gt is None else gt.size // 2
    if gt is None or min(S, 2 * r + K) == S:
        return range(S)
    return range(r + K, max(r + K, S - r - K))


class _PeriodicDenominator:
    """The time-blurred sample mask ``den[s]`` of an ``F·K``-sub-frame clip without the full volume.

    The mask repeats every K sub-frames, so away from the clip's ends (farther than the time
    kernel's radius r) the blurred mask does too; only the first and last ``r + K`` sub-frames
    see the reflecting ends. Those come from blurring ``2r + K`` sub-frames at each end (exactly
    what the whole clip's blur gives there), a band of columns at a time; the rest repeats one
    period of the first end's. A clip too short for that is blurred whole.

    ``ends``: a callable ``ends(s, row, cols)`` that takes each end sub-frame's blurred mask as its
    columns ``cols`` (a slice of the flattened plane) are made, ``row`` 1-D, in place of holding the ends
    (:meth:`__getitem__` then gives the interior's sub-frames alone); None: the ends are held.
    """

    def __init__(self, den_k: np.ndarray, F: int, gt: np.ndarray | None, ends=None) -> None:
        K, H, W = den_k.shape
        self.K, self.S = K, F * K
        self.r = 0 if gt is None else gt.size // 2
        length = min(self.S, 2 * self.r + K)
        self.length = length
        self.den_k: np.ndarray | None = den_k
        self.head: np.ndarray | None = None
        self.tail: np.ndarray | None = None
        self.streamed = False
        if gt is None:
            return
        flat = den_k.reshape(K, H * W)
        if length == self.S:  # a short clip: blurred whole
            block = flat[np.arange(length) % K]
            _blur_rows(block, gt, block)
            self.head = self.tail = block.reshape(length, H, W)
            self.den_k = None
            return
        r = self.r
        # Of each end's blurred block the r + K sub-frames read are kept (the head's last K are the interior's
        # period), or handed to `ends` and the period alone kept.
        self.streamed = ends is not None
        starts = [0, self.S - length]
        kept = [(0, r + K), (length - r - K, length)]
        if self.streamed:
            held = [np.empty((K, H * W), den_k.dtype)]
        else:
            held = [np.empty((b - a, H * W), den_k.dtype) for a, b in kept]
        # The same column bands as _blur_rows cuts a whole block into (the same bits), one block band at a time:
        # never a whole end's block of 2r + K sub-frames.
        cols = list(range(0, H * W, _CHUNK))

        def one(i: int) -> None:
            end, c = divmod(i, len(cols))
            band = slice(cols[c], cols[c] + _CHUNK)
            phases = (starts[end] + np.arange(length)) % K
            block = flat[phases, band]  # (length, columns), a copy
            _blur_rows(block, gt, block)
            a, b = kept[end]
            if not self.streamed:
                held[end][:, band] = block[a:b]
                return
            if end == 0:
                held[0][:, band] = block[r: r + K]
            for j in range(a, b):
                if end == 0 or starts[1] + j >= r + K:  # a short clip's ends overlap: the head's first
                    ends(starts[end] + j, block[j], band)

        # Bands side by side, one per core, for short time kernels; a long one (about 50 taps and more) is filtered
        # on OpenCV's own threads, which for_each would switch off (sigma_t = 8: 0.16 -> 0.29 s).
        if gt.size < PARALLEL_ENDS_TAPS:
            for_each(one, len(starts) * len(cols))
        else:
            for i in range(len(starts) * len(cols)):
                one(i)
        if self.streamed:
            self.period = held[0].reshape(K, H, W)  # phases r .. r + K - 1
        else:
            self.head, self.tail = (e.reshape(-1, H, W) for e in held)
        self.den_k = None  # read no more

    @property
    def interior(self) -> range:
        """The sub-frames :meth:`__getitem__` gives when the ends were handed over (``ends``): those the ends' blur
        does not reach; every sub-frame otherwise."""
        if self.streamed:
            return range(self.r + self.K, max(self.r + self.K, self.S - self.r - self.K))
        return range(self.S)

    def __getitem__(self, s: int) -> np.ndarray:
        r, K = self.r, self.K
        if self.streamed:
            return self.period[(s - r) % K]
        if self.head is None:
            assert self.den_k is not None
            return self.den_k[s % K]
        assert self.tail is not None
        if self.length == self.S or s < r + K:
            return self.head[s]
        if s >= self.S - r - K:
            return self.tail[s - (self.S - r - K)]
        return self.head[r + (s - r) % K]  # one period of the interior: phases r .. r + K - 1


def _put_samples(volume: np.ndarray, samples: np.ndarray, order: np.ndarray, present=None) -> None:
    """Write the captured values back at their voxels of ``volume`` (S, H, W), in place
    (``present``: only those frames' values)."""
    F, H, W = samples.shape
    K = volume.shape[0] // F
    slots = np.arange(K)[:, None, None] == order[None]
    where = slots[None] if present is None else slots[None] & present[:, None, None, None]
    np.copyto(volume.reshape(F, K, H, W), samples[:, None], where=where)


# --------------------------------------------------------------------------- explicit


def _add_second_difference(vol: np.ndarray, axis: int, c: float, acc: np.ndarray) -> None:
    """``acc += c · [I(x+e) − 2 I(x) + I(x−e)]`` along ``axis``, ghost voxels = edge voxels."""
    n = vol.shape[axis]
    if c == 0 or n == 1:
        return
    v = np.moveaxis(vol, axis, 0)
    a = np.moveaxis(acc, axis, 0)
    cc = vol.dtype.type(c)
    a[1:-1] += cc * (v[2:] + v[:-2] - 2 * v[1:-1])
    a[0] += cc * (v[1] - v[0])
    a[-1] += cc * (v[-2] - v[-1])


def _explicit_kernel(init: np.ndarray, mask: np.ndarray, tensor, time: float) -> np.ndarray:
    cx, cy, ct = tensor
    dt_max = 1.0 / (2.0 * (cx + cy + ct))
    steps = max(1, math.ceil(time / dt_max - 1e-9))
    dt = init.dtype.type(time / steps)
    missing = ~mask
    vol = init
    acc = np.empty_like(vol)
    for _ in range(steps):
        acc.fill(0)
        _add_second_difference(vol, 0, ct, acc)
        _add_second_difference(vol, 1, cy, acc)
        _add_second_difference(vol, 2, cx, acc)
        acc *= dt
        np.add(vol, acc, out=vol, where=missing)
    _logger.debug("explicit: %d steps of dt = %.4g (bound %.4g)", steps, float(dt), dt_max)
    return vol


# --------------------------------------------------------------------------- steady


def _steady_kernel(init: np.ndarray, mask: np.ndarray, tensor) -> np.ndarray:
    from scipy.sparse import coo_matrix, diags
    from scipy.sparse.linalg import cg

    S, H, W = init.shape
    N = S * H * W
    index = np.arange(N).reshape(S, H, W)
    rows, cols, vals = [], [], []
    for axis, c in ((0, tensor[2]), (1, tensor[1]), (2, tensor[0])):
        if c == 0 or init.shape[axis] == 1:
            continue
        lo = np.take(index, np.arange(init.shape[axis] - 1), axis=axis).ravel()
        hi = np.take(index, np.arange(1, init.shape[axis]), axis=axis).ravel()
        rows += [lo, hi]
        cols += [hi, lo]
        vals += [np.full(lo.size, c), np.full(lo.size, c)]
    x = init.astype(np.float64).ravel()
    if not rows:
        return init
    adj = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N)).tocsr()
    degree = np.asarray(adj.sum(axis=1)).ravel()
    unknown = np.flatnonzero(~mask.ravel())
    known = np.flatnonzero(mask.ravel())
    a_uu = (diags(degree[unknown]) - adj[unknown][:, unknown]).tocsr()
    b = adj[unknown][:, known] @ x[known]
    d = degree[unknown]
    precond = diags(np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 1.0))
    sol, info = cg(a_uu, b, x0=x[unknown], rtol=STEADY_RTOL, maxiter=STEADY_MAXITER, M=precond)
    if info > 0:
        _logger.warning("steady: CG stopped after %d iterations without reaching rtol %g", info, STEADY_RTOL)
    x[unknown] = sol
    out = x.reshape(S, H, W).astype(init.dtype)
    samples = init[mask]
    np.clip(out, samples.min(), samples.max(), out=out)  # CG rounding only
    return out


# --------------------------------------------------------------------------- public


DEFAULT_TENSOR = (0.15, 0.15, 1.0)
DEFAULT_TIME = 1.5
"""Default tensor and diffusion time, chosen with ``flexvox bench`` as a compromise across
scenes: texture-heavy still scenes prefer the paper's high-SR tensor (0.05, 0.05, 1), the SCI
clips isotropic (1, 1, 1), n = 0.25; this one beats every re-binning and GAP-TV on every group of
the benchmark and lies between those two where either is best. The figures:
docs/reconstruction.md, "Fixed tensors", and docs/benchmarks.md, "flexvox bench"."""


def diffuse(
    frames,
    code,
    *,
    tensor=DEFAULT_TENSOR,
    time: float = DEFAULT_TIME,
    solver: str = "nc",
    keep_samples: bool = True,
    init: str = "nc",
    dtype=np.float32,
    missing=None,
    subframes: tuple[int, int] | None = None,
) -> np.ndarray:
    r"""Fill the missing voxels by diffusion with a constant tensor ``diag(cx, cy, ct)``.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        An identity-code capture (demultiplex first: :func:`~flexvox_core.reconstruct.as_identity_capture`).
        A NaN or infinite value raises ``ValueError`` naming the frame.
    code : ndarray, shape (m, n, K), bool
        Its identity code. Partial tiles at the borders are fine.
    tensor : (float, float, float), keyword-only
        ``(cx, cy, ct) >= 0``, not all zero. Only ``time · c`` matters.
    time : float, keyword-only
        Diffusion time n > 0: Gaussian σᵢ = sqrt(2·n·cᵢ) (see :func:`sigmas`).
    solver : {"nc", "explicit", "steady"}, keyword-only
        See the module notes.
    keep_samples : bool, keyword-only
        Write measured voxels back exactly (``nc`` only; the others never move them).
    init : {"nc", "mean"}, keyword-only
        Starting volume of ``explicit`` (and ``steady``).
    dtype : float32 or float64, keyword-only
        Working and output precision.
    missing : ndarray (F,) bool, keyword-only, optional
        Frames the camera dropped: their rows hold no samples and are left out of the mask
        (their sub-frames are filled like any unsampled voxel; :mod:`flexvox_core.gaps`).
    subframes : (s0, s1), keyword-only, optional
        Compute only sub-frames [s0, s1) (``nc`` only): the same values up to float rounding,
        at the cost of those sub-frames and the ones the time kernel reaches from them (a
        streaming run wants one frame of a short window, :mod:`flexvox_core.motion.streaming`).

    Returns
    -------
    video : ndarray, shape (F·K, H, W), ``dtype`` (``(s1 - s0, H, W)`` with ``subframes``)
        Within ``[min(frames), max(frames)]`` (of the frames not missing).

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import capture, code_from_order
    >>> code = code_from_order([[0, 2], [3, 1]])
    >>> video = np.full((8, 6, 6), 0.25, dtype=np.float32)
    >>> out = diffuse(capture(video, code), code, tensor=(1, 1, 1), time=1.0)
    >>> out.shape, bool(np.all(out == 0.25))
    ((8, 6, 6), True)
    """
    f = check_frames(frames)
    c = check_identity_code(code)
    tens = check_tensor(tensor)
    t = _check_time(time)
    if solver not in SOLVERS:
        raise ValueError(f"`solver` must be one of {', '.join(SOLVERS)}; got {solver!r}")
    if init not in ("nc", "mean"):
        raise ValueError(f"`init` must be 'nc' or 'mean'; got {init!r}")
    dt = check_dtype(dtype)
    sig = sigmas(tens, t)
    missing = as_missing(missing, f.shape[0])
    present = None if missing is None else ~missing
    if solver == "explicit" and math.ceil(t * 2.0 * sum(tens) - 1e-9) > MAX_EXPLICIT_STEPS:
        raise ValueError(
            f"`time` {t:g} with `tensor` {tensor!r} needs {math.ceil(t * 2.0 * sum(tens))} explicit "
            f"steps (time · 2·Σc), more than {MAX_EXPLICIT_STEPS}; scale the tensor down (only "
            "time · c matters) or use solver='nc'"
        )
    if subframes is not None:
        S = f.shape[0] * c.shape[2]
        try:
            s0, s1 = (int(v) for v in subframes)
        except (TypeError, ValueError):
            raise ValueError(f"`subframes` must be two whole numbers (s0, s1) or None; got {subframes!r}") from None
        if not 0 <= s0 < s1 <= S:
            raise ValueError(f"`subframes` must satisfy 0 <= s0 < s1 <= {S} (the clip's sub-frames); got {subframes!r}")
        if solver != "nc":
            raise ValueError(f"`subframes` needs solver='nc'; got solver={solver!r}")
        return _nc_rows(f, c, sig, bool(keep_samples), dt, present, (s0, s1))
    if solver == "nc":
        return _nc_kernel(f, c, sig, bool(keep_samples), dt, present)
    F, H, W = f.shape
    K = c.shape[2]
    samples = f.astype(dt, copy=False)
    if init == "nc":
        start = _nc_kernel(f, c, sig, True, dt, present)
        mask = _sample_mask(tiled_order(c, H, W), F, K)
    else:
        start, order = _sample_volume(f, c, dt)
        mask = _sample_mask(order, F, K)
    if present is not None:
        mask &= np.repeat(present, K)[:, None, None]
    if init != "nc":
        start[~mask] = captured(samples, missing).mean(dtype=np.float64)
    if solver == "explicit":
        return _explicit_kernel(start, mask, tens, t)
    return _steady_kernel(start, mask, tens)


def diffuse_where(frames, code, out: np.ndarray, where, *, tensor=DEFAULT_TENSOR, time: float = DEFAULT_TIME,
                  missing=None) -> np.ndarray:
    """``out[where] = diffuse(frames, code, tensor=tensor, time=time, missing=missing)[where]``, in place
    (``nc``, float32, samples kept), and ``out`` returned.

    ``where`` is a bool array of ``out``'s shape, or a volume read a band of sub-frames at a time: an object with
    that ``shape`` and a method ``band(s0, s1)`` giving sub-frames [s0, s1) as a bool array (e.g. motion-aware's
    speed classes, held a bit per voxel: :class:`~flexvox_core.motion.packed.PackedVolume`). Such an object may
    also hold the bits as ``packed``, a C-contiguous uint8 array ``(S, H, ⌈W/8⌉)``, each row's voxels 8 to a byte,
    the first in the highest bit (:func:`numpy.packbits`), as PackedVolume does.

    A tensor without spatial blur, (0, 0, ct), is computed at those voxels alone: the compiled time pass
    (:mod:`~flexvox_core.reconstruct.nc_time_kernel`) writes them into ``out`` and skips rows without one,
    so no volume is made (motion-aware's still voxels, :mod:`flexvox_core.motion.pipeline`; fresh memory
    is dear: a 640×480 × 240 volume costs 0.1–0.5 s of page faults); it reads ``packed`` bits as they are, and
    a ``where`` read by bands otherwise :data:`SELECT_BAND` sub-frames at a time. Any other tensor, or a voxel
    with no sample in reach, computes the whole volume and copies from it (a band of ``where`` at a time).
    """
    f = check_frames(frames)
    c = check_identity_code(code)
    sig = sigmas(check_tensor(tensor), _check_time(time))
    missing = as_missing(missing, f.shape[0])
    present = None if missing is None else ~missing
    shape = (f.shape[0] * c.shape[2], *f.shape[1:])
    if (not isinstance(out, np.ndarray) or out.shape != shape or out.dtype != np.float32
            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ValueError(f"`out` must be a writable C-contiguous float32 array of shape {shape}")
    if hasattr(where, "band") and not isinstance(where, np.ndarray):
        select = where
        got = tuple(where.shape)
    else:
        select = np.ascontiguousarray(where, dtype=bool)
        got = select.shape
    if got != shape:
        raise ValueError(f"`where` must have shape {shape}; got {got}")
    gx, gy, gt = (gaussian_kernel(v, np.float32) for v in sig)
    if gx is None and gy is None and gt is not None:
        samples = f if present is None else np.where(present[:, None, None], f, 0).astype(f.dtype, copy=False)
        if _nc_time_only(samples, c, sig[2], True, np.float32, present, out=out, select=select) is not None:
            return out
    whole = _nc_kernel(f, c, sig, True, np.float32, present)
    if isinstance(select, np.ndarray):
        np.copyto(out, whole, where=select)
        return out
    for s0 in range(0, shape[0], SELECT_BAND):
        s1 = min(shape[0], s0 + SELECT_BAND)
        np.copyto(out[s0:s1], whole[s0:s1], where=np.asarray(select.band(s0, s1), dtype=bool))
    return out


def nc_leave_one_out(frames, code, *, tensor=DEFAULT_TENSOR, time: float = DEFAULT_TIME, missing=None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`diffuse`'s ``nc`` and, for every sample, its **leave-one-out** estimate: the value the
    normalized convolution gives the sample's voxel from all the *other* samples, ``(N − c·y) / (D − c)``
    with N and D the blurred samples and mask there, y the sample and c the weight it gives itself (the
    kernel's centre, more at a reflecting border). How well a method predicts samples it did not see
    measures how well it fills the voxels it has no sample for (motion-aware's local choice,
    :mod:`flexvox_core.motion.local_choice`, uses oriented nc's, :mod:`flexvox_core.reconstruct.oriented_nc`,
    which equals this one for a guide without edges).

    Returns
    -------
    video : ndarray (F·K, H, W) float32
        As ``diffuse(frames, code, tensor=tensor, time=time, missing=missing)``.
    loo : ndarray (F, H, W) float32
        The leave-one-out estimate of each pixel's sample in each frame (an identity code samples each
        pixel once a frame); NaN where no other sample is in reach, and in missing frames.
    """
    f = check_frames(frames)
    c = check_identity_code(code)
    sig = sigmas(check_tensor(tensor), _check_time(time))
    missing = as_missing(missing, f.shape[0])
    loo = np.empty(f.shape, np.float32)
    video = _nc_kernel(f, c, sig, True, np.float32, None if missing is None else ~missing, loo=loo)
    return video, loo
