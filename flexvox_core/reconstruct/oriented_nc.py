r"""Oriented normalized convolution: isotropic ``nc`` whose spatial kernel follows the picture's edges.

Structure-adaptive normalized convolution (Pham, van Vliet & Schutte, "Robust fusion of irregularly
sampled data using adaptive normalized convolution", 2006). Isotropic normalized convolution with a
Gaussian of σ = 0.71 px and sub-frames (tensor (1, 1, 1), n = 0.25) fills a voxel from the samples
around it in every direction, across an edge as readily as along it. Here the spatial Gaussian at each
voxel is stretched along the local edge and squeezed across it:

.. math::

    \sigma_u = \sigma\,\frac{\alpha}{\alpha + A}, \qquad \sigma_v = \sigma\,\frac{\alpha + A}{\alpha},

u the direction of the gradient, v along the edge, A = (λ₁ − λ₂)/(λ₁ + λ₂) ∈ [0, 1] the anisotropy of the
structure tensor J = G_ρ * (∇(G_σp * I) ∇(G_σp * I)ᵀ) of a **guide** picture I (motion-aware passes its
high-TR reconstruction: a first estimate, sharp in time), α = 2. Where the guide has no dominant
direction (A ≈ 0) the kernel is isotropic ``nc``'s (the same weights up to a constant factor); the time
Gaussian is nc's, with reflecting ends. Unlike :func:`~flexvox_core.reconstruct.diffusion.diffuse`, a voxel
with no sample in reach keeps the ``fallback`` (nc gives it the nearest sample), and nothing is clipped (a
normalized convolution of the samples stays within their range anyway).

The kernels come from a bank: A is rounded to 0, ½ or 1 and the direction to one of 8 (22.5° apart), 17
kernels cut at 4 σ along their own axes (9×9 px). It serves as motion-aware's local-choice candidate
(docs/reconstruction.md, "The local choice"). The guide sets the direction only; it is not averaged in: the
estimate is a normalized convolution of the samples, within their range, and keeps them.

The sums run in a compiled kernel (:mod:`~flexvox_core.reconstruct.oriented_nc_kernel`, float32), one block of a
sub-frame per call (:data:`BLOCK_ROWS`: the structure tensor and the time blur are made around the voxels asked
for, not over the whole picture), at the voxels asked for; the tests compare it with a plain numpy form that
computes each kernel weight from the formula above (``tests/flexvox_core/reconstruct/oriented_reference.py``).

References
----------
T. Q. Pham, L. J. van Vliet, K. Schutte, "Robust fusion of irregularly sampled data using adaptive normalized
convolution", EURASIP J. Adv. Signal Process. 2006, 083268.
J. Bigün, G. H. Granlund, "Optimal orientation detection of linear symmetry", ICCV 1987, pp. 433–438.
H. Knutsson, C.-F. Westin, "Normalized and differential convolution: methods for interpolation and filtering of
incomplete and uncertain data", CVPR 1993, pp. 515–523.
"""

from __future__ import annotations

import math
import threading

import cv2
import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.gaps import as_missing
from flexvox_core.reconstruct._common import check_frames, check_identity_code
from flexvox_core.reconstruct.diffusion import NC_MIN_WEIGHT, TRUNCATE, gaussian_kernel, time_weights
from flexvox_core.slopes import cv_radius
from flexvox_core.threads import for_each

SIGMA = math.sqrt(0.5)
"""Spatial and temporal standard deviation of the isotropic kernel (px, sub-frames): nc's at n = 0.25."""
ALPHA = 2.0
"""How far the kernel stretches: at A = 1 it is 1.5 σ along the edge and σ/1.5 across it. A stronger
stretch (α = 1) helps smooth natural scenes a little and costs still texture; a weaker one (α = 3) gains
less everywhere (as motion-aware's candidate, on ``flexvox bench``'s captures)."""
LEVELS = (0.0, 0.5, 1.0)
"""Anisotropy levels of the kernel bank (A is rounded to the nearest)."""
ANGLES = 8
"""Directions of the kernel bank, over 180° (the compiled kernel's sector comparisons are written for 8)."""
PRE_SIGMA = 0.7
"""The guide is blurred by this (px) before its gradient is taken."""
RHO = 1.0
"""The gradient products are averaged over this (px): the structure tensor's scale."""
_PAD = cv_radius(PRE_SIGMA) + 1 + cv_radius(RHO) + 2
"""Rows of guide around the wanted ones that the structure tensor reads (the blur, Sobel's row and the
averaging), and 2 to spare: the wanted rows' tensor is the whole picture's."""
_STRUCTURE_TAPS = tuple(np.ascontiguousarray(cv2.getGaussianKernel(2 * cv_radius(s) + 1, s, ktype=cv2.CV_32F).ravel())
                        for s in (PRE_SIGMA, RHO))
