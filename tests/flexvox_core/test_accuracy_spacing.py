"""GAP-TV's candidate spacing correction (flexvox_core.accuracy_folds.spacing_ratio) against a closed form."""

from __future__ import annotations

import numpy as np
import pytest

from flexvox_core import capture
from flexvox_core.accuracy_folds import spacing_ratio
from flexvox_core.design import design_code


def test_the_spacing_ratio_of_a_ramp_is_its_increments_ratio():
    code = design_code((2, 4)).code
    m, n, K = code.shape
    g = np.array([0.004, 0.006, 0.0025])  # per sub-frame, row, column: increments (g·h)²
    t, y, x = np.mgrid[0:4 * K, 0:32, 0:48]
    frames = capture(0.1 + g[0] * t + g[1] * y + g[2] * x, code).astype(np.float64)

    def d(dy: int, dx: int) -> float:
        return float((g[1] * dy + g[2] * dx) ** 2)

    lattice = [(a * m, b * n) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    held = min(d(dy, dx) for dy, dx in lattice if (dy, dx) != (0, 0))
    unsampled = [min(d(i - pi + dy, j - pj + dx) for dy, dx in lattice) for pi in range(m) for pj in range(n)
                 for i in range(m) for j in range(n) if (i, j) != (pi, pj)]
    want = float(np.mean(unsampled)) / held  # a ramp: the nearest in its increment, not in pixels
    assert spacing_ratio(frames, code, np.zeros_like(frames)) == pytest.approx(want, rel=0.05)
