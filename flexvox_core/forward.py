"""The forward model of a per-pixel shutter, and the helpers every reconstruction needs.

The paper's §2 ("Simulating multi-resolution sampling": K consecutive high-speed frames weighted by the
per-pixel code and added) and §5 (the projector's binary patterns as that shutter).

.. math::

    \\mathrm{capture}[f, y, x] = \\sum_s \\mathrm{code}[y \\bmod m, x \\bmod n, s]
        \\cdot \\mathrm{video}[f K + s, y, x]

Tiles are anchored at the sensor's top-left; partial tiles at the right and bottom
borders use the matching part of the code.
"""

from __future__ import annotations

import numpy as np

from flexvox_core.codes import is_identity_code, order_from_code, validate_code
from flexvox_core.intensity import as_relative


def tiled_code(code, height: int, width: int) -> np.ndarray:
    """The code laid over a ``height × width`` sensor: bool array ``(K, height, width)``."""
    c = validate_code(code)
    m, n, _ = c.shape
    if height < 1 or width < 1:
        raise ValueError(f"sensor size must be positive; got {height}x{width}")
    rows = np.arange(height) % m
    cols = np.arange(width) % n
    return np.ascontiguousarray(c[rows][:, cols].transpose(2, 0, 1))


def tiled_order(code, height: int, width: int) -> np.ndarray:
    """Slot of every sensor pixel for an identity code: int array ``(height, width)``."""
    order = order_from_code(code)
    m, n = order.shape
    return order[np.arange(height) % m][:, np.arange(width) % n]


def check_video(video, K: int, *, name: str = "video") -> np.ndarray:
    """Validate a high-speed video ``(S, H, W)`` with S a multiple of K; keep float dtypes.

    Integer and bool input is read in relative units as float32, divided by its dtype's largest value (uint8:
    255; :func:`flexvox_core.intensity.as_relative`), float16 becomes float32. A NaN or infinite value raises
    ``ValueError`` naming the first sub-frame that holds one.
    """
    arr = np.asarray(video)
    if arr.ndim != 3:
        raise ValueError(f"`{name}` must have shape (S, H, W); got {arr.ndim} dimensions {arr.shape}")
    S = arr.shape[0]
    if S == 0 or S % K:
        raise ValueError(
            f"`{name}` length S = {S} must be a positive multiple of K = {K} "
            "(whole camera frames)"
        )
    if arr.dtype.kind in "biu":  # an 8-bit clip is a video in [0, 1], as everywhere (flexvox_core.intensity)
        arr = as_relative(arr, name=name)
    elif not np.issubdtype(arr.dtype, np.floating) or arr.dtype == np.float16:
        arr = arr.astype(np.float32)
    finite = np.isfinite(arr).all(axis=(1, 2))
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"`{name}` sub-frame {bad} holds NaN or infinite values")
    return arr


def capture(video, code) -> np.ndarray:
    """Simulate the camera frames of a per-pixel-shutter rig (ideal, no effects).

    Parameters
    ----------
    video : ndarray, shape (S, H, W)
        High-speed video; S must be a multiple of K. float32 and float64 are kept; integers
        (an 8-bit clip) become float32 in [0, 1], divided by their dtype's largest value.
    code : ndarray, shape (m, n, K)
        Identity or multiplexed code.

    Returns
    -------
    frames : ndarray, shape (S / K, H, W), same float dtype as ``video``
        For identity codes each value *is* the sampled voxel. For multiplexed codes the
        sum runs over slots in increasing order.

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import code_from_order
    >>> video = np.arange(4 * 2 * 2, dtype=np.float32).reshape(4, 2, 2)
    >>> capture(video, code_from_order([[0, 2], [3, 1]]))[0].tolist()
    [[0.0, 9.0], [14.0, 7.0]]
    """
    c = validate_code(code)
    K = c.shape[2]
    v = check_video(video, K)
    S, H, W = v.shape
    F = S // K
    blocks = v.reshape(F, K, H, W)
    if is_identity_code(c):
        idx = tiled_order(c, H, W)
        return np.take_along_axis(blocks, idx[None, None], axis=1)[:, 0]
    mask = tiled_code(c, H, W)
    out = np.zeros((F, H, W), dtype=v.dtype)
    for s in range(K):  # in slot order: the same sum, term for term, as the definition
        np.add(out, blocks[:, s], out=out, where=mask[s][None])
    return out


def sample_mask(shape, code) -> np.ndarray:
    """Bool volume ``(S, H, W)``: True where the code samples the video (slot open)."""
    c = validate_code(code)
    K = c.shape[2]
    try:
        S, H, W = (int(x) for x in shape)
    except (TypeError, ValueError):
        raise ValueError(f"`shape` must be (S, H, W); got {shape!r}") from None
    if S < 1 or S % K:
        raise ValueError(f"`shape` S = {S} must be a positive multiple of K = {K}")
    return np.tile(tiled_code(c, H, W), (S // K, 1, 1))


def sparse_volume(frames, code, *, fill: float = 0.0) -> np.ndarray:
    """Place captured values at their sampled voxels: ``(F·K, H, W)``, ``fill`` elsewhere.

    Only for identity codes (demultiplex a multiplexed capture first).
    """
    c = validate_code(code)
    K = c.shape[2]
    f = np.asarray(frames)
    if f.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {f.ndim} dimensions {f.shape}")
    if not np.issubdtype(f.dtype, np.floating):
        f = f.astype(np.float32)
    from flexvox_core.threads import for_each  # (OpenCV: not imported with the package)

    F, H, W = f.shape
    slots = np.arange(K)[:, None, None] == tiled_order(c, H, W)[None]  # (K, H, W); refuses non-identity codes
    vol = np.empty((F, K, H, W), dtype=f.dtype)

    def one(i):  # a frame at a time, on every core: the fresh volume's pages are faulted in on both
        vol[i] = fill
        np.copyto(vol[i], f[i][None], where=slots)

    for_each(one, F)
    return vol.reshape(F * K, H, W)
