"""The gated flow's gate on one sub-frame, compiled (numba): :class:`~flexvox_core.motion.gated_flow._GatedFlow`'s
element-wise steps in one pass over a plane, with numpy's values bit for bit.

Each speed is ``hypot`` as numpy's float32 ``np.hypot`` gives it: the square root of the float64 sum of squares
(exact squares), rounded to float32 once; numpy's ``np.hypot`` takes about 9 ns an element here, and the gate
reads four speeds a voxel. The arithmetic is float32 throughout, with the thresholds rounded to float32 first, as
numpy does with Python numbers. The whole-volume form the tests compare with is
``tests/flexvox_core/flow/gated_reference.py``.
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
    K-average blurred the motion away). The rule of both engines: compiled per voxel here (:func:`gate_plane`) and
    on the GPU (:mod:`flexvox_core.motion.gpu.gated_flow`); element-wise on arrays too."""
    return (slow < slow_speed) & (successive < 2 * slow_speed)


_takes_slow = numba.njit(inline="always", nogil=True, cache=True)(takes_slow)


@numba.njit(inline="always", nogil=True, cache=True)
def _hypot(u: np.float32, v: np.float32) -> np.float32:
    """float32 ``np.hypot(u, v)``: exact float64 squares, their sum's square root rounded to float32."""
    uu = np.float64(u)
    vv = np.float64(v)
    return np.float32(math.sqrt(uu * uu + vv * vv))


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def _ramp(speed: np.float32, lo: np.float32, width: np.float32) -> np.float32:
    """``np.clip((speed - lo) / width, 0, 1)`` in float32."""
    r = (speed - lo) / width
    r = np.float32(0) if r < 0 else r
    return np.float32(1) if r > 1 else r


@numba.njit(nogil=True, cache=True, error_model="numpy")
def gate_plane(vel: Plane, conf: Plane, d0: Plane, d1: Plane, w0: float, w1: float, blend: bool, steps: Plane,
               mean: Plane, has_mean: bool, px: np.float32, use_slow: bool, slow_speed: np.float32,
               lo: np.float32, width: np.float32, plo: np.float32, pwidth: np.float32, max_mag: np.float32) -> None:
    """Gate one sub-frame in place: ``vel`` (h, w, 2) becomes the gated velocity, sanitised (non-finite: 0 with
    ``conf`` 0; magnitudes capped at ``max_mag``).

    The K-average's velocity is ``w0 * d0 + w1 * d1`` (``d0`` alone unless ``blend``; float64 weights, the sum
    rounded to float32 once, as numpy makes it with :func:`~flexvox_core.flow.baseline.blend`'s); it is taken where
    ``use_slow`` and :func:`takes_slow` at ``slow_speed``. The ramp opens from ``lo`` over ``width`` on the larger
    of that speed and ``steps``' (the detector's velocity, at this size), and from ``plo`` over ``pwidth`` on
    ``mean``'s speed when ``has_mean``. Speeds in full-size pixels (times ``px``); every other number float32.
    """
    h, w = conf.shape
    zero = np.float32(0)
    for y in range(h):
        for x in range(w):
            u = vel[y, x, 0]
            v = vel[y, x, 1]
            if blend:
                su = np.float32(w0 * np.float64(d0[y, x, 0]) + w1 * np.float64(d1[y, x, 0]))
                sv = np.float32(w0 * np.float64(d0[y, x, 1]) + w1 * np.float64(d1[y, x, 1]))
            else:
                su = d0[y, x, 0]
                sv = d0[y, x, 1]
            speed = _hypot(su, sv) * px
            take = use_slow & _takes_slow(speed, _hypot(u, v) * px, slow_speed)
            u = su if take else u
            v = sv if take else v
            step = _hypot(steps[y, x, 0], steps[y, x, 1]) * px
            speed = step if (step > speed) | (step != step) else speed  # np.maximum: a NaN wins
            ramp = _ramp(speed, lo, width)
            if has_mean:
                other = _ramp(_hypot(mean[y, x, 0], mean[y, x, 1]) * px, plo, pwidth)
                ramp = other if (other > ramp) | (other != other) else ramp
            u = u * ramp
            v = v * ramp
            if not (math.isfinite(u) and math.isfinite(v)):
                u = zero
                v = zero
                conf[y, x] = zero
            elif max(abs(u), abs(v)) * math.sqrt(2.0) > max_mag:  # as sanitize_flow: the magnitude only then
                mag = _hypot(u, v)
                if mag > max_mag:
                    f = max_mag / max(mag, np.float32(1e-12))
                    u = u * f
                    v = v * f
            vel[y, x, 0] = u
            vel[y, x, 1] = v
