"""Sample values in relative units: the one rule for integer arrays (camera counts, 8-bit videos).

flexvox works in relative units, white = 1 (a video in [0, 1]). An integer array is read as
``skimage.util.img_as_float`` reads an unsigned one: divided by its dtype's largest value
(``np.iinfo(dtype).max``: 255 for uint8, 65535 for uint16), unless a white level is given (a 12-bit
camera's counts in uint16: ``white=4095``). A float array is taken as relative units already, or divided
by ``white`` when one is given. A bool array is 0 and 1. Integers wider than 16 bits (int32, int64: what
``astype(int)`` gives) need ``white``: their dtype's largest value is no camera's white, and dividing by it
would read every count as black. uint16 counts without ``white`` that all fit in 12 bits (none above 4095: a
10- or 12-bit camera's, most likely) are read by the rule all the same, with a :class:`CountsWarning` that says
the video then lies within [0, 0.0625] and how to give the camera's white.
"""

from __future__ import annotations

import warnings

import numpy as np
import numpy.typing as npt

from flexvox_core.numbers import positive_number

__all__ = ["CountsWarning", "as_relative", "white_level"]

NARROW_COUNTS = 4095
"""The largest count of a 12-bit camera: uint16 counts none above it are most likely a 10- or 12-bit camera's."""


class CountsWarning(UserWarning):
    """Integer counts read by the dtype's rule that look like another white level's (a 12-bit camera in uint16)."""


def white_level(dtype: npt.DTypeLike, white: float | None = None) -> float | None:
    """The value that stands for white in an array of ``dtype``: ``white`` when given (checked: a positive
    finite number), the dtype's largest value for an integer dtype, None for floats and bool (no scaling)."""
    if white is not None:
        return positive_number("`white`", white, unit="counts")
    dtype = np.dtype(dtype)
    return float(np.iinfo(dtype).max) if dtype.kind in "iu" else None


def as_relative(values: npt.ArrayLike, *, white: float | None = None, name: str = "frames") -> np.ndarray:
    """``values`` in relative units (white = 1).

    Parameters
    ----------
    values : array_like
        Real numbers: integer counts, bool, or floats.
    white : float, optional
        The value that stands for white. Default: the dtype's largest value for integers (uint8: 255,
        uint16: 65535), none for floats (taken as relative units already).
    name : str
        The argument's name, for messages.

    Returns
    -------
    ndarray
        Integers and bool as float32 divided by the white level; floats unchanged when ``white`` is None,
        else divided by it (float32 stays float32).

    Raises
    ------
    ValueError
        Values that are not real numbers, integers wider than 16 bits without ``white``, or a ``white`` that is
        not a positive finite number.

    Examples
    --------
    >>> import numpy as np
    >>> as_relative(np.array([0, 255], np.uint8)).tolist()
    [0.0, 1.0]
    >>> as_relative(np.array([0, 4095], np.uint16), white=4095).tolist()
    [0.0, 1.0]
    """
    a = np.asarray(values)
    if a.dtype.kind not in "biuf":
        raise ValueError(f"`{name}` must hold real numbers (integer counts or floats in relative units); got "
                         f"dtype {a.dtype}")
    if a.dtype.kind in "iu" and a.dtype.itemsize > 2 and white is None:
        raise ValueError(f"`{name}` are {a.dtype.name} counts and {a.dtype.name}'s largest value "
                         f"({np.iinfo(a.dtype).max}) is no camera's white: give `white=` where the call takes it (the "
                         "count that stands for white, 4095 for a 12-bit camera), the counts as uint8 or uint16, or "
                         "floats in [0, 1] (counts / white)")
    w = white_level(a.dtype, white)
    if white is None and a.dtype == np.uint16 and a.size:
        top = int(a.max())
        if 0 < top <= NARROW_COUNTS:
            warnings.warn(f"`{name}` are uint16 counts none above {top}: read as 16-bit counts (white 65535), they "
                          f"lie within [0, {top / 65535:.4f}]; a 12-bit camera's counts need `white=4095` (10-bit: "
                          "1023) where the call takes it, or floats (counts / white)", CountsWarning, stacklevel=3)
    if a.dtype.kind in "biu":
        out = a.astype(np.float32)
        return out if w is None else np.divide(out, np.float32(w), out=out)
    if w is None:
        return a
    return np.asarray(a / np.asarray(w, a.dtype), dtype=a.dtype)
