"""The checks of real-number parameters: a positive one (a diffusion time, a TV weight, a data range, a time
step), one with any rule (:func:`checked_number`), and a (low, high) pair (:func:`number_pair`)."""

from __future__ import annotations

import math


def flag(name: str, value) -> bool:
    """``value`` as a bool when it is True or False (a numpy bool too); ``TypeError`` naming ``name`` otherwise: a
    string such as ``"no"`` is true to Python, and would do the opposite of what it says."""
    numpy_bool = getattr(getattr(value, "dtype", None), "kind", None) == "b" and getattr(value, "ndim", 1) == 0
    if not (isinstance(value, bool) or numpy_bool):
        raise TypeError(f"{name} must be True or False; got {value!r}")
    return bool(value)


def positive_number(name: str, value, *, unit: str = "") -> float:
    """``value`` as a float when it is a finite number above 0; otherwise a ``ValueError`` naming
    ``name``, the rule and the value ("`time` must be a positive finite number; got 0")."""
    what = f"a positive finite number{' of ' + unit if unit else ''}"
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {what}; got {value!r}") from None
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be {what}; got {value!r}")
    return number


def checked_number(name: str, value, rule: str, ok) -> float:
    """``value`` as a float when it is a real number (not a bool, not a string) that is finite and meets ``ok``;
    otherwise a ``ValueError`` naming ``name``, the ``rule`` in words and the value
    ("`still_speed` must be a number >= 0 (px per sub-frame) or None; got -1")."""
    if (isinstance(value, bool) or not isinstance(value, int | float) and not _is_numpy_real(value)
            or not math.isfinite(value) or not ok(value)):
        raise ValueError(f"`{name}` must be {rule}; got {value!r}")
    return float(value)


def number_pair(name: str, value, rule: str = "two numbers (lo, hi)") -> tuple[float, float]:
    """``value`` as two floats (lo, hi), or a ``ValueError`` naming ``name`` and ``rule``; the caller checks
    how the two relate."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"`{name}` must be {rule}; got {value!r}") from None
    return lo, hi


def _is_numpy_real(value) -> bool:
    import numpy as np

    return isinstance(value, np.integer | np.floating)
