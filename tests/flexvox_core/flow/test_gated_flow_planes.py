"""The flow steps that run a sub-frame at a time give the whole-volume forms' values, bit for bit."""

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from flexvox_core.design import design_code
from flexvox_core.flow.backends import make_backend
from flexvox_core.flow.baseline import BOX_COLUMNS, KAverageFlow, box_in_time, kaverage, kaverage_flow
from flexvox_core.flow.estimate import (
    check_video,
    downscale,
    subframe_sums_finite,
    successive_flow,
    to_uint8,
    to_uint8_planes,
)
from flexvox_core.flow.mean_kernel import pair_mean
from flexvox_core.forward import capture
from flexvox_core.motion.pipeline import STEP1_TENSOR, STEP1_TIME, gated_flow
from flexvox_core.reconstruct.diffusion import diffuse
from flexvox_core.simulate.scenes import render_scene

from .gated_reference import gated_flow_reference, successive_flow_reference

CODE = design_code((4, 4)).code


@pytest.fixture(scope="module")
def high_tr():
    """High-TR reconstruction of bouncing balls (moving and still regions, swimming), 40×52, K = 16."""
    truth = render_scene("balls", 4 * 16, 40, 52)
    return diffuse(capture(truth, CODE), CODE, tensor=STEP1_TENSOR, time=STEP1_TIME)


@pytest.mark.parametrize("temporal_window", [0, 1, 2])
@pytest.mark.parametrize("consistency", [False, True])
def test_successive_flow_equals_the_whole_volume_sums(high_tr, temporal_window, consistency):
    small = downscale(high_tr, 0.5)
    got = successive_flow(small, make_backend("dis"), consistency=consistency, temporal_window=temporal_window)
    want = successive_flow_reference(small, make_backend("dis"), consistency=consistency,
                                     temporal_window=temporal_window)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    if consistency:
        assert float(got[1].min()) < 1  # the round trip lowered some confidence: the weights mattered


@pytest.mark.parametrize("kwargs", [{}, {"slow_speed": None}, {"period_gate": None}, {"consistency": True},
                                    {"scale": 1.0}, {"scale": 0.3, "gate": (0.01, 0.5)}])
@pytest.mark.parametrize("K", [1, 8, 16])
def test_gated_flow_equals_the_whole_volume_gate(high_tr, K, kwargs):
    got = gated_flow(high_tr, K, backend="dis", **kwargs)
    want = gated_flow_reference(high_tr, K, backend="dis", **kwargs)
    np.testing.assert_array_equal(got.flow, want.flow)
    np.testing.assert_array_equal(got.confidence, want.confidence)
    assert got.params == want.params


def test_gate_opens_and_closes(high_tr):
    # Not a trivial comparison: the gate both zeroes still voxels and keeps moving ones.
    speed = gated_flow(high_tr, 16, backend="dis").magnitude
    assert float((speed == 0).mean()) > 0.005 and float((speed > 0.5).mean()) > 0.1


def test_kaverage_velocity_of_one_subframe_is_its_plane_of_the_volume(high_tr):
    small = downscale(high_tr, 0.5)
    vel, span = kaverage_flow(small, 16, make_backend("dis"), 4)
    measured = KAverageFlow(small, 16, make_backend("dis"), 4)
    assert measured.span == span
    for s in (0, 7, 31, len(small) - 1):
        np.testing.assert_array_equal(measured.at(s, np.empty_like(vel[s])), vel[s])


def test_check_video_names_the_bad_subframe_and_passes_huge_finite_values():
    v = np.zeros((3, 4, 4))
    v[:] = 1e308  # a float64 sum overflows; every value is finite
    assert check_video(v) is v  # accepted, and returned as it is (no copy)
    v[2, 1, 1] = np.nan
    with pytest.raises(ValueError, match="sub-frame 2"):
        check_video(v)


# The steps between the gated flow's DIS pairs, a sub-frame (or a band of rows) at a time on every core: the
# whole-volume numpy and SciPy calls' values, bit for bit (odd sizes: the bands and the planes do not divide them).

@pytest.mark.parametrize("shape", [(7, 5, 3), (33, 17, 11), (40, 1, 9)])
@pytest.mark.parametrize("size", [2, 5, 16])
def test_box_in_time_is_scipys_uniform_filter(shape, size):
    rng = np.random.default_rng(3)
    v = rng.normal(size=shape).astype(np.float32)
    np.testing.assert_array_equal(box_in_time(v, size), uniform_filter1d(v, size, axis=0, mode="nearest"))
    vectors = rng.normal(size=(*shape, 2)).astype(np.float32)  # the period gate's flow (S, h, w, 2)
    np.testing.assert_array_equal(box_in_time(vectors, size),
                                  uniform_filter1d(vectors, size, axis=0, mode="nearest"))


@pytest.mark.parametrize("size", [1, 3, 7, 16, 17, 50])
@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_box_in_time_compiled_is_scipys_bits_at_odd_sizes_and_long_boxes(size, scale):
    # The compiled running box (several bands of columns: 2 × 41 × 53 × 2 > BOX_COLUMNS) against SciPy itself, bit
    # for bit: boxes odd and even (only a power of two divides exactly), longer than the clip, values far from 1.
    rng = np.random.default_rng(size)
    v = (rng.normal(size=(23, 41, 53, 2)) * scale).astype(np.float32)
    assert v[0].size > BOX_COLUMNS
    want = uniform_filter1d(v, size, axis=0, mode="nearest")
    np.testing.assert_array_equal(box_in_time(v, size).view(np.uint32), want.view(np.uint32))
    strided = v[:, ::2]  # not C-contiguous: read as a copy
    np.testing.assert_array_equal(box_in_time(strided, size),
                                  uniform_filter1d(strided, size, axis=0, mode="nearest"))


