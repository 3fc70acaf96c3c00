import pickle
import warnings

import numpy as np
import pytest

from flexvox_core.metrics import psnr, psnr_per_frame, ssim, ssim_per_frame


def test_psnr_known_value_and_identity(rng):
    ref = rng.random((3, 16, 16))
    x = ref + 0.01  # MSE 1e-4 -> 40 dB at data range 1
    assert np.allclose(psnr_per_frame(ref, x), 40.0)
    assert psnr(ref, x) == pytest.approx(40.0)
    assert psnr(ref, x, data_range=255) == pytest.approx(40.0 + 20 * np.log10(255))
    assert np.all(np.isinf(psnr_per_frame(ref, ref))) and psnr(ref, ref) == np.inf


def test_psnr_per_frame_differs(rng):
    ref = np.zeros((2, 8, 8))
    x = ref.copy()
    x[0] += 0.1
    x[1] += 0.01
    assert psnr_per_frame(ref, x).round(6).tolist() == [20.0, 40.0]


def test_ssim_identical_is_one_and_noise_lowers_it(rng):
    ref = rng.random((2, 32, 32))
    assert ssim(ref, ref) == pytest.approx(1.0, abs=1e-12)
    noisy = ref + 0.2 * rng.standard_normal(ref.shape)
    s = ssim_per_frame(ref, noisy)
    assert np.all(s < 0.9)
    assert np.all(s > -1)


def test_ssim_of_two_constant_images_is_the_luminance_term():
    a, b = 0.3, 0.6
    c1 = (0.01 * 1.0) ** 2
    want = (2 * a * b + c1) / (a * a + b * b + c1)
    got = ssim(np.full((1, 20, 20), a), np.full((1, 20, 20), b))
    assert got == pytest.approx(want, rel=1e-9)


def test_ssim_is_symmetric_and_scale_invariant_with_data_range(rng):
    a = rng.random((1, 24, 24))
    b = np.clip(a + 0.1 * rng.standard_normal(a.shape), 0, 1)
    assert ssim(a, b) == pytest.approx(ssim(b, a), rel=1e-12)
    assert ssim(255 * a, 255 * b, data_range=255) == pytest.approx(ssim(a, b), rel=1e-9)


@pytest.mark.parametrize(
    ("ref", "x", "kw", "match"),
    [
        (np.zeros((2, 4, 4)), np.zeros((2, 4, 5)), {}, r"`x` must have the shape of `ref`"),
        (np.zeros(4), np.zeros(4), {}, r"`ref` must have shape \(S, H, W\)"),
        (np.zeros((2, 4, 4)), np.zeros((2, 4, 4)), {"data_range": 0}, r"`data_range` must be a positive"),
    ],
)
def test_metric_misuse_is_refused(ref, x, kw, match):
    with pytest.raises(ValueError, match=match):
        psnr(ref, x, **kw)
    with pytest.raises(ValueError, match=match):
        ssim(ref, x, **kw)


def test_nan_names_the_frame():
    x = np.zeros((3, 4, 4))
    x[2, 1, 1] = np.nan
    with pytest.raises(ValueError, match=r"`x` frame 2 holds NaN"):
        psnr(np.zeros((3, 4, 4)), x)


def test_psnr_of_float32_volumes_is_the_float64_figure(rng):
    # float32 volumes: the difference and its square in float32 (summed in float64), a frame at a time;
    # within 1e-6 dB of the float64 figure. float64 volumes: the float64 figure itself.
    ref = rng.random((5, 31, 17)).astype(np.float32)
    x = (ref + rng.normal(0, 0.05, ref.shape)).astype(np.float32)
    expected = 10 * np.log10(1 / np.mean((ref.astype(np.float64) - x.astype(np.float64)) ** 2, axis=(1, 2)))
    np.testing.assert_allclose(psnr_per_frame(ref, x), expected, rtol=0, atol=1e-6)
    x64 = x.astype(np.float64) + rng.normal(0, 1e-9, x.shape)  # not a float32 value: float64 throughout
    want64 = 10 * np.log10(1 / np.mean((ref.astype(np.float64) - x64) ** 2, axis=(1, 2)))
    np.testing.assert_allclose(psnr_per_frame(ref, x64), want64, rtol=1e-12)


def test_psnr_of_16_bit_frames_is_exact(rng):
    # Integers up to 16 bits are float32 values: their differences are exact, the squares rounded once.
    ref = rng.integers(0, 65536, (3, 20, 30)).astype(np.uint16)
    x = rng.integers(0, 65536, (3, 20, 30)).astype(np.uint16)
    d = ref.astype(np.int64) - x.astype(np.int64)
    expected = 10 * np.log10(65535.0**2 / (d * d).mean(axis=(1, 2)))
    np.testing.assert_allclose(psnr_per_frame(ref, x, data_range=65535), expected, rtol=0, atol=1e-6)


