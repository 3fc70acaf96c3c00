"""Shutter codes as arrays: validation, identity codes and firing orders, verification.

The paper's §2: the temporal firing order of a K-pixel tile (its Fig. 2), and the check that a code samples
every block of every division once (the constraints of its Eq. 1).

A code is an ``(m, n, K)`` bool array: ``code[i, j, s]`` is True when tile pixel
``(i, j)`` is open in slot ``s``. An *identity* code opens every pixel in exactly one
slot; its *firing order* is the ``(m, n)`` int array of those slots.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flexvox_core.divisions import Division, check_division, enumerate_divisions
from flexvox_core.tiles import validate_tile


def validate_code(code) -> np.ndarray:
    """Return ``code`` as a C-contiguous ``(m, n, K)`` bool array with K = m·n.

    Raises
    ------
    ValueError
        When the shape is not ``(m, n, m·n)``, a side is out of range, or the values
        are not 0/1.
    """
    arr = np.asarray(code)
    if arr.ndim == 0 and hasattr(code, "code"):  # a DesignResult, a MultiplexedCode
        raise ValueError(f"`code` must be the code's (m, n, K) array; got a {type(code).__name__}: give its `.code`")
    if arr.ndim == 0 and (isinstance(code, str) or arr.dtype == object):
        got = f"the text {code!r}" if isinstance(code, str) else f"a {type(code).__name__}"
        raise ValueError(f"`code` must be the code's (m, n, K) array (a tile's: fv.design_code(tile).code); got {got}"
                         ": a method goes after the code, (frames, code, method)")
    if arr.ndim != 3:
        raise ValueError(f"`code` must have shape (m, n, K); got {arr.ndim} dimensions {arr.shape}")
    m, n, K = arr.shape
    try:
        validate_tile((m, n))
        if K != m * n:
            raise ValueError(f"`code` of a {m}x{n} tile must have K = {m * n} slots; got {K}")
    except ValueError as exc:
        raise ValueError(f"{exc}{_axes_hint(arr)}") from None
    if arr.dtype != bool:
        if not np.issubdtype(arr.dtype, np.number) or not np.all((arr == 0) | (arr == 1)):
            raise ValueError("`code` values must be 0/1 (or bool)")
        arr = arr.astype(bool)
    return np.ascontiguousarray(arr)


def _axes_hint(arr: np.ndarray) -> str:
    """Why a 3-D array that is no (m, n, K) code may be one in another order, in words ("" when it does not look
    like one): the slots first, or a code tiled over a sensor (:func:`flexvox_core.forward.tiled_code`)."""
    first, rows, cols = arr.shape
    if first > 1 and first == rows * cols:
        return (f": a code is (m, n, K) and this one looks like (K, m, n) = {arr.shape}: "
                "np.moveaxis(code, 0, -1)")
    if 1 < first <= 64 and arr.dtype.kind in "biuf" and np.all(arr.sum(axis=0) == 1):
        return (f": a code is (m, n, K) and this one looks like (K, H, W) = {arr.shape}, a code tiled over a sensor "
                "(fv.tiled_code): give the tile's code")
    return ""


def is_identity_code(code) -> bool:
    """True when every pixel is open in exactly one slot and every slot is used once."""
    c = validate_code(code)
    m, n, K = c.shape
    return bool(np.all(c.sum(axis=2) == 1) and np.all(c.reshape(m * n, K).sum(axis=0) == 1))


def is_multiplexed_code(code) -> bool:
    """True when ``code`` is a multiplexed code: not an identity code, and its tile's K×K open/closed matrix
    (row r: tile pixel r in raster order, column s: slot s) is invertible, so that a tile's K measurements
    determine its K slot values (an S-matrix code, :func:`flexvox_core.multiplex.multiplexed_code`, is one)."""
    c = validate_code(code)
    m, n, K = c.shape
    if is_identity_code(c):
        return False
    return bool(np.linalg.matrix_rank(c.reshape(m * n, K).astype(np.float64)) == K)


def check_reconstructable(code) -> bool:
    """Check that a capture through ``code`` can be reconstructed; True for a multiplexed code, False for an
    identity code.

    A code must be an *identity* code (every tile pixel open in exactly one slot, every slot used once:
    :func:`code_from_order`, :func:`flexvox_core.design_code`) or a *multiplexed* one (:func:`is_multiplexed_code`:
    the tile's K×K open/closed matrix invertible, as an S-matrix code's, :func:`flexvox_core.multiplexed_code`).

    Raises
    ------
    ValueError
        Any other code (all pixels open in every slot, a slot no pixel uses, two pixels with the same
        pattern ...), naming the rule.

    Examples
    --------
    >>> import numpy as np
    >>> check_reconstructable(code_from_order(sequential_order((2, 2))))
    False
    >>> check_reconstructable(np.ones((2, 2, 4), bool))
    Traceback (most recent call last):
    ...
    ValueError: `code` is neither an identity code ...
    """
    c = validate_code(code)
    if is_identity_code(c):
        return False
    if is_multiplexed_code(c):
        return True
    m, n, K = c.shape
    rank = int(np.linalg.matrix_rank(c.reshape(m * n, K).astype(np.float64)))
    open_px = c.sum(axis=2)
    raise ValueError(
        f"`code` is neither an identity code (each tile pixel open in exactly one slot, each slot used once; "
        f"fv.design_code, fv.code_from_order) nor a multiplexed one (the tile's {K}x{K} pixel-by-slot matrix "
        f"invertible, as an S-matrix code's, fv.multiplexed_code): this {m}x{n} code opens its pixels in "
        f"{int(open_px.min())} to {int(open_px.max())} of {K} slots and its matrix has rank {rank} of {K}, so "
        "the slots cannot be told apart")


def validate_order(order) -> np.ndarray:
    """Return ``order`` as an ``(m, n)`` int array holding each slot 0..K-1 once."""
    arr = np.asarray(order)
    if arr.ndim != 2:
        raise ValueError(f"`order` must have shape (m, n); got {arr.ndim} dimensions {arr.shape}")
    m, n = validate_tile(arr.shape)
    if not np.issubdtype(arr.dtype, np.integer):
        if not np.issubdtype(arr.dtype, np.number) or not np.all(arr == np.round(arr)):
            raise ValueError("`order` must hold whole slot numbers")
        arr = arr.astype(np.int64)
    K = m * n
    if sorted(arr.ravel().tolist()) != list(range(K)):
        raise ValueError(f"`order` of a {m}x{n} tile must hold each slot 0..{K - 1} exactly once")
    return arr.astype(np.int64)


def code_from_order(order) -> np.ndarray:
    """The identity code ``(m, n, K)`` of a firing order ``(m, n)``."""
    o = validate_order(order)
    m, n = o.shape
    return np.arange(m * n)[None, None, :] == o[:, :, None]


def order_from_code(code) -> np.ndarray:
    """The firing order of an identity code; ``ValueError`` for a multiplexed code."""
    c = validate_code(code)
    if not is_identity_code(c):
        raise ValueError(
            "`code` is not an identity code (each pixel open in exactly one slot, each slot "
            "used once): it has no firing order"
        )
    return c.argmax(axis=2).astype(np.int64)


def sequential_order(tile) -> np.ndarray:
    """Sequential firing (slot = raster index), the scheme of Bub et al. 2010."""
    m, n = validate_tile(tile)
    return np.arange(m * n, dtype=np.int64).reshape(m, n)


def _neighbour_pairs(m: int, n: int) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """4-neighbour pairs of a tile on the torus (tiles repeat across the sensor)."""
    pairs = set()
    for i in range(m):
        for j in range(n):
            for di, dj in ((0, 1), (1, 0)):
                q = ((i + di) % m, (j + dj) % n)
                if q != (i, j):
                    pairs.add(tuple(sorted([(i, j), q])))
    return sorted(pairs)


def neighbour_separation(order) -> int | None:
    """Smallest cyclic firing-time gap between 4-neighbours, across tile borders too.

    The gap between slots s and t of a K-slot exposure is ``min(|s-t|, K-|s-t|)``
    (slot K-1 of one frame is next to slot 0 of the following one). ``None`` for a
    1×1 tile, which has no neighbour.
    """
    o = validate_order(order)
    m, n = o.shape
    K = m * n
    gaps = [
        min(abs(int(o[p]) - int(o[q])), K - abs(int(o[p]) - int(o[q])))
        for p, q in _neighbour_pairs(m, n)
    ]
    return min(gaps) if gaps else None


def block_counts(code, division: Division) -> np.ndarray:
    """Number of open (pixel, slot) samples in every block of ``division``.

    Returns an int array of shape ``(m/a, n/b, K/c)``.
    """
    c = validate_code(code)
    m, n, K = c.shape
    check_division(division, (m, n))
    a, b, cc = division.a, division.b, division.c
    return c.reshape(m // a, a, n // b, b, K // cc, cc).sum(axis=(1, 3, 5))


@dataclass(frozen=True)
class VerifyResult:
    """Which divisions a code supports.

    A code supports a division when every block of it holds exactly one sample.
    """

    tile: tuple[int, int]
    identity: bool
    supported: list[Division]
    unsupported: list[Division]
    message: str
    failing_blocks: dict[str, int] = field(default_factory=dict)

    @property
    def supports_all(self) -> bool:
        """True when no division was found unsupported."""
        return not self.unsupported

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "tile": list(self.tile),
            "K": self.tile[0] * self.tile[1],
            "identity": self.identity,
            "supports_all": self.supports_all,
            "resolutions": [d.as_dict() for d in self.supported],
            "unsupported": [d.as_dict() for d in self.unsupported],
            "failing_blocks": self.failing_blocks,
            "message": self.message,
        }


def verify(code, divisions=None) -> VerifyResult:
    """Check which divisions ``code`` supports (every block holds exactly one sample).

    Parameters
    ----------
    code : ndarray, shape (m, n, K)
        The code to check (an identity code; a multiplexed code supports divisions only
        after demultiplexing, see :mod:`flexvox_core.multiplex`).
    divisions : iterable of Division, optional
        The divisions to check; all of the tile's by default.

    Examples
    --------
    >>> from flexvox_core import code_from_order, sequential_order, parse_division
    >>> r = verify(code_from_order(sequential_order((4, 4))))
    >>> parse_division("2x2x4") in r.unsupported
    True
    """
    c = validate_code(code)
    m, n, _ = c.shape
    divs = enumerate_divisions((m, n)) if divisions is None else [
        check_division(d, (m, n)) for d in divisions
    ]
    identity = is_identity_code(c)
    supported, unsupported, failing = [], [], {}
    for d in divs:
        counts = block_counts(c, d)
        if np.all(counts == 1):
            supported.append(d)
        else:
            unsupported.append(d)
            failing[d.label] = int(np.count_nonzero(counts != 1))
    if not identity:
        message = (
            "not an identity code: pixels open in several slots (or slots reused); "
            "demultiplex before re-binning"
        )
    elif unsupported:
        message = "code does not support " + ", ".join(d.label for d in unsupported)
    else:
        message = f"code supports all {len(supported)} divisions checked"
    return VerifyResult((m, n), identity, supported, unsupported, message, failing)
