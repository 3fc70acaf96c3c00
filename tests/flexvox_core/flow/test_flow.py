import cv2
import numpy as np
import pytest

from flexvox_core.flow import estimate_flow, flow_to_color, magnitude_image, make_backend, quiver_image
from flexvox_core.flow.backends import dis_finest_scale
from flexvox_core.flow.estimate import consistency_confidence, sanitize_flow
from flexvox_core.simulate.textures import fine_texture, shift_image

from .sanitize_reference import sanitize_reference


@pytest.fixture
def translating(rng):
    tex = fine_texture(96, 128, rng)
    return np.stack([shift_image(tex, 1.5 * s, -0.5 * s) for s in range(5)])


@pytest.mark.parametrize("backend", ["dis", "farneback", "deepflow"])
def test_translation_is_recovered(translating, backend):
    ff = estimate_flow(translating, backend=backend)
    inner = ff.flow[:, 16:-16, 16:-16]
    assert ff.flow.shape == (5, 96, 128, 2) and ff.flow.dtype == np.float32
    assert np.median(inner[..., 0]) == pytest.approx(1.5, abs=0.15)
    assert np.median(inner[..., 1]) == pytest.approx(-0.5, abs=0.15)
    assert ff.confidence[:, 16:-16, 16:-16].mean() > 0.9


def test_no_motion_gives_zero_flow(rng):
    still = np.repeat(fine_texture(64, 80, rng)[None], 4, axis=0)
    ff = estimate_flow(still)
    assert np.abs(ff.flow).max() < 0.1


def test_flow_leaving_the_image_has_zero_confidence():
    fwd = np.zeros((10, 10, 2), np.float32)
    fwd[:, 8:, 0] = 5.0  # points 5 px right, out of a 10 px wide image
    conf = consistency_confidence(fwd, -fwd)
    assert np.all(conf[:, 8:] == 0) and np.all(conf[:, :5] > 0.99)


def test_inconsistent_round_trip_lowers_confidence():
    fwd = np.full((12, 12, 2), 1.0, np.float32)
    assert consistency_confidence(fwd, -fwd)[4:8, 4:8].min() > 0.99
    assert consistency_confidence(fwd, fwd)[4:8, 4:8].max() < 0.05  # backward says the same way: occluded


def test_occlusion_boundary_is_flagged(rng):
    """A textured square moves over a still background: confidence drops where it covers it."""
    bg = fine_texture(64, 96, rng)
    fg = fine_texture(64, 96, np.random.default_rng(7))
    frames = []
    for s in range(4):
        img = bg.copy()
        x0 = 20 + 4 * s
        img[20:44, x0:x0 + 24] = fg[20:44, 20:44]
        frames.append(img)
    ff = estimate_flow(np.stack(frames), scale=1.0)
    assert ff.flow[1, 28:36, 28 + 4:40 + 4, 0].mean() == pytest.approx(4, abs=1)
    assert ff.confidence[1, 10:18, 60:90].mean() > ff.confidence[1, 22:42, 48:52].mean()


def test_sanitize_replaces_nan_and_caps_magnitude():
    f = np.zeros((1, 4, 4, 2), np.float32)
    f[0, 0, 0] = np.nan
    f[0, 1, 1] = [300.0, 400.0]
    g, c = sanitize_flow(f, max_magnitude=50)
    assert np.isfinite(g).all() and c[0, 0, 0] == 0 and c[0, 1, 1] == 1
    assert np.hypot(*g[0, 1, 1]) == pytest.approx(50)