"""The float32 taps ``cv2.GaussianBlur`` uses on a float32 picture for :data:`PRE_SIGMA` and :data:`RHO` (7 and 9):
the structure tensor's blurs (:func:`structure`)."""
_LOW, _HIGH = (LEVELS[0] + LEVELS[1]) / 2, (LEVELS[1] + LEVELS[2]) / 2
"""Where the anisotropy rounds up to the next level."""
_TAN = math.tan(math.pi / ANGLES)
"""The doubled angle's sector edges are at ±22.5°, ±67.5°, … from the axes: this is their slope."""


def kernel_bank(sigma: float = SIGMA, alpha: float = ALPHA) -> np.ndarray:
    """The spatial kernels (1 + 8·2, 2h + 1, 2h + 1) float32: index 0 isotropic, then for each anisotropy level
    above 0 the 8 directions of the gradient (0°, 22.5°, … from the x axis). Each is 1 in its centre and cut,
    as nc cuts its Gaussians, at ``TRUNCATE`` standard deviations along its own axes (rounded as nc's
    radius): the isotropic one is nc's spatial kernel up to a constant factor."""
    big = int(math.ceil(TRUNCATE * sigma * (alpha + LEVELS[-1]) / alpha)) + 2
    y, x = np.mgrid[-big:big + 1, -big:big + 1].astype(np.float64)
    out = [kernel_weights(x, y, sigma, alpha, level, k * math.pi / ANGLES)
           for level in LEVELS for k in range(ANGLES if level > 0 else 1)]
    bank = np.asarray(out)
    used = np.flatnonzero(bank.any(axis=(0, 1)))
    half = int(max(abs(used[0] - big), abs(used[-1] - big)))
    return np.ascontiguousarray(bank[:, big - half:big + half + 1, big - half:big + half + 1], np.float32)


def kernel_weights(dx, dy, sigma: float, alpha: float, level: float, theta: float):
    """The weight of offsets (dx, dy) px (arrays or numbers) in the kernel of anisotropy ``level`` whose
    gradient direction is ``theta`` (radians from x): a Gaussian of σ·α/(α + A) along the gradient and
    σ·(α + A)/α along the edge, 0 beyond ``TRUNCATE`` standard deviations on either axis."""
    su, sv = sigma * alpha / (alpha + level), sigma * (alpha + level) / alpha
    u = np.asarray(dx, np.float64) * math.cos(theta) + np.asarray(dy, np.float64) * math.sin(theta)
    v = -np.asarray(dx, np.float64) * math.sin(theta) + np.asarray(dy, np.float64) * math.cos(theta)
    g = np.exp(-0.5 * ((u / su) ** 2 + (v / sv) ** 2))
    eps = 1e-9  # a tap on the box's edge stays in, whatever the rounding of the rotation
    return np.where((np.abs(u) > int(TRUNCATE * su + 0.5) + eps) | (np.abs(v) > int(TRUNCATE * sv + 0.5) + eps),
                    0.0, g)


