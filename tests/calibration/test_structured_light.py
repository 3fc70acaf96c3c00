"""Gray-code and phase-shift patterns and their decoding, on synthetic captures."""

import cv2
import numpy as np
import pytest

from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.structured_light import (
    decode_gray,
    decode_phase,
    gray_code_patterns,
    phase_patterns,
    shadow_mask_patterns,
    unwrap,
)


def test_gray_decoding_agrees_with_opencv_getprojpixel():
    size = (24, 40)
    pats, bx, by = gray_code_patterns(size)
    assert pats.shape == (2 * (bx + by), 24, 40) and (bx, by) == (6, 5)
    # An ideal capture: a camera that sees the projector shifted by (3, 2) pixels, on a textured wall.
    rng = np.random.default_rng(1)
    albedo = rng.uniform(0.3, 1.0, (20, 30))
    imgs = np.stack([np.roll(np.roll(p, -2, axis=0), -3, axis=1)[:20, :30] * albedo * 200 + 10 for p in pats])
    col, row, margin = decode_gray(imgs, bx, by, size)
    np.testing.assert_array_equal(col, np.broadcast_to(np.arange(30) + 3, (20, 30)))
    np.testing.assert_array_equal(row, np.broadcast_to((np.arange(20) + 2)[:, None], (20, 30)))
    assert margin.min() > 0
    gen = cv2.structured_light.GrayCodePattern.create(40, 24)
    u8 = [img.astype(np.uint8) for img in imgs]
    for y, x in [(0, 0), (5, 7), (19, 29), (11, 16)]:
        err, (px, py) = gen.getProjPixel(u8, x, y)
        assert not err and (px, py) == (col[y, x], row[y, x])


def test_shadow_mask_patterns_are_black_and_white():
    black, white = shadow_mask_patterns((6, 8))
    assert not black.any() and white.all() and black.shape == (6, 8)


@pytest.mark.parametrize("u0", [0.0, 0.3, 5.5, 11.75])
def test_phase_decoding_recovers_subpixel_positions_of_blurred_square_waves(u0):
    # Camera pixels that see projector coordinate u = u0 + 0.37·i, under an area + Gaussian blur.
    P, N = 16, 8
    pats = phase_patterns((1, 64), "x", period=P, steps=N)[:, 0].astype(float)  # (N, 64)
    fine = 32
    xs = (np.arange(64 * fine) + 0.5) / fine - 0.5  # sub-samples of the mirrors
    us = u0 + 0.37 * np.arange(80) + 8
    imgs = []
    for p in pats:
        light = p[np.clip(np.rint(xs).astype(int), 0, 63)]
        blurred = cv2.GaussianBlur(light[None].astype(np.float64), (0, 0), 0.6 * fine)[0]
        imgs.append(np.interp(us, xs, blurred))
    frac, amp = decode_phase(np.asarray(imgs)[:, None, :], period=P)
    err = unwrap(frac[0], np.rint(us), P) - us
    # Square-wave harmonics alias into a bias that repeats every P/N = 2 px (see the module
    # docstring): bounded per pixel, and it averages out over sub-pixel positions.
    assert np.abs(err).max() < 0.2
    assert abs(err.mean()) < 0.02
    assert amp.min() > 0.2


def test_unwrap_picks_the_period_nearest_the_gray_code():
    assert unwrap(np.array([1.0]), np.array([34.0]), 16)[0] == 33.0
    assert unwrap(np.array([15.5]), np.array([0.0]), 16)[0] == -0.5


def test_phase_patterns_refuse_bad_arguments():
    with pytest.raises(CalibrationError, match="`axis` must be 'x' or 'y'; got 'z'"):
        phase_patterns((4, 4), "z")
    with pytest.raises(CalibrationError, match="`period` must be even, >= 4 and a multiple of `steps`"):
        phase_patterns((4, 4), "x", period=10, steps=4)
    with pytest.raises(CalibrationError, match=r"`images` must be 6 Gray-code captures"):
        decode_gray(np.zeros((4, 2, 2)), 2, 1, (2, 4))
