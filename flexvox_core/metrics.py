r"""Image-quality metrics for reconstructed videos: PSNR and SSIM, averaged over frames or per frame.

:func:`psnr` and :func:`ssim` return one float, as scikit-image's do; :func:`psnr_per_frame` and
:func:`ssim_per_frame` return every frame's score. Both follow the convention of the video
snapshot-compressive-imaging literature (and of flexvox's benchmarks): frames are compared one by one,
with an explicit data range (1 for videos in [0, 1]), and the per-frame scores are averaged.

**Mixed dtypes.** An integer array against a float one (a uint16 ground truth against a reconstruction in
[0, 1]) is compared in [0, 1]: the integer one is divided by its dtype's largest value (uint8: 255, uint16:
65535), as ``skimage.util.img_as_float`` does for unsigned types, and ``data_range`` must be 1. Two integer
arrays or two float arrays are compared as they are, with the ``data_range`` given.

**Units.** A float array with values beyond ``[-L, 2L]`` (L the data range; 8-bit values in a float array at
the default ``data_range=1``) is refused, as are two float arrays that both lie in [0, 1] at a data range above 2
(``data_range=255`` for videos in [0, 1], which would add 20 log₁₀ L dB): each is another unit than the data
range says. The first is looked for on every fourth frame, row and column.

.. math::

    \mathrm{PSNR} = 10 \log_{10} \frac{L^2}{\mathrm{MSE}}, \qquad
    \mathrm{SSIM}(x, y) = \frac{(2\mu_x\mu_y + C_1)(2\sigma_{xy} + C_2)}
                               {(\mu_x^2 + \mu_y^2 + C_1)(\sigma_x^2 + \sigma_y^2 + C_2)}

SSIM is the Gaussian-window version of Wang et al. 2004 (σ = 1.5, C₁ = (0.01 L)²,
C₂ = (0.03 L)², population (not sample) covariances, window truncated at 3.5 σ, the map
averaged over the pixels at least half a window from the border) — the settings of
``skimage.metrics.structural_similarity(..., gaussian_weights=True, sigma=1.5,
use_sample_covariance=False)``. It is computed in float64.

References
----------
Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image quality assessment: from
error visibility to structural similarity", IEEE TIP 13(4), 2004.
"""

from __future__ import annotations

import logging
import warnings
from typing import NamedTuple

import numpy as np

from flexvox_core.numbers import positive_number

_logger = logging.getLogger(__name__)

__all__ = ["FrameScores", "clip_psnr", "psnr", "psnr_per_frame", "ssim", "ssim_per_frame"]

_SSIM_SIGMA = 1.5
_SSIM_TRUNCATE = 3.5
_SSIM_K1 = 0.01
_SSIM_K2 = 0.03


class FrameScores(NamedTuple):
    """Per-frame scores and their mean.

    Attributes
    ----------
    per_frame : ndarray, shape (S,), float64
    mean : float
    """

    per_frame: np.ndarray
    mean: float

    @property
    def clip(self) -> float:
        """The PSNR of the whole clip's mean squared error (:func:`clip_psnr`), from the frames' PSNRs (every
        frame the same size)."""
        return _clip_of(self.per_frame)


class _Score(float):
    """A mean score (a float) that still answers the old ``FrameScores`` fields, with a DeprecationWarning.

    Until 0.2, :func:`psnr` and :func:`ssim` returned :class:`FrameScores`; ``.mean`` and ``.per_frame``
    keep working for one release.
    """

    _per_frame: np.ndarray
    _name: str

    def __new__(cls, per_frame: np.ndarray, name: str):
        per = np.asarray(per_frame, dtype=np.float64)
        self = super().__new__(cls, float(np.mean(per)) if per.size else float("nan"))
        self._per_frame = per
        self._name = name
        return self

    def _warn(self, field: str, instead: str) -> None:
        warnings.warn(f"{self._name}() returns a float now (the mean over frames); `.{field}` on it is deprecated "
                      f"and goes in flexvox 0.3: use {instead}", DeprecationWarning, stacklevel=3)

    @property
    def mean(self) -> float:
        """Deprecated: the score itself is the mean."""
        self._warn("mean", f"the value itself, `{self._name}(ref, x)`")
        return float(self)

    @property
    def per_frame(self) -> np.ndarray:
        """Deprecated: use ``psnr_per_frame`` / ``ssim_per_frame``."""
        self._warn("per_frame", f"`{self._name}_per_frame(ref, x)`")
        return self._per_frame

    def __repr__(self) -> str:
        return float.__repr__(self)

    def __reduce__(self):
        return (float, (float(self),))