def structure(guide: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The structure tensor's entries (3, H, W) float32 — J_xx, J_xy, J_yy — of one guide picture (H, W),
    into ``out`` if given: the guide blurred by :data:`PRE_SIGMA`, Sobel's derivatives (⅛ of them), their products
    blurred by :data:`RHO`, with reflecting borders: OpenCV's filters and taps, compiled and fused
    (:func:`~flexvox_core.reconstruct.oriented_nc_kernel.structure_block`; the tests compare it with OpenCV's)."""
    from flexvox_core.reconstruct.oriented_nc_kernel import structure_block

    g = np.ascontiguousarray(guide, np.float32)
    shape = (3, *g.shape)
    if out is None:
        out = np.empty(shape, np.float32)
    if out.shape != shape:
        raise ValueError(f"`out` must have shape {shape}; got {out.shape}")
    if out.dtype == np.float32 and out.flags.c_contiguous and out.flags.writeable:
        structure_block(g, *_STRUCTURE_TAPS, out, 0, 0)
    else:
        j = np.empty(shape, np.float32)
        structure_block(g, *_STRUCTURE_TAPS, j, 0, 0)
        out[...] = j
    return out


def bank_index(jxx, jxy, jyy) -> np.ndarray:
    """The kernel (index into :func:`kernel_bank`) for structure-tensor entries (arrays of one shape).

    The anisotropy A = √((J_xx − J_yy)² + 4 J_xy²) / (J_xx + J_yy) rounds to the nearest of :data:`LEVELS`
    (0 at no gradient, or where the entries are not finite); the gradient's direction
    θ = ½ atan2(2 J_xy, J_xx − J_yy) to the nearest multiple of 22.5°, found by comparing the doubled angle
    with the sectors' edges (the compiled kernel makes the same comparisons)."""
    jxx, jxy, jyy = (np.asarray(v, np.float64) for v in (jxx, jxy, jyy))
    with np.errstate(invalid="ignore", over="ignore"):  # inf − inf and the like: NaN, then level 0
        a, b, trace = jxx - jyy, 2 * jxy, jxx + jyy
        spread2 = a * a + b * b
        level = np.where(spread2 <= (_HIGH * trace) ** 2, 1, 2)
        level = np.where(~(trace > 0) | ~(spread2 > (_LOW * trace) ** 2), 0, level)
        ax, by = np.abs(a), np.abs(b)
        angle = np.select([by <= _TAN * ax, ax <= _TAN * by, a > 0],
                          [np.where(a >= 0, 0, 4), np.where(b > 0, 2, 6), np.where(b > 0, 1, 7)],
                          np.where(b > 0, 3, 5))
    return np.where(level == 0, 0, 1 + (level - 1) * ANGLES + angle)


def check_inputs(frames, code, guide, where, fallback, missing, subframes=None):
    """The checked (frames, code, guide, where, missing) of :func:`oriented_nc` (see there); ``where`` an array or
    a volume read by bands (its bands' type is checked as they are read), the guide's values checked at
    ``subframes`` (s0, s1) alone when given."""
    f = check_frames(frames)
    c = check_identity_code(code)
    F, H, W = f.shape
    S = F * c.shape[2]
    g = np.asarray(guide)
    if g.dtype not in (np.float16, np.float32):  # float16 is read a plane at a time as float32 (no float32 copy)
        g = g.astype(np.float32)
    if g.shape != (S, H, W):
        raise ValueError(f"`guide` must be the (S, H, W) = {(S, H, W)} video whose edges orient the kernel; "
                         f"got {g.shape}")
    s0, s1 = _check_subframes(subframes, S)
    bad = _not_finite(g, s0, s1)
    if bad.any():
        raise ValueError(f"`guide` sub-frame {s0 + int(np.argmax(bad))} holds NaN or infinite values")
    if where is not None:
        if not (isinstance(where, np.ndarray) or hasattr(where, "band")):
            where = np.asarray(where)
        if tuple(where.shape) != (S, H, W) or (isinstance(where, np.ndarray) and where.dtype != bool):
            raise ValueError(f"`where` must be a bool (S, H, W) = {(S, H, W)} array; got "
                             f"{getattr(where, 'dtype', 'a volume of')} {tuple(where.shape)}")
    if fallback is not None and np.shape(fallback) != (S, H, W):
        raise ValueError(f"`fallback` must be an (S, H, W) = {(S, H, W)} array; got {np.shape(fallback)}")
    return f, c, g, where, as_missing(missing, F)


def _not_finite(guide: np.ndarray, s0: int, s1: int) -> np.ndarray:
    """(s1 − s0,) bool: which of the guide's sub-frames s0 to s1 hold a NaN or an infinite value (no boolean
    plane made; the sub-frames side by side)."""
    bad = np.zeros(s1 - s0, bool)

    def finite(i):
        plane = guide[s0 + i]
        if plane.dtype == np.float16:  # NaN and ±inf have every exponent bit set: 3x faster than a float64 sum
            bad[i] = (plane.view(np.uint16) & 0x7C00).max() == 0x7C00
        else:
            bad[i] = not np.isfinite(plane.sum(dtype=np.float64))

    for_each(finite, s1 - s0)
    return bad


def _as_float32(block: np.ndarray) -> np.ndarray:
    """``block`` (h, w) of the guide as a C-contiguous float32 array: float16 by OpenCV where it is at least 2×2
    (``cv2.multiply`` by 1 into float32: the CPU's conversion instructions, 0.13 against numpy's 1.0 ns a value;
    every float16 value is a float32 one, so the same values, tested on all of them), numpy otherwise (OpenCV reads
    a 1×1 array as a number)."""
    if block.dtype == np.float16 and min(block.shape) >= 2:
        return cv2.multiply(block, 1.0, dtype=cv2.CV_32F)
    return np.ascontiguousarray(block, np.float32)


def _check_subframes(subframes, S: int) -> tuple[int, int]:
    if subframes is None:
        return 0, S
    try:
        s0, s1 = (int(v) for v in subframes)
        ok = all(int(v) == v and not isinstance(v, bool) for v in subframes) and 0 <= s0 < s1 <= S
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"`subframes` must be (s0, s1), whole numbers with 0 <= s0 < s1 <= {S}; got {subframes!r}")
    return s0, s1


BLOCK_ROWS = 64
"""A sub-frame's wanted voxels are estimated a band of this many rows at a time, each band over the columns
from its first wanted voxel to its last: the structure tensor and the time blur are made there alone (and
:data:`_PAD` px around), not over whole rows."""
ALIGN = 32
"""A block's structure tensor is made over columns from a multiple of this to one (or to the picture's right
edge), so that successive bands over nearly the same columns make one block (:func:`_blocks`). The tensor's values
do not depend on the span (:func:`~flexvox_core.reconstruct.oriented_nc_kernel.structure_block`): 1, 8 and 32
took the same time on the 1-s balls clip."""


def _blocks(wanted: np.ndarray) -> list[tuple[int, int, int, int]]:
    """(y0, y1, x0, x1) of each band of :data:`BLOCK_ROWS` rows of ``wanted`` (H, W) bool that holds a wanted
    voxel: its first and last wanted rows and columns (ends excluded); successive bands over the same aligned
    columns (:func:`_aligned_columns`) are one block."""
    from flexvox_core.reconstruct.oriented_nc_kernel import band_spans

    H, W = wanted.shape
    wanted = np.ascontiguousarray(wanted, bool)
    spans = np.empty((-(-H // BLOCK_ROWS), 4), np.int64)
    band_spans(wanted, wanted[:, :W // 8 * 8].view(np.uint64), BLOCK_ROWS, spans)  # compiled: no GIL held
    out: list[tuple[int, int, int, int]] = []
    for y0, y1, x0, x1 in spans.tolist():
        if y0 < 0:
            continue
        if out and _aligned_columns(*out[-1][2:], W) == _aligned_columns(x0, x1, W):
            # the same columns as the band above: one block (no rows of tensor made twice at their seam)
            p0, _, p2, p3 = out[-1]
            out[-1] = (p0, y1, min(p2, x0), max(p3, x1))
        else:
            out.append((y0, y1, x0, x1))
    return out


def _aligned_columns(x0: int, x1: int, W: int) -> tuple[int, int]:
    """The columns a block's structure tensor is made over: [x0, x1) and :data:`_PAD` px around, widened to
    multiples of :data:`ALIGN` (or the picture's edges)."""
    a0 = max(0, x0 - _PAD) // ALIGN * ALIGN
    a1 = min(W, -(-(x1 + _PAD) // ALIGN) * ALIGN)
    return a0, a1


def oriented_nc(frames, code, guide, *, where=None, fallback=None, missing=None, out=None, subframes=None, loo=None,
                workspace: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The oriented normalized convolution of an identity-code capture, and each sample's leave-one-out estimate.

    Parameters
    ----------
    frames : ndarray (F, H, W)
    code : ndarray (m, n, K), identity code
    guide : ndarray (F·K, H, W)
        The picture whose structure orients the kernel at each voxel (finite values); float16 is read a band of
        rows at a time as float32, any other dtype converted to float32 whole.
    where : ndarray (F·K, H, W) bool, or a volume read by bands, optional
        The voxels to estimate (default: all); elsewhere the result is ``fallback``.
    fallback : ndarray (F·K, H, W), or a volume read by bands, optional
        The values outside ``where`` and where no sample is in reach (default: NaN).
    missing : ndarray (F,) bool, optional
        Dropped frames: they hold no samples.
    out : ndarray (s1 − s0, H, W) float32 C-contiguous, optional
        Where the video goes (a volume the caller no longer needs: no fresh memory); it must not share
        memory with the other inputs.
    subframes : (s0, s1), optional
        Estimate these sub-frames alone (default: all, (0, F·K)): the video returned is theirs, equal to the
        whole one's ``[s0:s1]``; ``where`` and ``fallback`` are read over them alone
        (:func:`~flexvox_core.planes.band`).
    loo : ndarray (F, H, W) float32 C-contiguous, optional
        Where the leave-one-out estimates go (default: a new array of NaN); only the samples of the frames these
        sub-frames belong to are written.
    workspace : list, optional
        Where the planes each thread works in are kept for the next call (pass one list to the calls on
        ``subframes`` of one video: fresh planes cost page faults each call); empty at first.

    Returns
    -------
    video : ndarray (s1 − s0, H, W) float32 (``out`` when given)
        Samples kept exactly; each estimate is a weighted mean of samples, so within their range.
    loo : ndarray (F, H, W) float32 (``loo`` when given)
        At each sample whose voxel is in ``where``, its leave-one-out estimate (N − c·y)/(D − c), c the weight
        it gives itself (as :func:`~flexvox_core.reconstruct.diffusion.nc_leave_one_out`); NaN elsewhere,
        where no other sample is in reach, and in missing frames.
    """
    from flexvox_core.planes import band

    plan = OrientedNc(frames, code, guide, where=where, fallback=fallback, missing=missing, subframes=subframes)
    s0, s1 = _check_subframes(subframes, plan.S)
    chosen = None if plan.where is None else band(plan.where, s0, s1)
    fall = None if plan.fallback is None else band(plan.fallback, s0, s1)
    return plan.run(s0, s1, chosen, fall, out=out, loo=loo, workspace=workspace)


class OrientedNc:
    """:func:`oriented_nc`'s checked inputs and the constants its sums read (the kernel bank, the time weights, the
    code's slots), made once for the calls on bands of sub-frames of one video (:meth:`run`): motion-aware's local
    choice calls it a band at a time. The arguments are :func:`oriented_nc`'s; the guide's values are checked at
    ``subframes`` alone (default: all)."""

    def __init__(self, frames, code, guide, *, where=None, fallback=None, missing=None, subframes=None) -> None:
        from flexvox_core.reconstruct.oriented_nc_kernel import dense_bank, tap_lists

        f, c, g, where, missing = check_inputs(frames, code, guide, where, fallback, missing, subframes)
        F, H, W = f.shape
        K = c.shape[2]
        self.frames, self.guide, self.where, self.fallback = frames, g, where, fallback
        self.S, self.K = F * K, K
        self.present = np.ones(F, bool) if missing is None else ~missing
        gt = gaussian_kernel(SIGMA, np.float64)
        weight, self.first = time_weights(gt, K, F, None if missing is None else ~missing)
        self.weight = weight.astype(np.float32)
        self.floor = NC_MIN_WEIGHT * float(gt.max())
        bank = kernel_bank()
        self.offsets, weights, self.counts = tap_lists(bank)
        self.weights = weights.astype(np.float32)
        self.dense = dense_bank(bank)
        self.h = bank.shape[1] // 2
        self.order = tiled_order(c, min(H, c.shape[0]), W).astype(np.int64)  # repeats every m rows
        self.samples = np.ascontiguousarray(f, dtype=np.float32)

    def run(self, s0: int, s1: int, chosen, fall, *, out=None, loo=None, workspace: list | None = None,
            fill: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Sub-frames ``s0`` to ``s1`` (checked by the caller): ``chosen`` and ``fall`` their ``where`` and
        ``fallback`` (arrays (s1 − s0, H, W), or None), ``out``, ``loo`` and ``workspace`` as :func:`oriented_nc`'s.
        ``fill=False`` (``chosen`` and ``fall`` given): ``out`` is written at the ``chosen`` voxels alone, the
        fallback's value where no estimate is made; elsewhere it keeps what it held (a reader of the chosen voxels
        alone need not have the fallback copied whole)."""
        from flexvox_core.reconstruct.oriented_nc_kernel import ROW, oriented_plane, structure_block

        F, H, W = self.samples.shape
        K = self.K
        n = s1 - s0
        g, samples, weight, first, present_f = self.guide, self.samples, self.weight, self.first, self.present
        if not fill and (chosen is None or fall is None):
            raise ValueError("`fill=False` needs the voxels to estimate and a fallback")
        if out is not None:
            if (not isinstance(out, np.ndarray) or out.shape != (n, H, W) or out.dtype != np.float32
                    or not out.flags.c_contiguous or not out.flags.writeable
                    or any(np.may_share_memory(out, a) for a in (self.frames, g, chosen, fall)
                           if isinstance(a, np.ndarray))):
                raise ValueError(f"`out` must be a writable C-contiguous float32 array of shape {(n, H, W)} that "
                                 "shares no memory with the other inputs")
            video = out
        else:
            video = np.empty((n, H, W), np.float32)
        if loo is None:
            loo = np.full((F, H, W), np.nan, np.float32)
        elif (not isinstance(loo, np.ndarray) or loo.shape != (F, H, W) or loo.dtype != np.float32
              or not loo.flags.c_contiguous or not loo.flags.writeable):
            raise ValueError(f"`loo` must be a writable C-contiguous float32 array of shape {(F, H, W)}")
        if chosen is not None and chosen.dtype != bool:
            raise ValueError(f"`where` must be a bool (S, H, W) = {(F * K, H, W)} array; its sub-frames {s0} to {s1} "
                             f"are {chosen.dtype}")
        everywhere = np.ones((H, W), bool) if chosen is None else None
        # Planes a thread works in, taken from the pool and given back (fresh memory costs page faults every time).
        pool = [] if workspace is None else workspace
        lock = threading.Lock()

        def one(i):
            s = s0 + i
            if not fill:
                pass  # the chosen voxels take the fallback's value in the kernel where no estimate is made
            elif fall is None:  # each sub-frame starts as the fallback, on the thread that estimates it
                video[i].fill(np.nan)
            else:
                np.copyto(video[i], fall[i], casting="unsafe")
            wanted = everywhere if chosen is None else chosen[i]
            blocks = _blocks(wanted)
            if not blocks:
                return
            with lock:
                planes = pool.pop() if pool else None
            if planes is None or planes[0].shape != (3, H, W):  # the time-blurred planes start finite (zeros)
                planes = (np.zeros((3, H, W), np.float32), np.zeros(H * W + ROW, np.float32),
                          np.zeros(H * W + ROW, np.float32))
            j, vt, mt = planes
            fallback = video[i] if fill else fall[i]
            for y0, y1, x0, x1 in blocks:
                b0, b1 = max(0, y0 - _PAD), min(H, y1 + _PAD)
                a0, a1 = _aligned_columns(x0, x1, W)
                structure_block(_as_float32(g[s, b0:b1, a0:a1]), *_STRUCTURE_TAPS, j, b0, a0)
                oriented_plane(samples, self.order, weight[s], int(first[s]), s % K, s // K, bool(present_f[s // K]),
                               j, wanted, self.dense, self.offsets, self.weights, self.counts, self.h, self.floor,
                               y0, y1, x0, x1, vt, mt, video[i], fallback, loo, _LOW, _HIGH, _TAN)
            with lock:
                pool.append(planes)

        for_each(one, n)
        return video, loo
