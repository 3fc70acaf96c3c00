"""Re-binning's closed-form estimate, compiled a voxel at a time (flexvox_core.accuracy_rebin_kernel), against the
whole-volume numpy form it replaced (tests/flexvox_core/accuracy_rebin_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest

from flexvox_core import capture, render_scene
from flexvox_core.accuracy_rebin import increments, rebin_error
from flexvox_core.design import design_code
from flexvox_core.divisions import Division
from flexvox_core.reconstruct.rebin import default_block

from .accuracy_rebin_reference import increments_reference, rebin_error_reference

CASES = {  # (tile, frames, height, width, dropped frames)
    "4x4, odd sizes": ((4, 4), 3, 9, 13, None),
    "4x4, a dropped frame": ((4, 4), 4, 30, 45, [False, True, False, False]),
    "2x4, odd sizes": ((2, 4), 5, 17, 22, None),
    "4x4, one frame": ((4, 4), 1, 24, 32, None),
}


def _capture(tile, F, H, W, seed=1):
    code = design_code(tile).code
    rng = np.random.default_rng(seed)
    frames = capture(render_scene("balls", F * code.shape[2], H, W, seed=seed), code).astype(np.float64)
    frames += rng.normal(0.0, 0.01, frames.shape)
    return code, frames, rng.uniform(0.5e-4, 2e-4, frames.shape)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("interpolate", [True, False])
def test_the_compiled_estimate_is_the_whole_volume_one(case, interpolate):
    tile, F, H, W, dropped = CASES[case]
    code, frames, var = _capture(tile, F, H, W)
    division = default_block(code)
    dropped = None if dropped is None else np.array(dropped)
    got = rebin_error(frames, code, division, var, interpolate=interpolate, dropped=dropped)
    want = rebin_error_reference(frames, code, division, var, interpolate=interpolate, dropped=dropped)
    # Each voxel's error and each lag's weight are made in the reference's order: the same bits per frame; the clip's
    # mean is the frames' sums added, not numpy's pairwise sum of the whole volume.
    np.testing.assert_array_equal(got.per_frame, want.per_frame)
    assert got.mse == pytest.approx(want.mse, rel=1e-13, abs=0)
    assert (got.beta, got.misfit, got.unspanned, got.samples) == (want.beta, want.misfit, want.unspanned,
                                                                 want.samples)
    assert got.low == pytest.approx(want.low, rel=1e-12) and got.high == pytest.approx(want.high, rel=1e-12)


def test_the_compiled_estimate_with_a_table_and_another_division():
    code, frames, var = _capture((4, 4), 3, 20, 28)
    division = Division(4, 2, 2)
    half = (2 * division.c, 2 * division.a, 2 * division.b)
    table = np.random.default_rng(2).random(tuple(2 * h + 1 for h in half))
    got = rebin_error(frames, code, division, var, table=table)
    want = rebin_error_reference(frames, code, division, var, table=table)
    np.testing.assert_array_equal(got.per_frame, want.per_frame)
    assert got.mse == pytest.approx(want.mse, rel=1e-13, abs=0)


@pytest.mark.parametrize("case", CASES)
def test_the_compiled_increments_are_the_numpy_ones(case):
    tile, F, H, W, dropped = CASES[case]
    code, frames, var = _capture(tile, F, H, W, seed=3)
    dropped = None if dropped is None else np.array(dropped)
    for half in [(8, 4, 4), (2, 1, 3)]:
        got = increments(frames, code, var, half, dropped)
        want = increments_reference(frames, code, var, half, dropped)
        np.testing.assert_array_equal(got.count, want.count)
        np.testing.assert_array_equal(got.mean, want.mean)
