"""Integer samples read in relative units: by the dtype's largest value, or by a white level given."""

import numpy as np
import pytest

import flexvox_core as fv
from flexvox_core.intensity import CountsWarning, as_relative


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int16, bool])
def test_narrow_integers_are_divided_by_their_dtype_s_largest_value(dtype):
    top = 1 if dtype is bool else np.iinfo(dtype).max
    np.testing.assert_array_equal(as_relative(np.array([0, top], dtype)), [0.0, 1.0])


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.uint32, np.uint64])
def test_wide_integers_need_their_white_level(dtype):
    # np.round(x * 4095).astype(int) is int64: divided by 2**63 - 1 every count read as 0, a black video
    counts = np.array([0, 2048, 4095], dtype)
    with pytest.raises(ValueError, match=rf"`frames` are {np.dtype(dtype).name} counts and {np.dtype(dtype).name}'s "
                                         rf"largest value \({np.iinfo(dtype).max}\) is no camera's white: give "
                                         r"`white=` where the call takes it \(the count that stands for white, 4095 "
                                         r"for a 12-bit camera\), the counts as uint8 or uint16, or floats in "
                                         r"\[0, 1\] \(counts / white\)"):
        as_relative(counts)
    np.testing.assert_allclose(as_relative(counts, white=4095), [0, 2048 / 4095, 1], rtol=1e-6)


def test_a_reconstruction_and_a_score_of_int64_counts_are_refused_not_black(tmp_path):
    code = fv.design_code((2, 2)).code
    video = fv.render_scene("balls", 4 * 4, 16, 16, seed=0)
    counts = np.round(fv.capture(video, code) * 4095).astype(np.int64)
    with pytest.raises(ValueError, match=r"`frames` are int64 counts .* give `white=`"):
        fv.reconstruct_video(counts, code, "diffusion")
    got = fv.reconstruct_video(counts, code, "diffusion", white=4095)
    assert fv.psnr(video, got) > 20
    with pytest.raises(ValueError, match=r"`ref` are int64 counts .* the counts as uint8 or uint16"):
        fv.psnr(np.round(video * 255).astype(np.int64), got)
    with pytest.raises(ValueError, match=r"`video` are int64 counts"):
        fv.write_video(tmp_path / "never.npy", np.round(video * 255).astype(np.int64))


def test_uint16_counts_within_12_bits_are_read_by_the_rule_with_a_warning():
    import warnings

    counts = np.array([0, 2048, 4095], np.uint16)  # a 12-bit camera's, most likely
    with pytest.warns(CountsWarning, match=r"`frames` are uint16 counts none above 4095: read as 16-bit counts "
                                                 r"\(white 65535\), they lie within \[0, 0.0625\]; a 12-bit camera's "
                                                 r"counts need `white=4095`"):
        got = as_relative(counts)
    np.testing.assert_allclose(got, counts / 65535, rtol=1e-6)  # the stated rule, not a guess
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        as_relative(counts, white=4095)  # the white given: nothing to say
        as_relative(np.array([0, 4096], np.uint16))  # above 12 bits: a 16-bit camera's
        as_relative(np.zeros(3, np.uint16))  # black: no counts to judge by
        as_relative(np.array([0, 255], np.uint8))


def test_a_reconstruction_of_12_bit_counts_without_white_warns():
    code = fv.design_code((2, 2)).code
    counts = np.round(fv.capture(fv.render_scene("balls", 8, 12, 12, seed=0), code) * 4095).astype(np.uint16)
    with pytest.warns(CountsWarning, match=r"`frames` are uint16 counts none above"):
        dark = fv.reconstruct_video(counts, code, "rebin")
    assert dark.max() <= 0.0625
    assert fv.reconstruct_video(counts, code, "rebin", white=4095).max() > 0.5
