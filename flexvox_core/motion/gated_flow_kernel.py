"""The gated flow's gate on one sub-frame, compiled (numba): :class:`~flexvox_core.motion.gated_flow._GatedFlow`'s
element-wise steps in one pass over a plane, with numpy's values bit for bit.

Each speed is ``hypot`` as numpy's float32 ``np.hypot`` gives it: the square root of the float64 sum of squares
(exact squares), rounded to float32 once; numpy's ``np.hypot`` takes about 9 ns an element here. The arithmetic is
float32 throughout, with the thresholds rounded to float32 first, as numpy does with Python numbers. The whole-volume
form the tests compare with is ``tests/flexvox_core/flow/gated_reference.py``.

The pass is vector code (AVX: four or eight pixels at a time, float64 square roots included): no branch depends on
a pixel, and its flags (the K-average's blend, the period gate) are selections, every plane read whatever they are (a
read that depends on a flag is a masked gather; four loops, one for each pair of flags, ran no faster and took three
times as long to compile). A speed only compared with a threshold is compared as its float64 square, with the least
square whose speed fails the test (:func:`squared_below`: the speed is monotone in it, so the test is the same); the
larger of two speeds is the speed of the larger square; and the magnitude cap, which a sane flow never reaches, is a
second pass over the plane that runs only when a velocity comes within reach of it. Two square roots a pixel remain
(of five).
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
import numpy.typing as npt

Plane = npt.NDArray[np.float32]


def takes_slow(slow: Any, successive: Any, slow_speed: Any) -> Any:
    """Whether a voxel's velocity is the K-average's: its speed there (``slow``) below ``slow_speed`` and its
    successive-sub-frame speed (``successive``, both in full-size px per sub-frame) below twice it (faster, the
    K-average blurred the motion away). The rule of both engines: compiled here (:func:`gate_plane`, through
    :func:`squared_below`) and on the GPU (:mod:`flexvox_core.motion.gpu.gated_flow`); element-wise on arrays too."""
    return (slow < slow_speed) & (successive < 2 * slow_speed)


_takes_slow = numba.njit(inline="always", nogil=True, cache=True)(takes_slow)


@numba.njit(inline="always", nogil=True, cache=True)
def _hypot(u: np.float32, v: np.float32) -> np.float32:
    """float32 ``np.hypot(u, v)``: exact float64 squares, their sum's square root rounded to float32."""
    uu = np.float64(u)
    vv = np.float64(v)
    return np.float32(math.sqrt(uu * uu + vv * vv))


@numba.njit(inline="always", nogil=True, cache=True)
def _speed(square: float, px: np.float32) -> np.float32:
    """The speed (full-size px) of a velocity whose float64 squared length is ``square``: as ``_hypot(u, v) * px``."""
    return np.float32(math.sqrt(square)) * px


@numba.njit(nogil=True, cache=True)
def squared_below(px: np.float32, slow_speed: np.float32, successive: bool) -> float:
    """The least float64 squared length whose speed fails :func:`takes_slow`'s test at ``slow_speed`` (the
    K-average's speed, or ``successive``: the successive-sub-frame speed): for a square ``s2`` (>= 0, float64 sum of
    exact squares), ``s2 < squared_below(...)`` is the test on its speed, since the speed (:func:`_speed`) does not
    fall as ``s2`` grows (NaN fails both). Found by bisection over the bit patterns of the non-negative float64s."""
    zero = np.float32(0)
    bits = np.zeros(1, np.int64)
    square = bits.view(np.float64)
    lo, hi = np.int64(-1), np.int64(0x7FF0000000000000)  # the test holds at lo (none yet), fails at hi (+inf)
    while hi - lo > 1:
        mid = lo + (hi - lo) // 2
        bits[0] = mid
        speed = _speed(square[0], px)
        if _takes_slow(zero, speed, slow_speed) if successive else _takes_slow(speed, zero, slow_speed):
            lo = mid
        else:
            hi = mid
    bits[0] = hi
    return float(square[0])


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def _ramp(speed: np.float32, lo: np.float32, width: np.float32) -> np.float32:
    """``np.clip((speed - lo) / width, 0, 1)`` in float32."""
    r = (speed - lo) / width
    r = np.float32(0) if r < 0 else r
    return np.float32(1) if r > 1 else r


@numba.njit(inline="always", nogil=True, cache=True)
def _square(u: np.float32, v: np.float32) -> float:
    """The float64 sum of exact squares of ``u`` and ``v``."""
    uu = np.float64(u)
    vv = np.float64(v)
    return uu * uu + vv * vv