@pytest.mark.parametrize("value", [0, -1.0, float("nan"), float("inf"), "two", None])
def test_one_check_for_positive_numbers(value):
    from flexvox_core.numbers import positive_number

    with pytest.raises(ValueError, match=r"^`data_range` must be a positive finite number; got "):
        positive_number("`data_range`", value)
    assert positive_number("x", "2.5") == 2.5


def test_psnr_of_rows_reads_the_reference_a_few_frames_at_a_time(rng):
    from flexvox_core.metrics import psnr_of_rows

    ref = rng.random((37, 6, 5)).astype(np.float32)
    x = ref + rng.normal(0, 0.05, ref.shape).astype(np.float32)
    x[7] = ref[7]  # an exact frame: inf, and so is the mean
    calls = []

    def read(a, b):
        calls.append((a, b))
        return ref[a:b]

    got = psnr_of_rows(read, x, rows=16)
    np.testing.assert_array_equal(got.per_frame, psnr_per_frame(ref, x))
    assert got.mean == psnr(ref, x) == np.inf
    assert calls == [(0, 16), (16, 32), (32, 37)]
    with pytest.raises(ValueError, match=r"`rows` must be a whole number >= 1; got 0"):
        psnr_of_rows(read, x, rows=0)


@pytest.mark.parametrize("scale", [1e21, 1e-20, 1e-25])
def test_psnr_of_float32_frames_at_extreme_scales_is_the_float64_figure(rng, scale):
    # Float32 squares would overflow (1e21) or fall below float32's normal range (1e-20, 1e-25): such frames are
    # taken again in float64.
    ref = (rng.random((2, 9, 7)) * scale).astype(np.float32)
    x = (ref + rng.normal(0, 0.1 * scale, ref.shape)).astype(np.float32)
    d = ref.astype(np.float64) - x.astype(np.float64)
    expected = 10 * np.log10(scale**2 / (d * d).mean(axis=(1, 2)))
    got = psnr_per_frame(ref, x, data_range=scale)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)


def test_psnr_refuses_complex_frames():
    with pytest.raises(ValueError, match=r"`x` must hold real numbers; got dtype complex64"):
        psnr(np.zeros((1, 2, 2)), np.zeros((1, 2, 2), np.complex64))


def test_psnr_of_rows_names_the_sub_frames_of_a_bad_block(rng):
    from flexvox_core.metrics import psnr_of_rows

    ref = rng.random((40, 3, 4)).astype(np.float32)
    ref[21, 1, 1] = np.nan
    with pytest.raises(ValueError, match=r"^sub-frames 16\.\.31: `ref` frame 5 holds NaN"):
        psnr_of_rows(lambda a, b: ref[a:b], ref.copy(), rows=16)


def test_psnr_and_ssim_return_a_float_like_scikit_image(rng):
    ref = rng.random((3, 16, 16))
    x = ref + 0.01 * rng.standard_normal(ref.shape)
    for score, per_frame in ((psnr, psnr_per_frame), (ssim, ssim_per_frame)):
        value = score(ref, x)
        assert isinstance(value, float) and repr(value) == repr(float(value))
        assert value == pytest.approx(float(np.mean(per_frame(ref, x))), rel=1e-12)
        assert type(pickle.loads(pickle.dumps(value))) is float


