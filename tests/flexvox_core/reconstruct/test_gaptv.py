import numpy as np
import pytest

from flexvox_core.forward import capture, tiled_code
from flexvox_core.metrics import psnr
from flexvox_core.reconstruct import gap_tv, gap_tv_masks, tv_denoise

from .conftest import smooth_video


def _tv(u):
    gx = np.diff(u, axis=-1, append=u[..., -1:])
    gy = np.diff(u, axis=-2, append=u[..., -1:, :])
    return np.sqrt(gx**2 + gy**2).sum()


def test_tv_denoise_lowers_the_rof_energy_and_keeps_constants(rng):
    f = (np.kron(rng.random((4, 4)), np.ones((4, 4))) + 0.2 * rng.standard_normal((16, 16)))
    lam = 0.1
    energy_f = lam * _tv(f)
    prev = energy_f
    for it in (1, 4, 20, 100):
        u = tv_denoise(f, weight=lam, iterations=it, dtype=np.float64)
        e = 0.5 * np.sum((u - f) ** 2) + lam * _tv(u)
        assert e < energy_f
        if it >= 20:
            assert e <= prev + 1e-9  # converging
        prev = e
    assert np.allclose(tv_denoise(np.full((3, 5, 5), 0.7), weight=5.0, iterations=10), 0.7)
    assert np.array_equal(tv_denoise(f, weight=lam, iterations=0, dtype=np.float64), f)


def test_tv_denoise_scale_covariance_and_float32(rng):
    f = rng.random((2, 12, 12))
    u = tv_denoise(f, weight=0.2, iterations=6, dtype=np.float64)
    u255 = tv_denoise(255 * f, weight=0.2 * 255, iterations=6, dtype=np.float64)
    np.testing.assert_allclose(u255 / 255, u, atol=1e-12)
    u32 = tv_denoise(f.astype(np.float32), weight=0.2, iterations=6)
    assert u32.dtype == np.float32
    np.testing.assert_allclose(u32, u, atol=1e-5)


def test_gap_tv_recovers_a_smooth_video_with_an_identity_code(code24, rng):
    video = smooth_video(rng, 16, 24, 24)
    frames = capture(video, code24)
    start = gap_tv(frames, code24, iterations=0)
    out = gap_tv(frames, code24, iterations=30, tv_weight=0.1)
    assert out.shape == video.shape and out.dtype == np.float32
    assert psnr(video, out) > psnr(video, start) + 10
    assert psnr(video, out) > 20  # 22 dB on this small, fast-changing test video


def test_gap_tv_with_a_random_mask_and_the_mask_entry(rng):
    video = smooth_video(rng, 8, 24, 24)
    masks = rng.random((8, 24, 24)) < 0.5
    masks[:, 0, 0] = False  # a pixel never open: R = 0 there
    y = (masks * video).sum(axis=0)
    out = gap_tv_masks(y, masks, iterations=30, tv_weight=0.1)
    assert np.isfinite(out).all()
    assert psnr(video, out) > 19  # 21 dB here; 8 frames from one snapshot
    plain = gap_tv_masks(y, masks, iterations=30, tv_weight=0.1, accelerate=False)
    assert psnr(video, out) > psnr(video, plain)  # acceleration helps at equal iterations


def test_gap_tv_code_entry_is_the_mask_entry_with_the_tiled_code(code24, rng):
    video = rng.random((8, 9, 11)).astype(np.float32)  # border tiles
    frames = capture(video, code24)
    a = gap_tv(frames, code24, iterations=5)
    b = gap_tv_masks(frames, tiled_code(code24, 9, 11), iterations=5)
    np.testing.assert_array_equal(a, b)
    f64 = gap_tv(frames.astype(np.float64), code24, iterations=5, dtype=np.float64)
    np.testing.assert_allclose(a, f64, atol=1e-4)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"iterations": -1}, r"`iterations` must be an integer >= 0; got -1"),
        ({"tv_iterations": 1.5}, r"`tv_iterations` must be an integer >= 0"),
        ({"tv_weight": 0}, r"`tv_weight` must be a positive finite number; got 0"),
        ({"dtype": int}, r"`dtype` must be float32 or float64"),
    ],
)
def test_gap_tv_misuse_is_refused(code22, kw, match):
    with pytest.raises(ValueError, match=match):
        gap_tv(np.zeros((1, 4, 4), np.float32), code22, **kw)


def test_gap_tv_mask_shape_and_nan_are_refused():
    with pytest.raises(ValueError, match=r"`masks` must have shape \(K, H, W\) with \(H, W\) = \(4, 4\)"):
        gap_tv_masks(np.zeros((4, 4)), np.ones((4, 4, 8)))
    y = np.zeros((2, 4, 4))
    y[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"`frames` camera frame 1 holds NaN"):
        gap_tv_masks(y, np.ones((2, 4, 4)))
