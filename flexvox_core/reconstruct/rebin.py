r"""Re-binning (the paper's §2): the captured samples rearranged into a video at [TR, SR].

A division ``a × b × c`` (rows × columns × slots, see :mod:`flexvox_core.divisions`)
cuts the video into blocks of ``a`` rows, ``b`` columns and ``c`` sub-frames, anchored
at the sensor's top-left and at sub-frame 0. A code *supports* the division when every
block of its tile volume holds exactly one sample; that sample then *is* the block's
value. Its gains over the acquired video are TR = K / c and SR = 1 / (a·b).

Three outputs:

- :func:`rebin_blocks` — the video at [TR, SR] as blocks, shape
  ``(F·TR, ⌈H/a⌉, ⌈W/b⌉)``: element ``[t, i, j]`` is the block of sub-frames
  ``t·c .. t·c + c − 1``, rows ``i·a .. i·a + a − 1`` and columns ``j·b .. j·b + b − 1``.
- :func:`rebin` — the same on the full ``(S, H, W)`` grid, each block's one sample
  filling its block (nearest), or with ``interpolate=True`` trilinear interpolation
  between block centres (block ``[t, i, j]`` sits at sub-frame ``t·c + (c−1)/2``, row
  ``i·a + (a−1)/2``, column ``j·b + (b−1)/2``; beyond the first and last centres the
  value is held constant).

**Border blocks.** When H is not a multiple of ``a`` (or W of ``b``), the last block row
(column) is cut by the sensor edge, and its sample may lie outside the sensor. Such an
empty block takes the value of the nearest non-empty block in the block grid (in
practice the one just inside the border). A block never holds more than one sample.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from flexvox_core.codes import verify
from flexvox_core.divisions import Division, check_division, parse_division
from flexvox_core.forward import tiled_order
from flexvox_core.reconstruct._common import check_dtype, check_frames, check_identity_code

_logger = logging.getLogger(__name__)

__all__ = ["default_block", "rebin", "rebin_blocks", "supported_divisions"]


def _as_division(division, tile) -> Division:
    if isinstance(division, Division):
        d = division
    elif isinstance(division, str):
        d = parse_division(division)
    else:
        try:
            a, b, c = (int(v) for v in division)
        except (TypeError, ValueError):
            raise ValueError(
                f"`division` must be a Division, 'AxBxC' or (a, b, c); got {division!r}"
            ) from None
        d = Division(a, b, c)
    return check_division(d, tile)


def supported_divisions(code) -> list[Division]:
    """The divisions an identity ``code`` supports, sorted by TR (see :func:`~flexvox_core.codes.verify`)."""
    return verify(check_identity_code(code)).supported


def default_block(code) -> Division:
    """The supported division whose TR is closest to √K (a balanced space-time trade),
    squarest block first among ties (2×2×4 rather than 1×4×4 for a 4×4 tile).

    Parameters
    ----------
    code : ndarray (m, n, K) bool, identity code

    Raises
    ------
    ValueError
        When the code supports no division.
    """
    supported = verify(code).supported
    if not supported:
        raise ValueError("the code supports no division; re-binning is impossible")
    K = code.shape[2]
    return min(supported, key=lambda d: (round(abs(math.log(d.tr) - 0.5 * math.log(K)), 9), abs(d.a - d.b), -d.tr))


def _validate(frames, code, division, dtype):
    f = check_frames(frames)
    c = check_identity_code(code)
    m, n, _ = c.shape
    d = _as_division(division, (m, n))
    result = verify(c, [d])
    if result.unsupported:
        supported = ", ".join(x.label for x in verify(c).supported) or "none"
        raise ValueError(
            f"`division` {d.label} is not supported by this code: "
            f"{result.failing_blocks[d.label]} of its blocks do not hold exactly one sample "
            f"(re-binning needs one sample per block); this code supports: {supported}"
        )
    return f, c, d, check_dtype(dtype)


def _blocks_kernel(frames: np.ndarray, code: np.ndarray, d: Division, dtype) -> np.ndarray:
    F, H, W = frames.shape
    m, n, K = code.shape
    a, b, c = d.a, d.b, d.c
    TR = K // c
    order = tiled_order(code, H, W)  # slot of every pixel
    Hb, Wb = -(-H // a), -(-W // b)
    # Each pixel's sample lands in block (f·TR + slot // c, y // a, x // b); supported
    # divisions put exactly one pixel of each (full) block there.
    t_idx = (order // c)[None] + (np.arange(F) * TR)[:, None, None]  # (F, H, W)
    yy = np.broadcast_to((np.arange(H) // a)[None, :, None], (F, H, W))
    xx = np.broadcast_to((np.arange(W) // b)[None, None, :], (F, H, W))
    out = np.zeros((F * TR, Hb, Wb), dtype=dtype)
    filled = np.zeros((F * TR, Hb, Wb), dtype=bool)
    out[t_idx, yy, xx] = frames
    filled[t_idx, yy, xx] = True
    if not filled.all():  # border blocks whose sample fell outside the sensor
        from scipy.ndimage import distance_transform_edt

        idx = distance_transform_edt(~filled, return_distances=False, return_indices=True)
        out = out[tuple(idx)]
        _logger.debug("re-binning %s: %d empty border blocks filled from neighbours",
                      d.label, int((~filled).sum()))
    return out


def rebin_blocks(frames, code, division, *, dtype=np.float32) -> np.ndarray:
    """The capture re-binned at ``division``'s [TR, SR], one value per block.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        An identity-code capture (demultiplex first: :func:`~flexvox_core.reconstruct.as_identity_capture`).
    code : ndarray, shape (m, n, K), bool
        Its identity code.
    division : Division, str 'AxBxC' or (a, b, c)
        The block shape; the code must support it.
    dtype : float32 or float64, keyword-only

    Returns
    -------
    blocks : ndarray, shape (F·TR, ⌈H/a⌉, ⌈W/b⌉)
        TR = K / c. ``blocks[t, i, j]`` covers sub-frames ``t·c ..``, rows ``i·a ..``,
        columns ``j·b ..`` (see the module notes for border blocks).

    Raises
    ------
    ValueError
        For a division the code does not support (the message lists those it does).

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import capture, code_from_order
    >>> code = code_from_order([[0, 2], [3, 1]])
    >>> video = np.arange(4 * 2 * 2, dtype=np.float32).reshape(4, 2, 2)
    >>> rebin_blocks(capture(video, code), code, "2x2x1")[:, 0, 0].tolist()
    [0.0, 7.0, 9.0, 14.0]
    """
    f, c, d, dt = _validate(frames, code, division, dtype)
    return _blocks_kernel(f.astype(dt, copy=False), c, d, dt)


def _interp_axis(arr: np.ndarray, axis: int, block: int, n_out: int) -> np.ndarray:
    """Linear interpolation along ``axis`` from block centres to ``n_out`` grid points."""
    nb = arr.shape[axis]
    pos = (np.arange(n_out) - (block - 1) / 2.0) / block  # position in block units
    pos = np.clip(pos, 0.0, nb - 1)
    i0 = np.floor(pos).astype(np.intp)
    i1 = np.minimum(i0 + 1, nb - 1)
    w1 = (pos - i0).astype(arr.dtype)
    shape = [1] * arr.ndim
    shape[axis] = n_out
    w1 = w1.reshape(shape)
    lo = np.take(arr, i0, axis=axis)
    hi = np.take(arr, i1, axis=axis)
    lo += w1 * (hi - lo)
    return lo


def rebin(frames, code, division, *, interpolate: bool = False, dtype=np.float32) -> np.ndarray:
    """The re-binned video on the full ``(S, H, W)`` grid.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        An identity-code capture.
    code : ndarray, shape (m, n, K), bool
        Its identity code.
    division : Division, str 'AxBxC' or (a, b, c)
        The block shape; the code must support it.
    interpolate : bool, keyword-only
        False: each block's one sample fills its block. True: trilinear interpolation
        between block centres (held constant beyond the outermost centres).
    dtype : float32 or float64, keyword-only

    Returns
    -------
    video : ndarray, shape (F·K, H, W)
        Within the range of the samples (both modes are convex combinations of them).

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import capture, code_from_order
    >>> code = code_from_order([[0, 2], [3, 1]])
    >>> video = np.arange(4 * 2 * 2, dtype=np.float32).reshape(4, 2, 2)
    >>> rebin(capture(video, code), code, "1x1x4")[:, 0, 1].tolist()
    [9.0, 9.0, 9.0, 9.0]
    """
    f, c, d, dt = _validate(frames, code, division, dtype)
    F, H, W = f.shape
    K = c.shape[2]
    blocks = _blocks_kernel(f.astype(dt, copy=False), c, d, dt)
    if not interpolate:
        t = np.arange(F * K) // d.c
        y = np.arange(H) // d.a
        x = np.arange(W) // d.b
        return np.ascontiguousarray(blocks[t][:, y][:, :, x])
    out = _interp_axis(blocks, 0, d.c, F * K)
    out = _interp_axis(out, 1, d.a, H)
    out = _interp_axis(out, 2, d.b, W)
    return np.ascontiguousarray(out)
