"""The one check of a positive real parameter (a diffusion time, a TV weight, a data range, a time step)."""

from __future__ import annotations

import math


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