def _check_pair(ref, x, data_range, *, convert: bool = True, check_finite: bool = True
                ) -> tuple[np.ndarray, np.ndarray, float]:
    r = np.asarray(ref)
    v = np.asarray(x)
    if r.ndim == 2:
        r = r[None]
    if v.ndim == 2:
        v = v[None]
    if r.ndim != 3:
        raise ValueError(f"`ref` must have shape (S, H, W) or (H, W); got {np.asarray(ref).shape}")
    if r.shape != v.shape:
        raise ValueError(f"`x` must have the shape of `ref` {r.shape}; got {v.shape}")
    for name, a in (("ref", r), ("x", v)):
        if a.dtype.kind not in "biuf":  # bool, integers, floats
            raise ValueError(f"`{name}` must hold real numbers; got dtype {a.dtype}")
        if check_finite:
            _check_finite(name, a)
    L = positive_number("`data_range`", data_range)
    r, v = _same_units(r, v, L)
    _check_data_range(r, v, L)
    if not convert:
        return r, v, L
    return r.astype(np.float64), v.astype(np.float64), L


def _same_units(r: np.ndarray, v: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    """An integer array against a float one: the integer one in [0, 1], divided by its dtype's largest value
    (:func:`flexvox_core.intensity.as_relative`, as ``skimage.util.img_as_float`` does for unsigned types); the
    data range must then be 1. Two integer arrays, or two float ones, are compared as they are: two integer arrays
    of one dtype, in counts with the data range their white; of two dtypes, refused (two white levels)."""
    if r.dtype.kind in "iu" and v.dtype.kind in "iu":
        if r.dtype != v.dtype:
            raise ValueError(f"`ref` is {r.dtype} and `x` is {v.dtype}: two integer dtypes have two white levels; give "
                             "both as one dtype, or as floats in [0, 1]")
        if L == 1 and max(int(r.max(initial=0)), int(v.max(initial=0))) > 1:
            raise ValueError(f"`ref` and `x` are {r.dtype} counts, compared in counts: `data_range` must be their "
                             f"white ({np.iinfo(r.dtype).max} for {r.dtype}); got 1")
    kinds = {r.dtype.kind in "iu", v.dtype.kind in "iu"}
    if kinds != {True, False} or "f" not in (r.dtype.kind, v.dtype.kind):
        return r, v
    integer = r.dtype if r.dtype.kind in "iu" else v.dtype
    if L != 1:
        raise ValueError(f"`ref` is {r.dtype} and `x` is {v.dtype}: the {integer} one is read in [0, 1] (divided by "
                         f"{np.iinfo(integer).max}, as skimage.util.img_as_float does), so `data_range` must be 1; "
                         f"got {L:g}. To compare in counts, give both as the same dtype")
    from flexvox_core.intensity import as_relative

    return tuple(as_relative(a, name=name) if a.dtype.kind in "iu" else a  # type: ignore[return-value]
                 for name, a in (("ref", r), ("x", v)))


def _check_data_range(r: np.ndarray, v: np.ndarray, L: float) -> None:
    """Float arrays in another unit than the data range ``L`` says, refused (the module's "Units"): values beyond
    [-L, 2L] (looked for on every fourth frame, row and column: a unit is the whole array's), or two arrays in
    [0, 1] at an ``L`` above 2."""
    floats = [(name, a) for name, a in (("ref", r), ("x", v)) if a.dtype.kind == "f" and a.size]
    for name, a in floats:
        sample = a[::4, ::4, ::4]
        lo, hi = float(np.min(sample)), float(np.max(sample))  # NaN: no comparison holds; refused later, by frame
        if hi > 2 * L or lo < -L:
            hint = "8-bit values in a float array? divide by 255; or " if L == 1 and hi > 2 else ""
            raise ValueError(f"`{name}` holds values from {lo:.4g} to {hi:.4g}, but `data_range` is {L:g} (a float "
                             f"array must lie within [{-L:g}, {2 * L:g}], -data_range to 2·data_range): {hint}give "
                             "both in one unit, with that unit's data range")
    if L > 2 and len(floats) == 2:
        if all(np.min(a) >= 0 and np.max(a) <= 1 for _, a in floats):
            raise ValueError(f"`ref` and `x` both lie in [0, 1], but `data_range` is {L:g}: the PSNR would be "
                             f"{20 * np.log10(L):.1f} dB too high; videos in [0, 1] take data_range=1 (the default)")


def _check_finite(name: str, a: np.ndarray) -> None:
    finite = np.isfinite(a).all(axis=(1, 2))
    if not finite.all():
        raise ValueError(f"`{name}` frame {int(np.flatnonzero(~finite)[0])} holds NaN or infinite values")


FLOAT32_SAFE_MSE = (1e-30, 1e30)
"""Mean squared errors from float32 squares inside this range are kept; outside it (squares that may have
underflowed below float32's normal range, about 1.2e-38, or overflowed past its largest, 3.4e38) the frame is
taken again in float64."""


def _exact_in_float32(dtype) -> bool:
    """Whether every value of ``dtype`` is a float32 (float32 and narrower floats, bool, 8- and 16-bit integers)."""
    dtype = np.dtype(dtype)
    return dtype.kind == "b" or (dtype.kind in "iuf" and dtype.itemsize <= (4 if dtype.kind == "f" else 2))


def psnr(ref, x, *, data_range: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB, the mean of every frame's (as the benchmarks report it).

    Parameters
    ----------
    ref : ndarray, shape (S, H, W) or (H, W)
        Ground truth.
    x : ndarray, same shape as ``ref``
        Estimate.
    data_range : float, keyword-only
        Peak value L (1 for videos in [0, 1], 255 for two 8-bit videos).

    Returns
    -------
    float
        The mean of :func:`psnr_per_frame` (``inf`` when any frame equals its reference).

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.zeros((2, 4, 4)); x = ref + 0.1
    >>> round(psnr(ref, x), 6)
    20.0
    """
    return _Score(psnr_per_frame(ref, x, data_range=data_range), "psnr")


def clip_psnr(ref, x, *, data_range: float = 1.0) -> float:
    """Peak signal-to-noise ratio of the whole clip's mean squared error, in dB: ``10·log10(L² / MSE)``.

    The accuracy estimate (:mod:`flexvox_core.accuracy`) estimates this one. :func:`psnr` (the mean of the
    frames' PSNRs, as the benchmarks report it) is higher where the frames' errors differ: by up to about 0.4 dB
    on the built-in scenes.

    Parameters
    ----------
    ref : ndarray, shape (S, H, W) or (H, W)
        Ground truth.
    x : ndarray, same shape as ``ref``
        Estimate.
    data_range : float, keyword-only
        Peak value L (1 for videos in [0, 1], 255 for two 8-bit videos).

    Returns
    -------
    float
        ``inf`` when ``x`` equals ``ref``.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.zeros((2, 4, 4)); x = ref + [[[0.1]], [[0.01]]]
    >>> round(psnr(ref, x), 3), round(clip_psnr(ref, x), 3)
    (30.0, 22.967)
    """
    return _clip_of(psnr_per_frame(ref, x, data_range=data_range))


def _clip_of(per_frame: np.ndarray) -> float:
    """The clip's PSNR from its frames' (same-size frames: the clip's MSE is the mean of theirs)."""
    per = np.asarray(per_frame, np.float64)
    if per.size == 0:
        return float("nan")
    mse = float(np.mean(10.0 ** (-per / 10.0)))  # inf (an exact frame) gives 0
    return float("inf") if mse == 0 else float(-10.0 * np.log10(mse))


def psnr_per_frame(ref, x, *, data_range: float = 1.0) -> np.ndarray:
    """Peak signal-to-noise ratio of every frame, in dB.

    Parameters
    ----------
    ref : ndarray, shape (S, H, W) or (H, W)
        Ground truth.
    x : ndarray, same shape as ``ref``
        Estimate.
    data_range : float, keyword-only
        Peak value L (1 for videos in [0, 1], 255 for two 8-bit videos).

    Returns
    -------
    ndarray, shape (S,), float64
        ``inf`` for a frame equal to its reference.

    Examples
    --------
    >>> import numpy as np
    >>> ref = np.zeros((2, 4, 4)); x = ref + [[[0.1]], [[0.01]]]
    >>> psnr_per_frame(ref, x).round(6).tolist()
    [20.0, 40.0]
    """
    r, v, L = _check_pair(ref, x, data_range, convert=False, check_finite=False)
    # A frame at a time into one reused buffer: no copies of whole volumes (two float64 copies of a 1-s VGA
    # clip at K = 16, 590 MB each, took 3.4 s of a 7.5-s `flexvox reconstruct`), and no fresh memory per frame.
    # Volumes that float32 holds exactly take the difference and its square in float32 (each rounded once:
    # the MSE within about 1e-7 of itself, the PSNR within 1e-6 dB) and the sum in float64; 3-5x faster. A
    # frame whose float32 squares could have overflowed or fallen below float32's normal range (MSE outside
    # FLOAT32_SAFE_MSE; an exact frame, MSE 0, too) is taken again in float64.
    work = np.float32 if all(_exact_in_float32(a.dtype) for a in (r, v)) else np.float64
    buf = np.empty(r.shape[1:], work)
    wide = None
    mse = np.empty(len(r))
    for i in range(len(r)):
        with np.errstate(over="ignore", under="ignore"):  # such a frame is taken again below
            np.subtract(r[i], v[i], out=buf, dtype=work)
            np.square(buf, out=buf)
            mse[i] = buf.sum(dtype=np.float64) / max(buf.size, 1)
        if work is np.float32 and not FLOAT32_SAFE_MSE[0] < mse[i] < FLOAT32_SAFE_MSE[1]:
            wide = np.empty(r.shape[1:]) if wide is None else wide
            np.subtract(r[i], v[i], out=wide, dtype=np.float64)
            flat = wide.reshape(-1)
            mse[i] = np.dot(flat, flat) / max(flat.size, 1)
        if not np.isfinite(mse[i]):
            for name, a in (("ref", r), ("x", v)):
                if not np.isfinite(a[i]).all():
                    raise ValueError(f"`{name}` frame {i} holds NaN or infinite values")
    per = np.full(mse.shape, np.inf)
    ok = mse > 0
    per[ok] = 10.0 * np.log10(L * L / mse[ok])
    return per


def psnr_of_rows(read_ref, x, *, rows: int = 16, data_range: float = 1.0) -> FrameScores:
    """:func:`psnr` of ``x`` (S, H, W) against a reference read ``rows`` frames at a time by ``read_ref(a, b)``
    (frames [a, b)): a stored ground truth is never held whole. Reading a 1-s VGA clip's 295 MB truth at once
    cost ``flexvox reconstruct`` about 1 s of decompression into fresh memory; a few frames at a time reuse
    the same pages."""
    v = np.asarray(x)
    if v.ndim != 3:
        raise ValueError(f"`x` must have shape (S, H, W); got {v.shape}")
    if isinstance(rows, bool) or not isinstance(rows, int) or rows < 1:
        raise ValueError(f"`rows` must be a whole number >= 1; got {rows!r}")
    S = v.shape[0]
    per = []
    for a in range(0, S, rows):
        b = min(S, a + rows)
        try:
            per.append(psnr_per_frame(read_ref(a, b), v[a:b], data_range=data_range))
        except ValueError as exc:  # its frame numbers count from `a`: say which sub-frames
            raise ValueError(f"sub-frames {a}..{b - 1}: {exc}") from None
    per = np.concatenate(per) if S else np.zeros(0)
    return FrameScores(per, float(np.mean(per)) if S else float("nan"))


def _ssim_frame(a: np.ndarray, b: np.ndarray, L: float) -> float:
    from scipy.ndimage import gaussian_filter

    filt = {"sigma": _SSIM_SIGMA, "truncate": _SSIM_TRUNCATE, "mode": "reflect"}
    mu_a = gaussian_filter(a, **filt)
    mu_b = gaussian_filter(b, **filt)
    var_a = gaussian_filter(a * a, **filt) - mu_a * mu_a
    var_b = gaussian_filter(b * b, **filt) - mu_b * mu_b
    cov = gaussian_filter(a * b, **filt) - mu_a * mu_b
    c1 = (_SSIM_K1 * L) ** 2
    c2 = (_SSIM_K2 * L) ** 2
    num = (2 * mu_a * mu_b + c1) * (2 * cov + c2)
    den = (mu_a**2 + mu_b**2 + c1) * (var_a + var_b + c2)
    smap = num / den
    pad = int(_SSIM_TRUNCATE * _SSIM_SIGMA + 0.5)  # half window: 5 pixels
    H, W = a.shape
    if H > 2 * pad and W > 2 * pad:
        smap = smap[pad : H - pad, pad : W - pad]
    return float(np.mean(smap))


def ssim(ref, x, *, data_range: float = 1.0) -> float:
    """Structural similarity (Gaussian window, σ = 1.5), the mean of every frame's.

    Parameters
    ----------
    ref : ndarray, shape (S, H, W) or (H, W)
        Ground truth.
    x : ndarray, same shape as ``ref``
        Estimate.
    data_range : float, keyword-only
        Peak value L; sets C₁ = (0.01 L)² and C₂ = (0.03 L)².

    Returns
    -------
    float
        The mean of :func:`ssim_per_frame`, in [-1, 1] (1 for identical videos).

    Examples
    --------
    >>> import numpy as np
    >>> a = np.random.default_rng(0).random((1, 32, 32))
    >>> ssim(a, a)
    1.0
    """
    return _Score(ssim_per_frame(ref, x, data_range=data_range), "ssim")


def ssim_per_frame(ref, x, *, data_range: float = 1.0) -> np.ndarray:
    """Structural similarity (Gaussian window, σ = 1.5) of every frame.

    Parameters
    ----------
    ref : ndarray, shape (S, H, W) or (H, W)
        Ground truth.
    x : ndarray, same shape as ``ref``
        Estimate.
    data_range : float, keyword-only
        Peak value L; sets C₁ = (0.01 L)² and C₂ = (0.03 L)².

    Returns
    -------
    ndarray, shape (S,), float64
        In [-1, 1] (1 for identical frames). Frames smaller than 11 pixels on a side are averaged over the
        whole map (no border crop).

    Examples
    --------
    >>> import numpy as np
    >>> a = np.random.default_rng(0).random((2, 32, 32))
    >>> ssim_per_frame(a, a).tolist()
    [1.0, 1.0]
    """
    r, v, L = _check_pair(ref, x, data_range)
    return np.array([_ssim_frame(r[i], v[i], L) for i in range(r.shape[0])])