@pytest.mark.parametrize("shape", [(1, 4, 5), (2, 3, 1, 2)])
def test_box_in_time_of_one_or_two_sub_frames_and_other_dtypes_is_scipys(shape):
    rng = np.random.default_rng(5)
    v = rng.normal(size=shape).astype(np.float32)
    np.testing.assert_array_equal(box_in_time(v, 16), uniform_filter1d(v, 16, axis=0, mode="nearest"))
    d = rng.normal(size=shape)  # float64: SciPy's own
    got = box_in_time(d, 3)
    assert got.dtype == np.float64
    np.testing.assert_array_equal(got, uniform_filter1d(d, 3, axis=0, mode="nearest"))
    with pytest.raises(RuntimeError, match="incorrect filter size"):
        box_in_time(v, 0)


def test_kaverage_is_the_box_of_K_and_holds_a_clip_at_K_1():
    v = np.random.default_rng(4).random((21, 9, 13), dtype=np.float32)
    np.testing.assert_array_equal(kaverage(v, 8), uniform_filter1d(v, 8, axis=0, mode="nearest"))
    assert kaverage(v, 1) is v


def test_to_uint8_planes_is_to_uint8_of_the_volume():
    rng = np.random.default_rng(5)
    v = rng.uniform(-0.2, 1.2, (19, 7, 11)).astype(np.float32)  # clipped at both ends
    v[3, 2, 2], v[4, 1, 1] = 0.5 / 255, 254.5 / 255  # the rounding's halfway points
    got = to_uint8_planes(v)
    assert got.dtype == np.uint8
    np.testing.assert_array_equal(got, to_uint8(v))
    assert got.min() == 0 and got.max() == 255


@pytest.mark.parametrize("P", [1, 2, 3, 6])
@pytest.mark.parametrize("reach", [0, 1, 2, 3])
def test_pair_mean_is_the_whole_volume_weighted_mean(P, reach):
    """Each centre's weighted mean (the pairs weighed as they are read) against numpy's whole-volume product and
    sums, bit for bit, at odd sizes, with zero confidences, -0 and huge flows."""
    rng = np.random.default_rng(6 + P + 10 * reach)
    h, w = 5, 7
    fwd = (rng.normal(size=(P, h, w, 2)) * rng.choice([1e-3, 1, 1e3], (P, h, w, 2))).astype(np.float32)
    fwd[0, 0, :2] = [[-0.0, -0.0], [3e38, -3e38]]
    conf = rng.random((P, h, w), dtype=np.float32)
    conf[:, 1] = 0
    weighted = fwd * (conf + np.float32(1e-3))[..., None]
    for c in range(P):
        num, den = np.zeros((h, w, 2), np.float32), np.zeros((h, w), np.float32)
        for o in range(-reach, reach + 1):
            if 0 <= c + o < P:
                num += weighted[c + o]
                den += conf[c + o] + np.float32(1e-3)
        with np.errstate(over="ignore", invalid="ignore"):
            want = num / den[..., None]
        got = np.full((h, w, 2), np.nan, np.float32)
        pair_mean(fwd, conf, c, reach, got)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


def test_subframe_sums_finite_finds_any_nan_or_infinity():
    v = np.random.default_rng(7).random((11, 6, 5), dtype=np.float32)
    assert subframe_sums_finite(v)
    for bad in (np.nan, np.inf, -np.inf):
        w = v.copy()
        w[9, 5, 4] = bad
        assert not subframe_sums_finite(w)
        with pytest.raises(ValueError, match="sub-frame 9 holds NaN or infinite values"):
            check_video(w)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_held_as_float16_is_astype(dtype):
    from flexvox_core.motion.stages import held_as

    v = np.random.default_rng(8).normal(0, 1e4, (13, 7, 9)).astype(np.float32).clip(-6e4, 6e4)
    # -0, float16 subnormals and below them, ties to even (1 + 2^-11 -> 1, 1 + 3·2^-11 -> 1 + 2^-9), the largest
    # value that rounds down to 65504 and the first that rounds up to infinity, infinities
    v[0, 0, :] = (-0.0, 6e-8, 2.9e-8, 2.99e-8, 1 + 2**-11, 1 + 3 * 2**-11, 65519.0, 65520.0, np.inf)
    v[1, 0, 0] = -np.inf
    if dtype is np.float64:  # numpy's conversion (it warns of the overflow in its threads): values in range
        v[0, 0, 7:], v[1, 0, 0] = 1.0, 1.0
    v = v.astype(dtype)
    with np.errstate(over="ignore"):
        want = v.astype(np.float16)
    got = held_as(v, np.float16)
    assert got.dtype == np.float16
    np.testing.assert_array_equal(got.view(np.uint16), want.view(np.uint16))  # the bits: -0 is not +0
    assert got[0, 0, 6] == 65504 and got[0, 0, 2] == 0 and got[0, 0, 3] > 0 and np.signbit(got[0, 0, 0])
    assert dtype is np.float64 or np.isinf(got[0, 0, 7])
