"""A camera's frame rate and a recording's rates: the limit flexvox plans, simulates and records within, and what
makes a recording's ``rates`` attribute unusable (every time step and frame interval is read from it)."""

from __future__ import annotations

import math

MAX_CAMERA_HZ = 10_000.0
"""The fastest camera frame rate flexvox plans, simulates or records (a capture plan's and a scene file's limit)."""


def rate_problems(rates, K: int) -> list[str]:
    """What is wrong with a recording's ``rates`` attribute: both rates finite numbers above 0, the sub-frame
    rate K times the camera's (every time step and frame interval is read from them)."""
    if not isinstance(rates, dict):
        return [f"the `rates` attribute must be a mapping of camera_hz and subframe_hz; got {rates!r}"]
    problems = []
    values = {}
    for name in ("camera_hz", "subframe_hz"):
        value = rates.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float) or not (math.isfinite(value) and value > 0):
            problems.append(f"rate `{name}` must be a finite number of Hz above 0; got {value!r}")
        else:
            values[name] = float(value)
    if not problems and not math.isclose(values["subframe_hz"], values["camera_hz"] * K, rel_tol=1e-9):
        problems.append(f"rate `subframe_hz` {values['subframe_hz']:g} is not K = {K} times `camera_hz` "
                        f"{values['camera_hz']:g}")
    return problems
