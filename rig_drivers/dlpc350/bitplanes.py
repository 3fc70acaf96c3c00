"""Packing K binary masks into the bit-planes of 24-bit RGB video frames, and back.

In pattern mode with the video-port source, the DLPC350 shows each 24-bit input frame as
24 one-bit patterns. The LUT's *pattern number* picks the bit-plane (DLPC350 Programmer's
Guide DLPU010G Table 2-70, "Pattern Number Mapping"): **green first, least significant bit
first**::

    pattern number  0..7   -> green bits 0..7
    pattern number  8..15  -> red   bits 0..7
    pattern number 16..23  -> blue  bits 0..7

Mask k goes to frame ``k // 24`` and pattern number ``p = k % 24``, i.e. channel
``(G, R, B)[p // 8]`` and bit ``p % 8``. Frames are ``(H, W, 3)`` in R, G, B order (what
a display toolkit expects), so mask 0 is bit 0 of channel index 1.
"""

from __future__ import annotations

import numpy as np

from rig_drivers.errors import SettingError

PLANES_PER_FRAME = 24
_CHANNEL_OF_GROUP = (1, 0, 2)  # pattern numbers 0-7 green, 8-15 red, 16-23 blue; RGB indices


def plane_location(k: int) -> tuple[int, int, int]:
    """``(frame, rgb_channel, bit)`` that holds mask ``k``."""
    p = k % PLANES_PER_FRAME
    return k // PLANES_PER_FRAME, _CHANNEL_OF_GROUP[p // 8], p % 8


def pack_bitplanes(masks) -> np.ndarray:
    """Pack K binary masks into ``ceil(K / 24)`` RGB frames.

    Parameters
    ----------
    masks : array_like, shape (K, H, W), bool or 0/1
        Mask k is True where the mirror is on in slot k.

    Returns
    -------
    frames : ndarray, shape (ceil(K/24), H, W, 3), uint8
        Unused planes of the last frame are 0.

    Raises
    ------
    SettingError
        When ``masks`` is not 3-D, empty, or holds values other than 0/1.

    Examples
    --------
    >>> import numpy as np
    >>> frames = pack_bitplanes(np.ones((9, 1, 1), bool))
    >>> frames.shape, frames[0, 0, 0].tolist()
    ((1, 1, 1, 3), [1, 255, 0])
    """
    arr = np.asarray(masks)
    if arr.ndim != 3 or 0 in arr.shape:
        raise SettingError(f"`masks` must have shape (K, H, W) with K, H, W >= 1; got {arr.shape}")
    if arr.dtype != bool:
        if not np.issubdtype(arr.dtype, np.number) or not np.all((arr == 0) | (arr == 1)):
            raise SettingError("`masks` values must be 0/1 (or bool)")
        arr = arr.astype(bool)
    K, H, W = arr.shape
    frames = np.zeros((-(-K // PLANES_PER_FRAME), H, W, 3), dtype=np.uint8)
    for k in range(K):
        f, c, b = plane_location(k)
        frames[f, :, :, c] |= arr[k].astype(np.uint8) << b
    return frames


def unpack_bitplanes(frames, K: int) -> np.ndarray:
    """Inverse of :func:`pack_bitplanes`: the first ``K`` masks, ``(K, H, W)`` bool.

    Raises
    ------
    SettingError
        When ``frames`` is not ``(F, H, W, 3)`` uint8 or holds fewer than K planes.
    """
    arr = np.asarray(frames)
    if arr.ndim != 4 or arr.shape[-1] != 3 or arr.dtype != np.uint8:
        raise SettingError(f"`frames` must be a (F, H, W, 3) uint8 array; got {arr.dtype} {arr.shape}")
    if isinstance(K, bool) or not isinstance(K, (int, np.integer)) or not 1 <= K <= arr.shape[0] * 24:
        raise SettingError(f"`K` must be between 1 and {arr.shape[0] * 24} for {arr.shape[0]} frames; got {K!r}")
    out = np.empty((int(K),) + arr.shape[1:3], dtype=bool)
    for k in range(int(K)):
        f, c, b = plane_location(k)
        out[k] = (arr[f, :, :, c] >> b) & 1
    return out
