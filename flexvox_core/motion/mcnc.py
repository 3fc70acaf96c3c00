r"""Motion-compensated normalized convolution: the one-pass form of Eq. 3 with the field of Eq. 4.

Normalized convolution (Knutsson & Westin 1993) blurs the sampled values and divides by the
blurred sampling mask. Here the blur follows each voxel's trajectory: to estimate I(x, t),
samples of sub-frame t + d are read at x + d·(u, v) (the flow at (x, t), a straight
trajectory), weighted by the Gaussian of Eq. 3 along λ,

.. math::

    w_d = \exp\left(-\frac{d^2 (1 + u^2 + v^2)}{4 n c_1}\right),

(the step d·(u, v, 1) has length d·|(u, v, 1)|), then blurred in space with variance
2 n c2 for the directions across λ (isotropic: exact for c2 = c3 and zero flow). Where
the blurred mask is too small to trust (no sample nearby), ``fallback`` fills in.

References
----------
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Flexible voxels for motion-aware videography",
ECCV 2010 (the paper).
H. Knutsson, C.-F. Westin, "Normalized and differential convolution: methods for interpolation and filtering of
incomplete and uncertain data", CVPR 1993, pp. 515–523.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from flexvox_core.motion.gather_weights import CUTOFF
from flexvox_core.motion.subframes import flow_at, sample_planes, sampling_period
from flexvox_core.motion.tensors import DEFAULT_C, check_c
from flexvox_core.planes import band
from flexvox_core.reconstruct.diffusion import self_weights
from flexvox_core.threads import for_each


def motion_compensated_nc(
    sparse,
    mask,
    flow,
    *,
    c=DEFAULT_C,
    time: float = 2.0,
    fallback=None,
    keep_samples: bool = True,
    max_reach: int | None = None,
    still=None,
    still_value=None,
    gathered=None,
    loo: np.ndarray | None = None,
    wide=None,
    wide_sigma: float = 0.0,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Reconstruct a video from samples along the flow's trajectories.

    Parameters
    ----------
    sparse : ndarray, shape (S, H, W)
        Sampled values at their voxels (0 elsewhere), see :func:`flexvox_core.forward.sparse_volume`.
    mask : ndarray of bool, shape (S, H, W)
    flow : ndarray, shape (S, H, W, 2)
    c : (c1, c2, c3)
    time : float
        Diffusion time n > 0 of Eq. 3.
    fallback : ndarray (S, H, W), optional
        Used where the weights are below :data:`~flexvox_core.motion.gather_weights.MIN_WEIGHT` (default: the
        sparse value).
    keep_samples : bool
        Keep measured voxels exactly.
    max_reach : int, optional
        Largest |d| in sub-frames (default: the larger of 3 standard deviations of the static
        case and the sampling period K, at most S-1).
    still, still_value : ndarray (S, H, W), optional
        Voxels not to gather (bool) and their value (at zero flow this function computes the
        fixed-tensor normalized convolution with ``diag(c3, c2, c1)``; ``motion_aware`` passes
        its still and slow voxels' own values). The trajectory gather then runs only over the
        other voxels and their neighbours within the spatial blur's reach, as a list — that is
        where the time goes (a still scene costs almost nothing).
    gathered : ndarray of bool (S, H, W), optional
        The voxels to gather, given instead of ``still`` (its complement; ``still_value`` then goes with it):
        the same result without a volume of the complement (``motion_aware`` holds the gathered voxels).
    loo : ndarray (F, H, W) float32, optional
        Filled, at every sample the gather reaches (its voxel not in ``still``), with the sample's
        **leave-one-out** estimate: the gather's value there from all the *other* samples,
        (N − c·y) / (D − c), c the weight the sample gives itself (1 along the trajectory times the
        spatial blur's centre). F = S / K frames of K sub-frames; a sub-frame's samples go to its
        frame's plane (each pixel is sampled once a frame). Other pixels are left as they are.
        :mod:`~flexvox_core.motion.local_choice` compares it with oriented nc's.
    wide, wide_sigma : sequence of (H, W) weights or None per sub-frame, float
        Noise-aware smoothing (:mod:`~flexvox_core.motion.noise_aware`): the spatial blur at a voxel is
        the mixture (1 − g)·Gaussian(σ) + g·Gaussian(``wide_sigma``), g = ``wide[t]`` (None: g = 0),
        for the numerator and the weights alike (a normalized convolution still).
    out : ndarray (S, H, W) float32, optional
        Where the result goes (returned); may be ``still_value`` itself, each of whose sub-frames is read
        before that sub-frame is written (``motion_aware`` passes its still voxels' volume when it needs it
        no more: one volume less, and fresh memory is dear).
    """
    c1, c2, _ = check_c(c)
    vals = np.asarray(sparse, dtype=np.float32)
    m = np.asarray(mask, dtype=bool)
    f = np.asarray(flow, dtype=np.float32)
    if vals.ndim != 3 or m.shape != vals.shape or f.shape != (*vals.shape, 2):
        raise ValueError(f"`sparse` (S, H, W), `mask` and `flow` (S, H, W, 2) must match; got "
                         f"{vals.shape}, {m.shape}, {f.shape}")
    if not math.isfinite(time) or time <= 0:
        raise ValueError(f"`time` must be a finite number > 0; got {time!r}")
    S, H, W = vals.shape
    if not np.isfinite(f.sum(dtype=np.float64)):  # one pass, no (S, H, W, 2) temporary
        f = np.where(np.isfinite(f), f, 0).astype(np.float32)
    reach = default_reach(time, c1, sampling_period(m), S) if max_reach is None else max(0, min(int(max_reach), S - 1))
    sig_space = math.sqrt(2 * time * c2)
    # Value·mask and mask as separate planes (two one-channel remaps cost a third of one
    # two-channel remap, and interpolate exactly: see :mod:`~flexvox_core.motion.longreach`).
    value, weight = sample_planes(vals, m)
    if still is not None and gathered is not None:
        raise ValueError("`still` and `gathered` say the same (one is the other's complement): give one")
    invert = gathered is None  # `select` holds the voxels not gathered
    select = still if invert else gathered
    if (select is None) != (still_value is None):
        raise ValueError("`still` and `still_value` go together" if invert else
                         "`gathered` and `still_value` go together")
    if select is not None:
        select = np.asarray(select, dtype=bool)
        still_value = np.asarray(still_value, dtype=np.float32)
        if select.shape != vals.shape or still_value.shape != vals.shape:
            raise ValueError(f"`{'still' if invert else 'gathered'}` and `still_value` must have shape {vals.shape}")
    if loo is not None and (loo.ndim != 3 or loo.shape[1:] != (H, W) or not len(loo) or S % len(loo)):
        raise ValueError(f"`loo` must be (F, H, W) with F dividing the {S} sub-frames; got {loo.shape}")
    if out is None:
        out = np.empty((S, H, W), np.float32)
    elif not isinstance(out, np.ndarray) or out.shape != vals.shape or out.dtype != np.float32:
        raise ValueError(f"`out` must be a float32 array of shape {vals.shape}")
    elif np.may_share_memory(out, vals) or (fallback is not None and np.may_share_memory(out, fallback)):
        raise ValueError("`out` must not share memory with `sparse` or `fallback`")
    if wide is not None and (len(wide) != S or not (math.isfinite(wide_sigma) and wide_sigma > 0)):
        raise ValueError(f"`wide` must give a weight plane or None for each of the {S} sub-frames, and "
                         f"`wide_sigma` must be > 0; got {len(wide)} and {wide_sigma!r}")

    def sums(t, box, near):
        ys, xs = np.nonzero(near)
        ys += box[0].start
        xs += box[1].start
        ys, xs, num, den = _gather_list(t, ys, xs, value, weight, f, reach, time, c1)
        planes = np.zeros((2, *near.shape), np.float32)
        planes[0, ys - box[0].start, xs - box[1].start] = num
        planes[1, ys - box[0].start, xs - box[1].start] = den
        return planes

    def samples_of(t):
        return m[t], vals[t]

    return _gather(S, H, W, sums, samples_of, select=select, invert=invert, still_value=still_value,
                   fallback=fallback, wide=wide, wide_sigma=wide_sigma, sig_space=sig_space, loo=loo, out=out,
                   keep_samples=keep_samples)