def test_old_frame_scores_fields_warn_for_one_release(rng):
    ref = rng.random((2, 16, 16))
    x = ref + 0.01
    with pytest.warns(DeprecationWarning, match=r"psnr\(\) returns a float now .*`\.mean` .*goes in flexvox 0\.3"):
        mean = psnr(ref, x).mean
    assert mean == pytest.approx(40.0) and type(mean) is float
    with pytest.warns(DeprecationWarning, match=r"use `ssim_per_frame\(ref, x\)`"):
        per = ssim(ref, x).per_frame
    np.testing.assert_array_equal(per, ssim_per_frame(ref, x))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert psnr(ref, x) + 0 == pytest.approx(40.0)  # plain use warns nothing


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_an_integer_truth_against_a_float_estimate_is_compared_in_0_1(rng, dtype):
    white = np.iinfo(dtype).max
    truth = rng.integers(0, white, (2, 16, 16), endpoint=True).astype(dtype)
    estimate = np.clip(truth / white + rng.normal(0, 0.05, truth.shape), 0, 1).astype(np.float32)
    as_float = truth.astype(np.float64) / white
    assert psnr(truth, estimate) == pytest.approx(psnr(as_float, estimate), abs=1e-5)
    assert psnr(estimate, truth) == pytest.approx(psnr(estimate, as_float), abs=1e-5)
    assert 20 < psnr(truth, estimate) < 30
    assert ssim(truth, estimate) == pytest.approx(ssim(as_float, estimate), abs=1e-6)
    with pytest.raises(ValueError, match=rf"`ref` is {np.dtype(dtype)} and `x` is float32: the {np.dtype(dtype)} one "
                                         rf"is read in \[0, 1\] \(divided by {white}, as skimage.util.img_as_float "
                                         r"does\), so `data_range` must be 1; got 255"):
        psnr(truth, estimate, data_range=255)
    # Two integer arrays are compared as they are, with the data range given.
    assert psnr(truth, truth // 2 * 2, data_range=white) == pytest.approx(
        psnr(as_float, (truth // 2 * 2) / white), abs=1e-5)


def test_two_integer_arrays_in_other_units_are_refused_not_scored(rng):
    # a uint8 truth against a uint16 estimate scored -90 dB, two uint8 arrays at the default data range -14 dB
    truth = rng.integers(0, 256, (2, 16, 16)).astype(np.uint8)
    with pytest.raises(ValueError, match=r"`ref` is uint8 and `x` is uint16: two integer dtypes have two white levels; "
                                         r"give both as one dtype, or as floats in \[0, 1\]"):
        psnr(truth, truth.astype(np.uint16) * 257)
    with pytest.raises(ValueError, match=r"`ref` and `x` are uint8 counts, compared in counts: `data_range` must be "
                                         r"their white \(255 for uint8\); got 1"):
        ssim(truth, truth)
    assert psnr(truth, truth // 2 * 2, data_range=255) > 40
    assert psnr(truth > 128, truth > 100) < 20  # bool arrays: 0 and 1, the data range 1


def test_float_arrays_in_another_unit_than_the_data_range_are_refused_not_scored(rng):
    # a float truth in 0..255 against a reconstruction in [0, 1] scored -43 dB (SSIM 2e-5); two videos in [0, 1]
    # at data_range=255 scored 48 dB too high (68 dB)
    truth = rng.random((3, 16, 16)).astype(np.float32)
    x = np.clip(truth + 0.05 * rng.standard_normal(truth.shape), 0, 1).astype(np.float32)
    for metric in (psnr, ssim, psnr_per_frame):
        with pytest.raises(ValueError, match=r"`ref` holds values from \d.* to 2\d\d.*, but `data_range` is 1 \(a "
                                             r"float array must lie within \[-1, 2\], -data_range to 2·data_range\): "
                                             r"8-bit values in a float array\? divide by 255"):
            metric(truth * 255, x)
        with pytest.raises(ValueError, match=r"`x` holds values from .* but `data_range` is 1"):
            metric(np.round(truth * 255).astype(np.uint8), x * 255)  # the uint8 truth is read in [0, 1]
        with pytest.raises(ValueError, match=r"`ref` and `x` both lie in \[0, 1\], but `data_range` is 255: the PSNR "
                                             r"would be 48.1 dB too high; videos in \[0, 1\] take data_range=1"):
            metric(truth, x, data_range=255)
    assert psnr(truth * 255, x * 255, data_range=255) == pytest.approx(psnr(truth, x), abs=1e-4)  # one unit: scored
    assert np.isfinite(psnr(truth, x - 0.5))  # within [-1, 2]: scored as before


def test_clip_psnr_is_of_the_clip_mse_in_float64_and_from_the_frames_scores(rng):
    from flexvox_core.metrics import clip_psnr, psnr_of_rows

    ref = rng.random((5, 7, 9))
    x = ref + rng.normal(0, 1, (5, 1, 1)) * 0.05 * rng.random((5, 7, 9))  # errors that differ frame to frame
    want = 10 * np.log10(1.0 / np.mean((x - ref) ** 2))
    assert clip_psnr(ref, x) == pytest.approx(want, abs=1e-9)
    assert clip_psnr(ref, x) < psnr(ref, x)  # the frames' mean is higher where their errors differ
    assert psnr_of_rows(lambda a, b: ref[a:b], x, rows=2).clip == pytest.approx(want, abs=1e-9)
    assert clip_psnr(255 * ref, 255 * x, data_range=255) == pytest.approx(want, abs=1e-9)
    assert clip_psnr(ref, ref) == np.inf
