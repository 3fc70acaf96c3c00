import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from flexvox_core.codes import code_from_order
from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume, tiled_code
from flexvox_core.intensity import CountsWarning
from flexvox_core.simulate import render_scene, simulate_video

from .independent import capture_slow


@st.composite
def video_and_code(draw):
    m, n = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    K = m * n
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if draw(st.booleans()):
        code = code_from_order(rng.permutation(K).reshape(m, n))  # any identity code
    else:
        code = rng.random((m, n, K)) < draw(st.floats(0.1, 0.9))  # any 0/1 code
    F = draw(st.integers(1, 2))
    H, W = draw(st.integers(1, 13)), draw(st.integers(1, 13))  # partial tiles at borders
    dtype = draw(st.sampled_from([np.float32, np.float64]))
    video = rng.random((F * K, H, W)).astype(dtype)
    return video, code


@given(video_and_code())
def test_forward_model_matches_the_definition_bit_for_bit(case):
    video, code = case
    got = capture(video, code)
    want = capture_slow(video, code)
    assert got.dtype == video.dtype
    assert got.shape == want.shape
    assert np.array_equal(got, want)


@given(video_and_code())
def test_identity_capture_is_the_sampled_voxels(case):
    video, code = case
    if not np.all(code.sum(axis=2) == 1) or not np.all(code.sum(axis=(0, 1)) == 1):
        return  # only identity codes have this property
    frames = capture(video, code)
    mask = sample_mask(video.shape, code)
    vol = sparse_volume(frames, code)
    assert np.array_equal(vol[mask], video[mask])
    assert np.all(vol[~mask] == 0)
    assert mask.sum(axis=0).max() == video.shape[0] // code.shape[2]  # one sample per frame


def test_partial_tiles_use_the_matching_part_of_the_code():
    code = design_code((4, 4)).code
    t = tiled_code(code, 6, 7)
    assert t.shape == (16, 6, 7)
    assert np.array_equal(t[:, 4:, 4:], code[:2, :3].transpose(2, 0, 1))


def test_integer_video_becomes_float32():
    code = code_from_order([[0, 1]])
    with pytest.warns(CountsWarning, match=r"`video` are uint16 counts none above 1"):  # within 12 bits: said
        out = capture(np.ones((2, 2, 2), dtype=np.uint16), code)
    assert out.dtype == np.float32


def test_an_integer_video_is_read_in_relative_units_by_its_dtype():
    # an 8-bit clip (np.load of a uint8 movie) is a video in [0, 1], not one 255 times as bright
    code = design_code((2, 2)).code
    video = render_scene("balls", 8, 12, 12, seed=0)
    counts = np.round(video * 255).astype(np.uint8)
    np.testing.assert_allclose(capture(counts, code), capture(counts / np.float32(255), code), atol=1e-6)
    sim = simulate_video(counts, code)
    assert sim.normalised().max() <= 1 and sim.ground_truth.max() <= 1
    with pytest.raises(ValueError, match=r"`video` are int64 counts"):
        capture(counts.astype(np.int64), code)


@pytest.mark.parametrize(
    "video, match",
    [
        (np.zeros((5, 4, 4)), r"length S = 5 must be a positive multiple of K = 4"),
        (np.zeros((4, 4)), r"must have shape \(S, H, W\); got 2 dimensions"),
        (np.zeros((0, 4, 4)), r"length S = 0 must be a positive multiple"),
    ],
)
def test_capture_rejects_bad_shapes(video, match):
    with pytest.raises(ValueError, match=match):
        capture(video, code_from_order([[0, 2], [3, 1]]))


def test_capture_names_the_first_nan_subframe():
    video = np.zeros((8, 4, 4), dtype=np.float32)
    video[6, 1, 2] = np.nan
    video[7, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"sub-frame 6 holds NaN or infinite values"):
        capture(video, code_from_order([[0, 2], [3, 1]]))


def test_sample_mask_and_sparse_volume_errors():
    code = code_from_order([[0, 2], [3, 1]])
    with pytest.raises(ValueError, match=r"S = 6 must be a positive multiple of K = 4"):
        sample_mask((6, 2, 2), code)
    with pytest.raises(ValueError, match=r"not an identity code"):
        sparse_volume(np.zeros((1, 2, 2)), np.ones((2, 2, 4), dtype=bool))