def trajectory_gather(frames, code, flow, *, missing=None, c=DEFAULT_C, time: float = 2.0, fallback,
                      gathered, still_value, loo: np.ndarray | None = None, wide=None, wide_sigma: float = 0.0,
                      max_reach: int | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """:func:`motion_compensated_nc` at the ``gathered`` voxels of an identity code's capture, read from the camera
    frames and the code (no sample volume, no mask volume): the same result but for the positions, which are
    read exactly here (OpenCV's remap rounds them to 1/32 px), as the GPU's gather reads them.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        Camera frames of the identity ``code`` (m, n, K); a dropped frame's values are not read.
    code : ndarray (m, n, K) bool
    flow : ndarray (F·K, H, W, 2)
        Or a volume read a sub-frame at a time (:class:`~flexvox_core.planes.Bands`), as ``gathered`` may
        be: each sub-frame reads its own plane of each, the flow only where it gathers.
    missing : ndarray (F,) bool, optional
        Dropped frames: their sub-frames hold no samples.
    c, time, fallback, gathered, still_value, loo, wide, wide_sigma, max_reach, out
        As :func:`motion_compensated_nc`'s (``gathered``, ``still_value`` and ``fallback`` required); the samples
        are kept. ``max_reach`` defaults to :func:`default_reach` of the sampling period S / (frames present).
    """
    from flexvox_core.forward import tiled_code, validate_code
    from flexvox_core.motion.mcnc_kernel import lattice_sums, reach_thresholds, slot_tables

    c1, c2, _ = check_c(c)
    code = validate_code(code)
    fr = np.ascontiguousarray(frames, dtype=np.float32)
    if fr.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {fr.shape}")
    F, H, W = fr.shape
    m, n, K = code.shape
    if (code.sum(axis=2) != 1).any():
        raise ValueError("`code` must be an identity code (each pixel open in one slot); demultiplex first")
    S = F * K
    # Arrays, or volumes made a sub-frame at a time (planes.band): each sub-frame reads its own plane alone.
    f = flow if hasattr(flow, "band") else np.asarray(flow, dtype=np.float32)
    if tuple(f.shape) != (S, H, W, 2):
        raise ValueError(f"`flow` must have shape {(S, H, W, 2)} (F·K sub-frames of the frames); got "
                         f"{tuple(f.shape)}")
    present = np.ones(F, bool) if missing is None else ~np.asarray(missing, bool)
    if present.shape != (F,):
        raise ValueError(f"`missing` must be ({F},) bool; got shape {present.shape}")
    if not math.isfinite(time) or time <= 0:
        raise ValueError(f"`time` must be a finite number > 0; got {time!r}")
    select = gathered if hasattr(gathered, "band") else np.asarray(gathered, dtype=bool)
    still_value = np.asarray(still_value, dtype=np.float32)
    if tuple(select.shape) != (S, H, W) or still_value.shape != (S, H, W) or np.shape(fallback) != (S, H, W):
        raise ValueError(f"`gathered`, `still_value` and `fallback` must have shape {(S, H, W)}")
    if loo is not None and loo.shape != (F, H, W):
        raise ValueError(f"`loo` must be (F, H, W) = {(F, H, W)}; got {loo.shape}")
    if out is None:
        out = np.empty((S, H, W), np.float32)
    elif not isinstance(out, np.ndarray) or out.shape != (S, H, W) or out.dtype != np.float32:
        raise ValueError(f"`out` must be a float32 array of shape {(S, H, W)}")
    elif np.may_share_memory(out, fallback):
        raise ValueError("`out` must not share memory with `fallback`")
    if wide is not None and (len(wide) != S or not (math.isfinite(wide_sigma) and wide_sigma > 0)):
        raise ValueError(f"`wide` must give a weight plane or None for each of the {S} sub-frames, and "
                         f"`wide_sigma` must be > 0; got {len(wide)} and {wide_sigma!r}")
    count = int(present.sum())
    period = S // count if count else S
    reach = default_reach(time, c1, period, S) if max_reach is None else max(0, min(int(max_reach), S - 1))
    row_hit, col_hit = slot_tables(code, H, W)
    slots = tiled_code(code, H, W)  # (K, H, W): a slot's samples, a sixteenth of a volume at K = 16
    none = np.zeros((H, W), bool)
    inv_4nc1 = np.float32(1 / (4 * time * c1))
    thresholds = reach_thresholds(reach)

    def sums(t, box, near):
        planes = np.empty((2, *near.shape), np.float32)
        flow_t = np.ascontiguousarray(band(f, t, t + 1)[0], np.float32)
        lattice_sums(fr, present, row_hit, col_hit, flow_t, np.ascontiguousarray(near), box[0].start, box[1].start,
                     t, S, inv_4nc1, reach, planes[0], planes[1], thresholds)
        return planes

    def samples_of(t):
        return (slots[t % K] if present[t // K] else none), fr[t // K]

    tile = np.argwhere(np.transpose(code, (2, 0, 1)))[:, 1:]  # slot k's pixel (i, j) of the tile

    def keep(t):  # a slot's samples: every m-th row's every n-th pixel from (i, j)
        if present[t // K]:
            i, j = tile[t % K]
            out[t, i::m, j::n] = fr[t // K, i::m, j::n]

    return _gather(S, H, W, sums, samples_of, select=select, invert=False, still_value=still_value,
                   fallback=fallback, wide=wide, wide_sigma=wide_sigma, sig_space=math.sqrt(2 * time * c2), loo=loo,
                   out=out, keep_samples=keep)


def _gather(S, H, W, sums, samples_of, *, select, invert, still_value, fallback, wide, wide_sigma, sig_space, loo,
            out, keep_samples):
    """The gather's frame around its sums, a sub-frame at a time on every core: the box of the voxels to gather
    and their neighbours within the spatial blur's reach, ``sums(t, box, near)`` (the unblurred (numerator,
    weight) planes of the box, 0 off ``near``), the blurs, the leave-one-out, the division and the fallback;
    ``samples_of(t)`` gives the sub-frame's (mask, values) planes (the samples kept, the leave-one-out's);
    ``keep_samples``: true (the samples written where the mask is), false, or ``keep_samples(t)`` writing them."""
    per_frame = S // len(loo) if loo is not None else 0
    # The spatial blur mixes in trajectories up to `pad` away: those are gathered in full too.
    pad = int(math.ceil(max(sig_space, wide_sigma if wide is not None else 0.0) * 4)) + 1
    kernel = np.ones((2 * pad + 1,) * 2, np.uint8)
    everything = np.ones((H, W), bool)

    def one(t):
        sel = None if select is None else band(select, t, t + 1)[0]
        moving = everything if sel is None else ~sel if invert else sel
        if select is not None and out is not still_value:
            out[t] = still_value[t]
        rows = np.flatnonzero(moving.any(axis=1))
        if len(rows):
            cols = np.flatnonzero(moving[rows[0]: rows[-1] + 1].any(axis=0))
            y0, y1 = max(0, rows[0] - pad), min(H, rows[-1] + 1 + pad)
            x0, x1 = max(0, cols[0] - pad), min(W, cols[-1] + 1 + pad)
            box = (slice(y0, y1), slice(x0, x1))
            inside = moving[box]
            near = inside if select is None else cv2.dilate(inside.view(np.uint8), kernel) > 0
            _finish(t, box, inside, sums(t, box, near), samples_of, wide, wide_sigma, sig_space, fallback,
                    loo[t // per_frame] if loo is not None else None, out)
        if callable(keep_samples):
            keep_samples(t)
        elif keep_samples:
            m_t, vals_t = samples_of(t)
            np.copyto(out[t], vals_t, where=m_t)

    for_each(one, S)
    return out


def _finish(t, box, inside, planes, samples_of, wide, wide_sigma, sig_space, fallback, loo_f, out):
    """Blur a box's sums, write its leave-one-out into ``loo_f`` (the frame's plane) and N / D (the fallback
    where D is tiny) at the voxels ``inside`` of ``out[t]`` (the last two steps compiled:
    :func:`~flexvox_core.motion.mcnc_kernel.divide_box`; ``tests/flexvox_core/motion/finish_reference.py`` holds
    them in numpy)."""
    from flexvox_core.motion.mcnc_kernel import divide_box

    g = _blur_box(t, box, planes, wide, wide_sigma, sig_space)

    h, w = inside.shape
    sampled, y, own_y, own_x, wide_y, wide_x = _NO_MASK, _NO_PLANE, _NO_LINE, _NO_LINE, _NO_LINE, _NO_LINE
    if loo_f is not None:
        m_t, vals_t = samples_of(t)
        sampled, y = m_t[box], vals_t[box]
        own_y, own_x = _self_weights(sig_space, h), _self_weights(sig_space, w)
        if g is not None:
            wide_y, wide_x = _self_weights(wide_sigma, h), _self_weights(wide_sigma, w)
    short = np.empty((h, w), bool)
    dst = out[t][box]
    count = divide_box(planes[0], planes[1], inside, sampled, y, own_y, own_x,
                       _NO_PLANE if g is None else np.asarray(g, np.float32), wide_y, wide_x,
                       _NO_PLANE if loo_f is None else loo_f[box], dst, short)
    if count:  # no weight to trust: the fallback
        np.copyto(dst, np.float32(0) if fallback is None else np.asarray(fallback[t][box], np.float32), where=short)


def _blur_box(t, box, planes, wide, wide_sigma, sig_space):
    """Blur a box's sums ``planes`` in place (:func:`_finish`); returns the wide kernel's weights g of the box
    (None without them)."""
    g = wide[t] if wide is not None else None
    if g is not None:
        g = g[box]
        broad = np.empty_like(planes)
        for plane, dst in zip(planes, broad, strict=True):
            cv2.GaussianBlur(plane, (0, 0), wide_sigma, dst=dst, borderType=cv2.BORDER_REFLECT)
    if sig_space > 0.05:  # neighbours outside `near` are beyond the blur's reach of `moving`
        for plane in planes:
            cv2.GaussianBlur(plane, (0, 0), sig_space, dst=plane, borderType=cv2.BORDER_REFLECT)
    if g is not None:  # the mixture of the two kernels, per voxel
        planes += g * (broad - planes)
    return g


_NO_MASK = np.zeros((0, 0), bool)
_NO_PLANE = np.zeros((0, 0), np.float32)
_NO_LINE = np.zeros(0)
"""Empty arrays: :func:`~flexvox_core.motion.mcnc_kernel.divide_box`'s arguments not given (one type each)."""


@functools.lru_cache(maxsize=256)
def _self_weights(sigma: float, length: int) -> np.ndarray:
    """:func:`~flexvox_core.reconstruct.diffusion.self_weights` of ``cv2.GaussianBlur``'s kernel for ``sigma`` (px)
    over ``length`` (float64; 1 without a blur, σ <= 0.05, as the gather skips it), kept: a box's sizes repeat."""
    if sigma <= 0.05:
        weights = np.ones(length)
    else:
        g = cv2.getGaussianKernel(int(round(sigma * 8 + 1)) | 1, sigma, cv2.CV_64F).ravel()
        weights = self_weights(g, length)
    weights.flags.writeable = False
    return weights


def default_reach(time: float, c1: float, period: int, S: int) -> int:
    """The gather's largest offset |d| (sub-frames): far enough for 3 standard deviations of the static case, and at
    least one sampling ``period`` (a pixel is sampled once every K sub-frames), so a still pixel always reaches its
    own samples; at most S − 1."""
    return max(0, min(max(math.ceil(3 * math.sqrt(2 * time * c1)), period), S - 1))


LIST_WIDTH = 4096
"""Voxel lists are gathered as rows of this many (cv2.remap takes maps up to 32767 wide)."""


def _rows(n: int):
    """A list's first ``n`` entries as (start, stop, 2-D shape) pieces: whole rows of
    :data:`LIST_WIDTH`, then the rest as one row."""
    full = n // LIST_WIDTH * LIST_WIDTH
    pieces = [(0, full, (full // LIST_WIDTH, LIST_WIDTH))] if full else []
    if n > full:
        pieces.append((full, n, (1, n - full)))
    return pieces


def reaches(e: np.ndarray, reach: int) -> np.ndarray:
    """Per voxel, the largest offset d <= ``reach`` whose trajectory weight ``e``^(d²) is at least
    :data:`CUTOFF` (0 where ``e`` <= CUTOFF)."""
    e64 = e.astype(np.float64)
    with np.errstate(divide="ignore"):
        d = np.floor(np.sqrt(math.log(CUTOFF) / np.log(np.minimum(e64, 1.0))))
    d = np.where(e64 <= CUTOFF, 0, np.minimum(d, reach))  # e = 1: log 0, d = inf -> reach
    return d.astype(np.int16)


def _gather_list(t, ys, xs, value, weight, f, reach, time, c1):
    """Normalized-convolution sums (numerator, weight) along the trajectories of the voxels
    (``ys``, ``xs``) of sub-frame ``t``, each gathered as far as its own trajectory weights stay
    above :data:`CUTOFF`. The voxels are ordered by that reach (longest first), so that each
    offset runs over a prefix of the list; returns (ys, xs, numerator, weight) in that order."""
    S = len(value)
    W = value[t].shape[1]
    flat = ys * W + xs
    u, v = flow_at(f[t], flat)
    # w_d = e^(d²) with e = exp(-(1 + u² + v²) / (4 n c1)): built by multiplication, since
    # d² is the sum of the first d odd numbers (no exp per offset).
    e = np.exp(-(1 + u * u + v * v) / np.float32(4 * time * c1)).astype(np.float32)
    r = reaches(e, reach)
    order = np.argsort(-r, kind="stable")
    ys, xs, flat, u, v, e, r = (a[order] for a in (ys, xs, flat, u, v, e, r))
    # count[d]: voxels that reach offset d (a prefix of the list).
    count = np.cumsum(np.bincount(r, minlength=reach + 1)[::-1])[::-1]
    acc_num = value[t].reshape(-1)[flat]  # d = 0, weight 1
    acc_den = weight[t].reshape(-1)[flat]
    e2 = e * e
    w = np.ones_like(e)
    step = e.copy()
    # Trajectory positions x ± d·(u, v), advanced in place.
    fwd_x, fwd_y = xs.astype(np.float32), ys.astype(np.float32)
    back_x, back_y = fwd_x.copy(), fwd_y.copy()
    num, den = np.empty_like(e), np.empty_like(e)
    for d in range(1, int(r[0]) + 1 if len(r) else 1):
        n = int(count[d])
        cv2.multiply(w[:n], step[:n], dst=w[:n])
        cv2.multiply(step[:n], e2[:n], dst=step[:n])
        cv2.add(fwd_x[:n], u[:n], dst=fwd_x[:n])
        cv2.add(fwd_y[:n], v[:n], dst=fwd_y[:n])
        cv2.subtract(back_x[:n], u[:n], dst=back_x[:n])
        cv2.subtract(back_y[:n], v[:n], dst=back_y[:n])
        for sd, mx, my in ((d, fwd_x, fwd_y), (-d, back_x, back_y)):
            if 0 <= t + sd < S:
                for a, b, shape in _rows(n):
                    maps = mx[a:b].reshape(shape), my[a:b].reshape(shape)
                    cv2.remap(value[t + sd], *maps, cv2.INTER_LINEAR, dst=num[a:b].reshape(shape),
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)
                    cv2.remap(weight[t + sd], *maps, cv2.INTER_LINEAR, dst=den[a:b].reshape(shape),
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0)
                cv2.accumulateProduct(num[:n], w[:n], acc_num[:n])
                cv2.accumulateProduct(den[:n], w[:n], acc_den[:n])
    return ys, xs, acc_num, acc_den