@numba.njit(inline="always", nogil=True, cache=True)
def _finite(x: np.float32) -> bool:
    """``math.isfinite(x)`` as vector code: ``x - x`` is NaN for NaN and infinities, 0 otherwise."""
    return bool(x - x == 0)


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def _gate_loop(vel: Plane, conf: Plane, d0: Plane, d1: Plane, w0: float, w1: float, blend: bool, steps: Plane,
               mean: Plane, has_mean: bool, px: np.float32, use_slow: bool, slow_below: float, fast_below: float,
               lo: np.float32, width: np.float32, plo: np.float32, pwidth: np.float32,
               near: np.float32) -> tuple[int, int]:
    """:func:`gate_plane`'s pass without the cap, no branch in it: the number of velocities with a component beyond
    ``near`` (the cap may apply), and of confidences outside [0, 1] (NaN included)."""
    n = conf.size
    vf = vel.reshape(2 * n)
    cf = conf.reshape(n)
    a0 = d0.reshape(2 * n)
    a1 = d1.reshape(2 * n)
    sf = steps.reshape(2 * n)
    mf = mean.reshape(2 * n)
    zero = np.float32(0)
    one = np.float32(1)
    near_cap = 0
    outside = 0
    for i in range(n):
        u = vf[2 * i]
        v = vf[2 * i + 1]
        # Both flags by selection, every plane read (loads that depend on a flag would be masked gathers).
        bu = np.float32(w0 * np.float64(a0[2 * i]) + w1 * np.float64(a1[2 * i]))
        bv = np.float32(w0 * np.float64(a0[2 * i + 1]) + w1 * np.float64(a1[2 * i + 1]))
        su = bu if blend else a0[2 * i]
        sv = bv if blend else a0[2 * i + 1]
        square = _square(su, sv)
        take = use_slow & (square < slow_below) & (_square(u, v) < fast_below)
        u = su if take else u
        v = sv if take else v
        step = _square(sf[2 * i], sf[2 * i + 1])
        square = step if (step > square) | (step != step) else square  # np.maximum of the speeds: a NaN wins
        ramp = _ramp(_speed(square, px), lo, width)
        other = _ramp(_hypot(mf[2 * i], mf[2 * i + 1]) * px, plo, pwidth)
        ramp = other if has_mean & ((other > ramp) | (other != other)) else ramp
        u = u * ramp
        v = v * ramp
        good = _finite(u) & _finite(v)
        u = u if good else zero
        v = v if good else zero
        c = cf[i] if good else zero
        near_cap += max(abs(u), abs(v)) > near
        outside += not ((c >= zero) & (c <= one))
        vf[2 * i] = u
        vf[2 * i + 1] = v
        cf[i] = c
    return near_cap, outside


@numba.njit(nogil=True, cache=True, error_model="numpy")
def gate_plane(vel: Plane, conf: Plane, d0: Plane, d1: Plane, w0: float, w1: float, blend: bool, steps: Plane,
               mean: Plane, has_mean: bool, px: np.float32, use_slow: bool, slow_speed: np.float32,
               lo: np.float32, width: np.float32, plo: np.float32, pwidth: np.float32, max_mag: np.float32) -> bool:
    """Gate one sub-frame in place: ``vel`` (h, w, 2) becomes the gated velocity, sanitised (non-finite: 0 with
    ``conf`` 0; magnitudes capped at ``max_mag``); returns whether a confidence is outside [0, 1] (NaN included:
    the caller clips them, as :func:`~flexvox_core.flow.estimate.sanitize_flow`). The planes are C-contiguous, and
    every one is read whatever the flags (``d1`` and ``mean`` of ``vel``'s shape even when unused).

    The K-average's velocity is ``w0 * d0 + w1 * d1`` (``d0`` alone unless ``blend``; float64 weights, the sum
    rounded to float32 once, as numpy makes it with :func:`~flexvox_core.flow.baseline.blend`'s); it is taken where
    ``use_slow`` and :func:`takes_slow` at ``slow_speed``. The ramp opens from ``lo`` over ``width`` on the larger
    of that speed and ``steps``' (the detector's velocity, at this size), and from ``plo`` over ``pwidth`` on
    ``mean``'s speed when ``has_mean``. Speeds in full-size pixels (times ``px``); every other number float32.
    """
    slow_below = squared_below(px, slow_speed, False)
    fast_below = squared_below(px, slow_speed, True)
    # A component beyond max_mag / 1.5 flags a pixel for the cap's pass, which tests max_mag / √2 as before.
    near = max_mag / np.float32(1.5)
    near_cap, outside = _gate_loop(vel, conf, d0, d1, w0, w1, blend, steps, mean, has_mean, px, use_slow,
                                   slow_below, fast_below, lo, width, plo, pwidth, near)
    if near_cap:
        vf = vel.reshape(vel.size)
        for i in range(conf.size):
            u = vf[2 * i]
            v = vf[2 * i + 1]
            if max(abs(u), abs(v)) * math.sqrt(2.0) > max_mag:  # as sanitize_flow: the magnitude only then
                mag = _hypot(u, v)
                if mag > max_mag:
                    f = max_mag / max(mag, np.float32(1e-12))
                    vf[2 * i] = u * f
                    vf[2 * i + 1] = v * f
    return outside > 0
