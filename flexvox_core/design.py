r"""Code design: the paper's integer program (its Eq. 1) solved with ``scipy.optimize.milp``.

Variables ``x[i, j, s]`` ∈ {0, 1} mark the sampled (pixel, slot) locations of the
m×n×K block. Eq. 1 asks that every block of every division holds exactly one sample:

.. math::

    \sum_{p \in B_{ij}} x_p = 1 \quad \forall B_{ij}, \qquad \sum_p x_p = K.

(The division ``1×1×K`` makes each pixel open exactly once, ``m×n×1`` each slot used
once, so the second sum follows from the first.)

**Secondary objective.** Eq. 1 has many solutions. flexvox picks one whose 4-neighbours
fire far apart in time: it maximises the smallest cyclic firing-time gap ``d`` between
4-neighbours, across tile borders too (tiles repeat over the sensor, and slot K-1 of
one frame is next to slot 0 of the following). A large ``d`` spreads the samples of any
small space-time neighbourhood, so aliasing turns into fine, incoherent noise that
diffusion removes, rather than coherent coded blur. The gap constraint is written as
cliques: for every neighbour pair (p, q) and every cyclic window W of d consecutive
slots, ``Σ_{s∈W} x[p, s] + x[q, s] ≤ 1``.

The search solves Eq. 1 alone first (an infeasible request is answered at once: 6×6 with
all 16 divisions is infeasible, which HiGHS proves in about 9 s), then tries
``d = ⌊K/4⌋`` and, when that fails, bisects between the gap already achieved and ⌊K/4⌋.
Above K = 40 the default skips the gap search (see :data:`GAP_SEARCH_MAX_K`).
⌊K/4⌋ is where the search starts, not a proven bound. It is reached for 2×2, 2×4, 3×3, 3×5,
4×4 and 4×8 (``tests/flexvox_core/test_design.py`` checks these) and for 5×7; the solver proves
⌊K/4⌋+1 infeasible for 2×2, 2×4, 3×3 and 4×4, and for 4×8 reaches its node limit first (no proof
either way). Each MILP has a node limit, so the search is deterministic
(no wall-clock limits decide the answer). Ties are broken by a canonical form: of the
code's images under row flip, column flip, time reversal (and transpose for square
tiles) — all of which keep both the divisions and the gaps — the lexicographically
smallest firing order is returned.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_matrix

from flexvox_core.codes import (
    _neighbour_pairs,
    code_from_order,
    neighbour_separation,
    verify,
)
from flexvox_core.divisions import Division, enumerate_divisions, parse_division
from flexvox_core.reprs import html_table, short_repr
from flexvox_core.tiles import validate_tile

_logger = logging.getLogger(__name__)

STATUS_SUCCESS = 0
STATUS_LIMIT = 1
STATUS_INFEASIBLE = 2

DEFAULT_NODE_LIMIT = 2000
"""Branch-and-bound nodes allowed per MILP: deterministic, unlike a time limit."""

GAP_SEARCH_MAX_K = 40
"""``separation="auto"`` searches the gap only up to this K. Above it (5×8, 6×8, 7×7, 8×8, ...)
the search costs minutes (8×8: gap 14 after 270 s here), so "auto" returns the Eq. 1 code
and says so; demand a gap with an explicit ``separation``."""

SAFETY_TIME_LIMIT_S = 120.0
"""A last-resort wall-clock cap per MILP; never reached for tiles up to 8×8 in our runs."""


@dataclass(frozen=True)
class DesignResult:
    """The outcome of :func:`design_code`, in the spirit of ``scipy.optimize.OptimizeResult``.

    An infeasible request is a result (``success`` False, ``status`` 2, a message),
    not an exception; exceptions are for misuse (a bad tile or division).

    Attributes
    ----------
    status : int
        0 success, 1 a solver limit was reached before a code was found, 2 infeasible.
    success : bool
        True when a code was found.
    message : str
        What happened, in words.
    tile : (int, int)
    order : ndarray of int, shape (m, n), or None
        The firing order (slot of every tile pixel).
    code : ndarray of bool, shape (m, n, K), or None
    divisions : list of Division
        The divisions the design was asked to support.
    supported : list of Division
        Every division of the tile the returned code supports (checked independently).
    separation : int or None
        Smallest cyclic firing-time gap between 4-neighbours of the returned code.
    separation_target : int or None
        The gap the search started from (``⌊K/4⌋``) or the one requested.
    solve_time_s : float
        Wall-clock seconds spent in the solver.
    """

    status: int
    success: bool
    message: str
    tile: tuple[int, int]
    order: np.ndarray | None
    code: np.ndarray | None
    divisions: list[Division]
    supported: list[Division] = field(default_factory=list)
    separation: int | None = None
    separation_target: int | None = None
    solve_time_s: float = 0.0

    @property
    def K(self) -> int:  # noqa: N802 - the paper's name
        """Slots per frame."""
        return self.tile[0] * self.tile[1]

    def _facts(self) -> list[tuple[str, str]]:
        m, n = self.tile
        separation = ("none" if self.separation is None else
                      f"{self.separation} slots (target {self.separation_target})")
        return [("status", f"{self.status} ({'success' if self.success else 'no code'})"),
                ("tile", f"{m}×{n} (K = {self.K})"), ("message", self.message),
                ("divisions asked", ", ".join(d.label for d in self.divisions) or "none"),
                ("divisions supported", ", ".join(d.label for d in self.supported) or "none"),
                ("separation", separation), ("solve time", f"{self.solve_time_s:.2f} s")]

    def __repr__(self) -> str:
        m, n = self.tile
        facts = [f"tile {m}x{n} (K = {self.K})"]
        if self.success:
            facts += [f"{len(self.supported)} divisions supported", f"separation {self.separation}",
                      f"{self.solve_time_s:.2f} s"]
        else:
            facts.append(f"no code (status {self.status}): {self.message}")
        return short_repr("DesignResult", facts)

    def _repr_html_(self) -> str:
        return html_table("DesignResult", self._facts())

    def require(self) -> np.ndarray:
        """The code ``(m, n, K)`` bool; ``ValueError`` naming the tile and the reason when none was found."""
        if not self.success or self.code is None:
            raise ValueError(f"no code for a {self.tile[0]}x{self.tile[1]} tile: {self.message}")
        return self.code

    def as_dict(self) -> dict:
        """JSON-ready form (``tile``, ``K``, ``order``, ``code``, ``resolutions``, ...)."""
        return {
            "status": self.status,
            "success": self.success,
            "message": self.message,
            "tile": list(self.tile),
            "K": self.K,
            "multiplexed": False,
            "order": None if self.order is None else self.order.tolist(),
            "code": None if self.code is None else self.code.astype(int).tolist(),
            "resolutions": [d.as_dict() for d in self.supported],
            "divisions_requested": [d.label for d in self.divisions],
            "separation": self.separation,
            "separation_target": self.separation_target,
            "solve_time_s": round(self.solve_time_s, 4),
        }


def _var(i: int, j: int, s: int, n: int, K: int) -> int:
    return (i * n + j) * K + s


def _division_matrix(m: int, n: int, divisions: list[Division]):
    K = m * n
    # Index of every (i, j, s) variable, arranged so that a block is a sub-array.
    idx = np.arange(m * n * K).reshape(m, n, K)
    rows, cols = [], []
    r = 0
    for d in divisions:
        a, b, c = d.a, d.b, d.c
        blocks = idx.reshape(m // a, a, n // b, b, K // c, c).transpose(0, 2, 4, 1, 3, 5)
        blocks = blocks.reshape(-1, a * b * c)
        rows.append(np.repeat(np.arange(r, r + blocks.shape[0]), blocks.shape[1]))
        cols.append(blocks.ravel())
        r += blocks.shape[0]
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    return coo_matrix((np.ones(rows.size), (rows, cols)), shape=(r, m * n * K)).tocsr()


def _separation_matrix(m: int, n: int, d: int):
    K = m * n
    rows, cols = [], []
    r = 0
    window = np.arange(d)
    for p, q in _neighbour_pairs(m, n):
        for w0 in range(K):
            slots = (w0 + window) % K
            for pix in (p, q):
                rows.append(np.full(d, r))
                cols.append((pix[0] * n + pix[1]) * K + slots)
            r += 1
    if r == 0:
        return None
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    return coo_matrix((np.ones(rows.size), (rows, cols)), shape=(r, m * n * K)).tocsr()


def _solve(m, n, A_div, d, node_limit):
    K = m * n
    constraints = [LinearConstraint(A_div, 1, 1)]
    if d > 1:
        A_sep = _separation_matrix(m, n, d)
        if A_sep is not None:
            constraints.append(LinearConstraint(A_sep, 0, 1))
    res = milp(
        np.zeros(m * n * K),
        constraints=constraints,
        integrality=np.ones(m * n * K),
        bounds=Bounds(0, 1),
        options={"node_limit": int(node_limit), "time_limit": SAFETY_TIME_LIMIT_S},
    )
    if res.x is None:
        return res.status, None
    x = np.round(res.x).reshape(m, n, K).astype(bool)
    return res.status, x.argmax(axis=2).astype(np.int64)


def _canonical(order: np.ndarray) -> np.ndarray:
    """Lexicographically smallest image under the symmetries that keep divisions and gaps."""
    K = order.size
    images = []
    for o in (order, order.T) if order.shape[0] == order.shape[1] else (order,):
        for flip_r in (False, True):
            for flip_c in (False, True):
                for rev in (False, True):
                    x = o[::-1] if flip_r else o
                    x = x[:, ::-1] if flip_c else x
                    x = (K - 1 - x) if rev else x
                    images.append(np.ascontiguousarray(x))
    return min(images, key=lambda x: x.ravel().tolist())


TILES_WITH_CODES = "every tile with both sides at most 6 but 6x6 has one, and 4x8, 5x7 and 8x8 do"
"""Which tiles have an identity code supporting all their divisions (Eq. 1): tests/flexvox_core/test_design.py
solves every tile up to 6x6; 4x8, 5x7 and 8x8 are solved at the defaults."""


def design_code(
    tile,
    *,
    divisions=None,
    separation="auto",
    node_limit: int = DEFAULT_NODE_LIMIT,
) -> DesignResult:
    """Design an identity code whose samples support the requested divisions (Eq. 1).

    Parameters
    ----------
    tile : (int, int) or str
        Tile rows and columns, each 1..8: ``(4, 4)`` or ``"4x4"``.
    divisions : iterable of Division (or its spellings: "2x2x4", "2,2,4", (2, 2, 4)), optional
        Divisions the code must support; all of the tile's by default. ``1×1×K`` and
        ``m×n×1`` are always added: they make it an identity code (every pixel open in
        one slot, every slot used by one pixel).
    separation : "auto" or int, optional
        ``"auto"`` maximises the smallest cyclic firing-time gap between 4-neighbours
        (see the module docstring). An int demands at least that gap (0 or 1: Eq. 1
        alone, the fastest). An int too large for the tile gives an infeasible result.
    node_limit : int, optional
        Branch-and-bound nodes per MILP (keeps the search deterministic).

    Returns
    -------
    DesignResult

    Examples
    --------
    >>> r = design_code((2, 2))
    >>> r.success, r.order.tolist()
    (True, [[0, 2], [3, 1]])
    """
    m, n = validate_tile(tile)
    K = m * n
    if divisions is None:
        divs = enumerate_divisions((m, n))
    else:
        requested = {parse_division(d, (m, n)) for d in divisions}  # "2x2x4", "2,2,4", (2, 2, 4) or a Division
        if not requested:
            raise ValueError("`divisions` must name at least one division")
        # 1×1×K (each pixel open once) and m×n×1 (each slot used once) make it an identity code.
        requested |= {Division(1, 1, K), Division(m, n, 1)}
        divs = sorted(requested, key=lambda d: (d.tr, d.a, d.b))
    skipped = separation == "auto" and K > GAP_SEARCH_MAX_K
    if separation == "auto":
        target = 1 if skipped else max(K // 4, 1)
    elif isinstance(separation, int | np.integer) and not isinstance(separation, bool):
        if separation < 0:
            raise ValueError(f"`separation` must be 'auto' or a whole number >= 0; got {separation}")
        if separation > K // 2:
            raise ValueError(f"`separation` {separation} is more than any {m}x{n} code can have: two of its K = {K} "
                             f"slots are at most {K // 2} apart (cyclically); ask for at most {K // 2}")
        target = max(int(separation), 1)
    else:
        raise ValueError(f"`separation` must be 'auto' or a whole number >= 0; got {separation!r}")
    if node_limit < 1:
        raise ValueError(f"`node_limit` must be >= 1; got {node_limit}")

    A_div = _division_matrix(m, n, divs)
    t0 = time.perf_counter()
    # Eq. 1 alone first: an infeasible request is answered without the gap search.
    status, order = _solve(m, n, A_div, 1, node_limit)
    at_any_gap = order is None  # Eq. 1 alone has no answer: no gap is the reason
    if order is not None and target > 1:
        lo, hi = neighbour_separation(order) or 1, target
        if separation != "auto" and lo < hi:
            # A demanded gap: one solve, its answer is the result.
            status, order = _solve(m, n, A_div, hi, node_limit)
        else:
            # Bisect on the gap: lo is achieved, try the target first, then halve.
            best, d = order, hi
            while lo < hi:
                st, o = _solve(m, n, A_div, d, node_limit)
                _logger.debug("tile %dx%d gap %d: status %d", m, n, d, st)
                if o is not None:
                    best, lo = o, max(d, neighbour_separation(o) or d)
                else:
                    hi = d - 1
                d = (lo + hi + 1) // 2
            order = best
    elapsed = time.perf_counter() - t0

    if order is None:
        if status == STATUS_INFEASIBLE:
            what = "infeasible" if target == 1 or at_any_gap else f"infeasible with a neighbour gap >= {target}"
            if separation != "auto" and target > 1 and not at_any_gap:
                msg = f"no {m}x{n} code has a 4-neighbour gap >= {target} while supporting "
            else:
                msg = f"no {m}x{n} code supports "
            msg += ", ".join(d.label for d in divs) + f": {what}; " + (
                "ask for a smaller neighbour gap, or fewer divisions" if separation != "auto" and target > 1
                and not at_any_gap else f"ask for fewer divisions, or take another tile ({TILES_WITH_CODES})")
        else:
            status = STATUS_LIMIT
            msg = (f"the solver reached its node limit ({node_limit}) before finding a code; ask for fewer "
                   f"divisions or a smaller neighbour gap, or take another tile ({TILES_WITH_CODES})")
        return DesignResult(status, False, msg, (m, n), None, None, divs, [], None,
                            target, elapsed)

    order = _canonical(order)
    code = code_from_order(order)
    check = verify(code)
    missing = [d for d in divs if d not in check.supported]
    if missing:  # cannot happen unless the solver returned a wrong answer; say so loudly
        raise RuntimeError(f"solver returned a code that fails {', '.join(d.label for d in missing)}")
    sep = neighbour_separation(order)
    msg = (
        f"{m}x{n} code supporting {len(check.supported)} of "
        f"{len(enumerate_divisions((m, n)))} divisions; "
        + ("no neighbours (a 1x1 tile)" if sep is None else f"neighbour gap {sep} slot(s)")
    )
    if separation == "auto" and sep is not None and sep < target:
        msg += f" (the search tried {target})"
    if skipped:
        msg += f" (gap search skipped above K = {GAP_SEARCH_MAX_K}; pass a separation to demand one)"
    return DesignResult(STATUS_SUCCESS, True, msg, (m, n), order, code, divs, check.supported,
                        sep, target, elapsed)
