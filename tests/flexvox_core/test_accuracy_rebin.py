"""Re-binning's closed-form accuracy estimate (flexvox_core.accuracy_rebin) against float64 references."""

from __future__ import annotations

import numpy as np
import pytest

from flexvox_core import Method, capture, estimate_accuracy, render_scene
from flexvox_core.accuracy import NoiseModel, NotEstimable, refusal
from flexvox_core.accuracy_rebin import _blocks, _lags, increments, rebin_error, stencil
from flexvox_core.design import design_code
from flexvox_core.divisions import Division
from flexvox_core.reconstruct.rebin import default_block, rebin

CODE = design_code((4, 4)).code
DIVISION = default_block(CODE)  # 2x2x4
GRAD = np.array([0.004, 0.006, 0.003])  # a ramp's change per sub-frame, row and column


def ramp(S: int, H: int, W: int) -> np.ndarray:
    t, y, x = np.mgrid[0:S, 0:H, 0:W]
    out: np.ndarray = 0.1 + GRAD[0] * t + GRAD[1] * y + GRAD[2] * x
    return out


@pytest.mark.parametrize("interpolate", [True, False])
def test_the_stencil_is_re_binning_float64(interpolate):
    rng = np.random.default_rng(0)
    frames = rng.random((3, 9, 13))  # 9 and 13 not multiples of 2: border blocks filled from their neighbours
    S = 3 * 16
    blocks = _blocks(frames, CODE, DIVISION)
    st = stencil((S, 9, 13), DIVISION, blocks.shape, interpolate=interpolate)
    got = sum(w * blocks.ravel()[b] for b, w in zip(st.block, st.weight, strict=True))
    assert np.allclose(sum(st.weight), 1.0, atol=1e-12)
    assert all(np.array_equal(b, c[st.cell]) for b, c in zip(st.block, st.corner, strict=True))
    np.testing.assert_allclose(got, rebin(frames, CODE, DIVISION, interpolate=interpolate, dtype=np.float64),
                               atol=1e-12)


def test_the_error_identity_is_exact_with_the_truths_increments():
    truth = ramp(64, 24, 32)  # its increment at lag h is (g·h)² everywhere: the clip's mean per lag is exact
    frames = capture(truth, CODE).astype(np.float64)
    true = float(np.mean((rebin(frames, CODE, DIVISION, interpolate=True, dtype=np.float64) - truth) ** 2))
    half = (2 * DIVISION.c, 2 * DIVISION.a, 2 * DIVISION.b)
    table = ((_lags(half) @ GRAD) ** 2).reshape(tuple(2 * h + 1 for h in half))
    got = rebin_error(frames, CODE, DIVISION, np.zeros_like(frames), table=table)
    assert true > 1e-7  # the samples lie off their blocks' centres: the interpolation errs
    assert got.mse == pytest.approx(true, rel=1e-9)


def test_the_increments_between_samples_are_read_exactly():
    frames = capture(ramp(64, 24, 32), CODE).astype(np.float64)
    inc = increments(frames, CODE, np.zeros_like(frames), (8, 4, 4))
    spanned = inc.count > 0
    want = ((_lags((8, 4, 4)) @ GRAD) ** 2).reshape(inc.mean.shape)
    assert spanned.sum() > 50 and not spanned[8, 4, 5] and not spanned[9, 4, 4]  # no pair in a sub-frame or pixel
    np.testing.assert_allclose(inc.mean[spanned], want[spanned], rtol=1e-6, atol=1e-12)


def test_the_fitted_increments_recover_a_ramps_error():
    truth = ramp(64, 24, 32)
    frames = capture(truth, CODE).astype(np.float64)
    true = float(np.mean((rebin(frames, CODE, DIVISION, interpolate=True, dtype=np.float64) - truth) ** 2))
    got = rebin_error(frames, CODE, DIVISION, np.zeros_like(frames))
    assert got.beta == pytest.approx(2.0, abs=0.05)  # a smooth field
    assert got.mse == pytest.approx(true, rel=0.1) and got.low <= true <= got.high


def test_the_noise_term_adds_the_weighted_noise():
    truth = ramp(64, 24, 32)
    clean = capture(truth, CODE).astype(np.float64)
    half = (2 * DIVISION.c, 2 * DIVISION.a, 2 * DIVISION.b)
    table = ((_lags(half) @ GRAD) ** 2).reshape(tuple(2 * h + 1 for h in half))
    var = np.full_like(clean, 1e-4)
    rng = np.random.default_rng(1)
    errs, ests = [], []
    for _ in range(4):
        noisy = clean + rng.normal(0.0, 1e-2, clean.shape)
        errs.append(np.mean((rebin(noisy, CODE, DIVISION, interpolate=True, dtype=np.float64) - truth) ** 2))
        ests.append(rebin_error(noisy, CODE, DIVISION, var, table=table).mse)
    # the pairs' increments with their noise taken out, and the weights' noise added: the noisy error
    assert np.mean(ests) == pytest.approx(np.mean(errs), rel=0.06)  # both vary with the noise: 2-3 % a run
    assert rebin_error(clean, CODE, DIVISION, np.zeros_like(clean), table=table).mse < 0.2 * np.mean(errs)


def test_re_binning_is_estimated_in_closed_form_without_a_run():
    truth = render_scene("balls", 4 * 16, 32, 48, seed=0)
    est = estimate_accuracy(capture(truth, CODE), CODE, Method("rebin"), noise=NoiseModel())
    assert refusal(Method("rebin")) is None
    assert est.runs == 0 and est.scheme.startswith("closed form") and est.low <= est.psnr <= est.high
    assert est.samples == 4 * 32 * 48 and np.isfinite(est.per_frame).all()


def test_re_binning_without_interpolation_is_refused():
    frames = capture(ramp(64, 24, 32), CODE)
    with pytest.raises(NotEstimable, match=r"without interpolation .*\(8 of 12 runs within 1 dB; interval covers 1 "
                                           r"of 12"):
        estimate_accuracy(frames, CODE, Method("rebin", interpolate=False))


def test_re_binning_with_dropped_frames_is_refused():
    frames = capture(ramp(64, 24, 32), CODE)
    with pytest.raises(NotEstimable, match="not been checked on captures with dropped frames"):
        estimate_accuracy(frames, CODE, Method("rebin"), missing=[False, True, False, False])


def test_a_division_other_than_the_codes_default_is_refused():
    frames = capture(ramp(64, 24, 32), CODE)
    with pytest.raises(NotEstimable, match=r"at the code's default division .* but not at the others: -1\.83 to "
                                           r"\+1\.23 dB off the truth, 49 of 68 runs within 1 dB"):
        estimate_accuracy(frames, CODE, Method("rebin", block=Division(4, 2, 2)))
    est = estimate_accuracy(frames, CODE, Method("rebin", block=Division(4, 2, 2)), unchecked=True)
    assert "unchecked" in est.scheme and est.runs == 0


def test_a_division_whose_lags_no_pair_spans_is_refused():
    frames = capture(ramp(64, 24, 32), CODE)  # 1x1x16: each pixel interpolated along its own column only
    with pytest.raises(NotEstimable, match=r"rebin 1x1x16 interp: only 2 lags the interpolation uses are spanned "
                                           r"by 16 or more sample pairs; at least 8 are needed"):
        estimate_accuracy(frames, CODE, Method("rebin", block=Division(1, 1, 16)), unchecked=True)
