"""Divisions of the m×n×K space-time block into K equal blocks (the paper's §2).

A division is a block shape a rows × b columns × c slots with a | m, b | n, c | K and
a·b·c = K. Re-binning by it gives a video whose gains over the acquired one are
TR = K / c (temporal) and SR = 1 / (a·b) (spatial), so TR·SR = 1: the voxel budget is
constant. (The paper's printed factor lists are inconsistent in places; these are the
definitions flexvox uses everywhere.)
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

from flexvox_core.tiles import validate_tile

# One spelling set everywhere (the command line's --divisions and --block, Method options, files): "2x2x4",
# "2×2×4" and "2,2,4"; in Python also (2, 2, 4) and a Division.
_DIVISION_RE = re.compile(r"^\s*(\d+)\s*([xX×,])\s*(\d+)\s*\2\s*(\d+)\s*$")


@dataclass(frozen=True, order=True)
class Division:
    """A block shape ``a × b × c`` (rows × columns × slots) of a tile with K slots."""

    a: int
    b: int
    c: int

    @property
    def K(self) -> int:  # noqa: N802 - K is the paper's name
        """Slots per frame (= blocks per tile volume) implied by the shape."""
        return self.a * self.b * self.c

    @property
    def tr(self) -> int:
        """Temporal-resolution gain over the acquired video, K / c."""
        return self.K // self.c

    @property
    def sr(self) -> Fraction:
        """Spatial-resolution gain over the acquired video, 1 / (a·b)."""
        return Fraction(1, self.a * self.b)

    @property
    def label(self) -> str:
        """``"a x b x c"`` as typed on the command line."""
        return f"{self.a}x{self.b}x{self.c}"

    def as_dict(self) -> dict:
        """JSON-ready description: block, TR, SR (as a number and as a fraction)."""
        return {
            "block": [self.a, self.b, self.c],
            "TR": self.tr,
            "SR": float(self.sr),
            "SR_fraction": str(self.sr),
        }

    def __str__(self) -> str:
        return f"{self.label} [TR {self.tr}, SR {self.sr}]"


def _divisors(x: int) -> list[int]:
    return [d for d in range(1, x + 1) if x % d == 0]


def enumerate_divisions(tile) -> list[Division]:
    """All divisions of an ``m × n`` tile, sorted by TR then block shape.

    Parameters
    ----------
    tile : (int, int)
        Tile rows and columns.

    Returns
    -------
    list of Division
        Every ``a × b × c`` with ``a | m``, ``b | n``, ``c | K`` and ``a·b·c = K``.

    Examples
    --------
    >>> [d.label for d in enumerate_divisions((2, 2))]
    ['1x1x4', '1x2x2', '2x1x2', '2x2x1']
    """
    m, n = validate_tile(tile)
    K = m * n
    out = []
    for a in _divisors(m):
        for b in _divisors(n):
            if K % (a * b) == 0:
                out.append(Division(a, b, K // (a * b)))
    return sorted(out, key=lambda d: (d.tr, d.a, d.b))


def check_division(division: Division, tile) -> Division:
    """Return ``division`` if it divides ``tile``'s block, else raise ``ValueError``."""
    m, n = validate_tile(tile)
    K = m * n
    a, b, c = division.a, division.b, division.c
    if min(a, b, c) < 1 or m % a or n % b or K % c or a * b * c != K:
        raise ValueError(
            f"division {a}x{b}x{c} does not divide a {m}x{n} tile: it needs a | {m}, "
            f"b | {n}, c | {K} and a*b*c = {K}"
        )
    return division


def parse_division(text, tile=None) -> Division:
    """A division from any of its spellings; checked against ``tile`` when given.

    Parameters
    ----------
    text : str, sequence of 3 ints, or Division
        ``"AxBxC"`` (rows × columns × slots; ``×`` too), ``"A,B,C"``, ``(a, b, c)`` or a :class:`Division`.
    tile : (int, int), optional
        The tile the division must divide (``a | m``, ``b | n``, ``c | K``, ``a·b·c = K``).

    Returns
    -------
    Division

    Examples
    --------
    >>> parse_division("2x2x4") == parse_division("2,2,4") == parse_division((2, 2, 4))
    True
    >>> parse_division("1x2x8", (4, 4)).label
    '1x2x8'
    """
    if isinstance(text, Division):
        d = text
    elif isinstance(text, (tuple, list)):
        if len(text) != 3 or not all(isinstance(v, int) and not isinstance(v, bool) for v in text):
            raise ValueError(f"a division must be three whole numbers (rows, columns, slots), e.g. (2, 2, 4); "
                             f"got {text!r}")
        d = Division(*text)
    else:
        match = _DIVISION_RE.match(str(text))
        if match is None:
            raise ValueError(
                "a division must be written AxBxC or A,B,C (rows x columns x slots), e.g. 2x2x4; "
                f"got {text!r}"
            )
        a, _, b, c = match.groups()
        d = Division(int(a), int(b), int(c))
    if min(d.a, d.b, d.c) < 1:
        raise ValueError(f"a division's sizes must be >= 1; got {d.a}x{d.b}x{d.c}")
    if tile is not None:
        check_division(d, tile)
    return d