@pytest.mark.parametrize("bad", [None, np.nan, np.inf, -np.inf, 3e38, -3e38])
@pytest.mark.parametrize("max_magnitude", [None, 2.0, 1e3])
@pytest.mark.parametrize("with_confidence", [False, True])
def test_sanitize_flow_gives_the_bits_of_its_float64_sum_form(bad, max_magnitude, with_confidence):
    rng = np.random.default_rng(8)
    f = rng.normal(0, 2, (3, 5, 7, 2)).astype(np.float32)
    if bad is not None:
        f[1, 2, 3, 1] = bad
    conf = rng.uniform(-0.5, 1.5, f.shape[:-1]).astype(np.float32) if with_confidence else None
    if conf is not None:
        conf[0, 0, 0] = np.nan
    got = sanitize_flow(f, conf, max_magnitude=max_magnitude)
    want = sanitize_reference(f, conf, max_magnitude=max_magnitude)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype == np.float32
        np.testing.assert_array_equal(g.view(np.uint32), w.view(np.uint32))
    if bad is not None and not np.isfinite(bad):
        assert got[1][1, 2, 3] == 0 and np.isfinite(got[0]).all()
    empty = sanitize_flow(np.zeros((0, 4, 2), np.float32), max_magnitude=max_magnitude)
    assert empty[0].shape == (0, 4, 2) and empty[1].shape == (0, 4)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"backend": "lk"}, r"unknown flow backend 'lk'; backends: dis, deepflow, farneback, tvl1"),
        ({"backend": "dis", "preset": "slow"}, r"dis.preset must be ultrafast, fast or medium"),
        ({"backend": "dis", "alpha": -1.0}, r"dis.alpha must be a finite number >= 0"),
        ({"backend": "dis", "finest_scale": -1}, r"dis.finest_scale must be None or a whole number >= 0; got -1"),
        ({"backend": "dis", "patch_stride": 0.5}, r"dis.patch_stride must be None or a whole number >= 1; got 0.5"),
        ({"backend": "farneback", "winsize2": 3}, r"flow backend 'farneback' has no parameter 'winsize2'"),
        ({"scale": 0}, r"`scale` must be in \(0, 1\]; got 0"),
        ({"temporal_window": -1}, r"`temporal_window` must be a whole number >= 0"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        estimate_flow(np.zeros((3, 16, 16), np.float32), **kwargs)


def test_bad_videos():
    with pytest.raises(ValueError, match=r"at least 2 sub-frames"):
        estimate_flow(np.zeros((1, 16, 16)))
    v = np.zeros((3, 16, 16))
    v[2, 1, 1] = np.inf
    with pytest.raises(ValueError, match=r"sub-frame 2 holds NaN or infinite values"):
        estimate_flow(v)


@pytest.mark.parametrize("shape, finest", [((80, 106), 2), ((48, 64), 1), ((16, 16), 0), ((160, 213), 2)])
def test_dis_searches_no_coarser_than_the_images_coarsest_level(shape, finest):
    # OpenCV reads past its buffers when the finest level is coarser than the coarsest (it crashed at 48x64).
    assert dis_finest_scale(shape, 2, 8) == finest
    rng = np.random.default_rng(0)
    a = (rng.random(shape) * 255).astype(np.uint8)
    flow = make_backend("dis", finest_scale=2, variational_iterations=2)(a, np.roll(a, 1, axis=1))
    assert flow.shape == (*shape, 2) and np.isfinite(flow).all()


def test_dis_overrides_change_the_flow():
    rng = np.random.default_rng(1)
    a = cv2.GaussianBlur((rng.random((80, 106)) * 255).astype(np.uint8), (0, 0), 2)
    b = np.roll(a, 2, axis=1)
    medium = make_backend("dis")(a, b)
    assert np.array_equal(make_backend("dis", finest_scale=1, patch_stride=3)(a, b), medium)  # the preset's own
    assert not np.array_equal(make_backend("dis", finest_scale=2)(a, b), medium)


def test_every_backend_builds_with_named_parameters():
    assert make_backend("farneback", winsize=21).winsize == 21
    assert make_backend("tvl1", warps=3).warps == 3


def test_color_wheel_coding():
    flow = np.zeros((3, 3, 2), np.float32)
    flow[0, 0] = [1, 0]  # right
    flow[0, 1] = [-1, 0]  # left
    flow[0, 2] = [np.nan, 0]
    img = flow_to_color(flow)
    assert img.dtype == np.uint8 and img.shape == (3, 3, 3)
    assert img[1, 1].tolist() == [255, 255, 255]  # still: white
    assert img[0, 0, 0] > 200 and img[0, 0, 2] < 60  # right: red
    assert img[0, 1, 0] < 60 and img[0, 1, 2] > 150  # left: cyan/blue side
    assert img[0, 2].tolist() == [0, 0, 0]  # invalid: black


def test_magnitude_and_quiver_pictures():
    flow = np.zeros((32, 32, 2), np.float32)
    flow[8:24, 8:24] = [2.0, 0]
    mag = magnitude_image(flow)
    assert mag.shape == (32, 32, 3) and mag[16, 16, 0] > mag[0, 0, 0]  # fast = red
    q = quiver_image(np.full((32, 32), 0.5), flow, step=8)
    assert q.shape == (32, 32, 3) and (q != 127).any()
    with pytest.raises(ValueError, match=r"must share \(H, W\)"):
        quiver_image(np.zeros((8, 8)), flow)


def test_tiny_images_are_padded_for_the_backend(rng):
    v = rng.random((3, 6, 9)).astype(np.float32)
    ff = estimate_flow(v)
    assert ff.flow.shape == (3, 6, 9, 2) and np.isfinite(ff.flow).all()
