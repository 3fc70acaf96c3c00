"""Tiles: the m×n pixel neighbourhood that shares one exposure's K = m·n slots.

The paper's §2: the space-time volume :math:`V_{mn}` of one tile and one camera integration time.
"""

from __future__ import annotations

import re
from numbers import Integral

MAX_TILE_SIDE = 8
"""Largest supported tile side; 8×8 gives K = 64 slots per camera frame."""

_TILE_RE = re.compile(r"^\s*(-?\d+)\s*[xX×]\s*(-?\d+)\s*$")


def validate_tile(tile) -> tuple[int, int]:
    """Return ``tile`` as ``(m, n)`` ints, or raise ``ValueError`` naming the rule.

    Parameters
    ----------
    tile : tuple of two ints, or str
        Rows ``m`` and columns ``n`` of the tile, each in ``1 .. MAX_TILE_SIDE``; or the same written
        ``"MxN"`` (``"4x4"``, :func:`parse_tile`), the one spelling of sizes everywhere.
    """
    if isinstance(tile, str):
        return parse_tile(tile)
    try:
        m, n = tile
    except (TypeError, ValueError):
        raise ValueError(f"`tile` must be two integers (m, n); got {tile!r}") from None
    for name, v in (("m", m), ("n", n)):
        if isinstance(v, bool) or not isinstance(v, Integral):
            raise ValueError(f"`tile` side {name} must be an integer; got {v!r}")
        if not 1 <= int(v) <= MAX_TILE_SIDE:
            raise ValueError(
                f"`tile` side {name} must be between 1 and {MAX_TILE_SIDE}; got {int(v)} "
                f"(tiles up to {MAX_TILE_SIDE}x{MAX_TILE_SIDE}, K <= {MAX_TILE_SIDE ** 2})"
            )
    return int(m), int(n)


def parse_tile(text: str) -> tuple[int, int]:
    """Parse ``"MxN"`` (for example ``"4x4"`` or ``"2x4"``) into ``(m, n)``.

    Raises
    ------
    ValueError
        When the text is not ``MxN`` with two whole numbers, or a side is out of range.

    Examples
    --------
    >>> parse_tile("2x4")
    (2, 4)
    """
    match = _TILE_RE.match(str(text))
    if match is None:
        raise ValueError(
            f"tile must be written MxN with two whole numbers, e.g. 4x4; got {text!r}"
        )
    return validate_tile((int(match.group(1)), int(match.group(2))))

