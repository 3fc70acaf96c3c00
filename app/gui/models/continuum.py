"""The continuum from high spatial resolution (SR) to high temporal resolution (TR).

The Review workspace has one slider, position ``p`` in [0, 1], that runs from the paper's
high-SR tensor to its high-TR tensor. For **diffusion** it maps to a constant tensor
``(c_x, c_y, c_t)`` whose largest component is always 1 (so the diffusion time ``n``
keeps one meaning along the whole slider), interpolated geometrically::

    p <= 1/2:  (r, r, 1)   with r = 0.05 ** (1 - 2 p)      # p = 0: (0.05, 0.05, 1)  high SR
    p >= 1/2:  (1, 1, r)   with r = 0.05 ** (2 p - 1)      # p = 1: (1, 1, 0.05)     high TR

``p = 0.5`` is isotropic (1, 1, 1); the default tensor (0.15, 0.15, 1) sits at p ≈ 0.18 and
the bench's "between" (0.3, 0.3, 1) at p ≈ 0.30. Every bench tensor family lies on this path,
so the expected-quality figures apply to it.

For **re-binning** the same slider walks the code's supported divisions ordered by TR
(ties: squarest block): p = 0 is ``1×1×K`` [TR 1, SR 1], p = 1 is ``m×n×1`` [TR K, SR 1/K].
GAP-TV has no such knob, and motion-aware chooses the trade per voxel from the flow.
"""

from __future__ import annotations

import math

from flexvox_core.divisions import Division

LOW = 0.05
"""The small eigenvalue of the paper's high-SR (0.05, 0.05, 1) and high-TR (1, 1, 0.05) tensors."""


def _check_p(p) -> float:
    if isinstance(p, bool) or not isinstance(p, int | float) or not math.isfinite(p) or not 0 <= p <= 1:
        raise ValueError(f"`p` must be a number in [0, 1] (0 = high SR, 1 = high TR); got {p!r}")
    return float(p)


def continuum_tensor(p) -> tuple[float, float, float]:
    """The diffusion tensor ``(c_x, c_y, c_t)`` at slider position ``p`` (see the module docstring)."""
    p = _check_p(p)
    if p <= 0.5:
        r = LOW ** (1 - 2 * p)
        return (round(r, 4), round(r, 4), 1.0)
    r = LOW ** (2 * p - 1)
    return (1.0, 1.0, round(r, 4))


def tensor_position(tensor) -> float:
    """The slider position whose tensor is closest to ``tensor`` (inverse of :func:`continuum_tensor`).

    Uses the ratio c_t / mean(c_x, c_y) on a log scale, clipped to the slider's range.
    """
    cx, cy, ct = (float(c) for c in tensor)
    if min(cx, cy, ct) <= 0:
        raise ValueError(f"`tensor` components must be > 0; got {tuple(tensor)!r}")
    ratio = ct / ((cx + cy) / 2)  # 20 at high SR, 1 isotropic, 1/20 at high TR
    p = 0.5 - math.log(ratio) / (2 * math.log(1 / LOW))
    return min(1.0, max(0.0, p))


def ordered_divisions(divisions) -> list[Division]:
    """Divisions from high SR to high TR (TR ascending; squarest block first among ties)."""
    return sorted(divisions, key=lambda d: (d.tr, abs(d.a - d.b), d.a))


def continuum_division(p, divisions) -> Division:
    """The division at slider position ``p`` among ``divisions`` (ordered by :func:`ordered_divisions`)."""
    p = _check_p(p)
    ordered = ordered_divisions(divisions)
    if not ordered:
        raise ValueError("`divisions` is empty: the code supports no division to re-bin at")
    return ordered[min(len(ordered) - 1, int(round(p * (len(ordered) - 1))))]


def describe(p, tensor=None) -> str:
    """Words for the slider position: which way it leans and its tensor (``tensor``: the one used there, when it
    is not :func:`continuum_tensor`'s, e.g. the benched default at its step; written as method labels write it)."""
    p = _check_p(p)
    t = continuum_tensor(p) if tensor is None else tuple(tensor)
    lean = "high SR" if p < 0.4 else "high TR" if p > 0.6 else "balanced"
    return f"{lean}: tensor ({t[0]:g}, {t[1]:g}, {t[2]:g})"
