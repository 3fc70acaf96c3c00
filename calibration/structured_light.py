"""Structured-light patterns for the projector→camera correspondence, and their decoding.

Gray code
    :class:`cv2.structured_light.GrayCodePattern` generates the patterns: for every bit
    (columns first, most significant bit first, then rows) a pattern and its inverse
    (images ``2i`` and ``2i + 1``). A bit is 1 where the pattern is brighter than its
    inverse, so the scene's texture and ambient light cancel. :func:`decode_gray` is a
    vectorised equivalent of ``GrayCodePattern.getProjPixel`` (the tests check that they
    agree) that keeps pixels whose least significant bits are ambiguous: the phase shift
    below needs the Gray code only to within half a phase period.

Phase shifting (sub-pixel)
    A DMD shows binary patterns only, so the "fringes" are square waves of period ``P``
    projector pixels shown at ``N`` shifts of ``P/N`` pixels. A camera pixel at projector
    coordinate ``u`` sees ``I_k = A + B·cos(2π(u − c₀ − kP/N)/P) + harmonics``, where
    ``c₀ = (P/2 − 1)/2`` is the centre of the lit half-period of pattern 0 (mirror ``x``
    covers ``[x − ½, x + ½]``). The first DFT bin over k gives
    ``u = c₀ + P·arg(Σ_k I_k e^{2πik/N}) / 2π (mod P)``, and the Gray code picks the period.
    Odd harmonics of the square wave alias into that bin (h = N ± 1) and bias ``u`` by a
    pattern that repeats every ``P/N`` projector pixels; defocus and the camera pixel's area
    attenuate them, and what remains averages out in the homography fit over thousands of
    pixels at every sub-pixel position.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from flexvox_calibration.errors import CalibrationError


def gray_code_patterns(projector_size) -> tuple[np.ndarray, int, int]:
    """Gray-code patterns for a projector of ``(H, W)`` pixels.

    Returns
    -------
    patterns : ndarray, shape (2·(bits_x + bits_y), H, W), bool
        OpenCV's order: for each bit a pattern then its inverse; column bits first.
    bits_x, bits_y : int
        Bits for columns and rows.
    """
    Hp, Wp = projector_size
    gen = cv2.structured_light.GrayCodePattern.create(int(Wp), int(Hp))
    ok, images = gen.generate()
    if not ok:  # pragma: no cover - OpenCV does not fail for valid sizes
        raise CalibrationError(f"OpenCV could not generate Gray codes for {Hp}x{Wp}")
    bits_x = math.ceil(math.log2(Wp))
    bits_y = math.ceil(math.log2(Hp))
    pats = np.asarray(images) > 0
    if pats.shape[0] != 2 * (bits_x + bits_y):  # pragma: no cover - OpenCV's documented layout
        raise CalibrationError(f"unexpected Gray-code layout from OpenCV: {pats.shape[0]} images")
    return pats, bits_x, bits_y


def shadow_mask_patterns(projector_size) -> tuple[np.ndarray, np.ndarray]:
    """The all-black and all-white projector images (``getImagesForShadowMasks``), bool."""
    Hp, Wp = projector_size
    gen = cv2.structured_light.GrayCodePattern.create(int(Wp), int(Hp))
    black, white = gen.getImagesForShadowMasks(np.zeros((Hp, Wp), np.uint8), np.zeros((Hp, Wp), np.uint8))
    return np.asarray(black) > 0, np.asarray(white) > 0


def _gray_to_binary(bits: np.ndarray) -> np.ndarray:
    """``bits (nbits, ...)`` Gray code, MSB first → integer values ``(...)``."""
    value = np.zeros(bits.shape[1:], np.int64)
    b = np.zeros(bits.shape[1:], bool)
    for i in range(bits.shape[0]):
        b = b ^ bits[i]
        value = (value << 1) | b
    return value


def decode_gray(images, bits_x: int, bits_y: int, projector_size) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode captured Gray-code images into projector column and row per camera pixel.

    Parameters
    ----------
    images : ndarray, shape (2·(bits_x + bits_y), H, W)
        Captures of :func:`gray_code_patterns`, same order.
    bits_x, bits_y : int
    projector_size : (Hp, Wp)

    Returns
    -------
    col, row : ndarray (H, W) int
        The decoded projector column and row.
    margin : ndarray (H, W) float
        The weakest ``|pattern − inverse|`` of the two most significant bits of each axis
        (how clearly the coarse code was seen).
    """
    imgs = np.asarray(images, dtype=np.float64)
    n = bits_x + bits_y
    if imgs.ndim != 3 or imgs.shape[0] != 2 * n:
        raise CalibrationError(f"`images` must be {2 * n} Gray-code captures (H, W); got shape {imgs.shape}")
    diff = imgs[0::2] - imgs[1::2]
    bits = diff > 0
    col = _gray_to_binary(bits[:bits_x])
    row = _gray_to_binary(bits[bits_x:])
    coarse = np.concatenate([np.abs(diff[:min(2, bits_x)]), np.abs(diff[bits_x:bits_x + min(2, bits_y)])])
    margin = coarse.min(axis=0)
    Hp, Wp = projector_size
    col = np.where(col < Wp, col, -1)
    row = np.where(row < Hp, row, -1)
    return col, row, margin


def phase_patterns(projector_size, axis: str, *, period: int = 16, steps: int = 8) -> np.ndarray:
    """Binary square waves of ``period`` projector pixels at ``steps`` shifts, ``(steps, H, W)`` bool.

    ``axis="x"`` varies along columns (vertical stripes), ``"y"`` along rows. Pattern k is
    lit where ``(coordinate − k·period/steps) mod period < period/2``.
    """
    if axis not in ("x", "y"):
        raise CalibrationError(f"`axis` must be 'x' or 'y'; got {axis!r}")
    if period < 4 or period % 2 or period % steps:
        raise CalibrationError(f"`period` must be even, >= 4 and a multiple of `steps`; got period {period}, "
                               f"steps {steps}")
    Hp, Wp = projector_size
    coord = np.arange(Wp if axis == "x" else Hp)
    shift = period // steps
    lit = np.stack([((coord - k * shift) % period) < period // 2 for k in range(steps)])
    if axis == "x":
        return np.ascontiguousarray(np.broadcast_to(lit[:, None, :], (steps, Hp, Wp)))
    return np.ascontiguousarray(np.broadcast_to(lit[:, :, None], (steps, Hp, Wp)))


def decode_phase(images, *, period: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Sub-pixel projector coordinate modulo ``period`` from :func:`phase_patterns` captures.

    Returns
    -------
    frac : ndarray (H, W) float
        The coordinate modulo ``period`` (in ``[0, period)``).
    amplitude : ndarray (H, W) float
        The fundamental's amplitude ``B`` (how well the fringes were seen).
    """
    imgs = np.asarray(images, dtype=np.float64)
    N = imgs.shape[0]
    k = np.arange(N)
    s = np.tensordot(np.exp(2j * np.pi * k / N), imgs, axes=1)
    c0 = (period / 2 - 1) / 2
    frac = (c0 + period * np.angle(s) / (2 * np.pi)) % period
    return frac, 2 * np.abs(s) / N


def unwrap(frac: np.ndarray, coarse: np.ndarray, period: int) -> np.ndarray:
    """Absolute coordinate: the value ``≡ frac (mod period)`` closest to ``coarse``."""
    return frac + period * np.round((coarse - frac) / period)
