"""The gated flow's gate as one scalar compiled loop a pixel (motion/gated_flow_kernel.py before its pass became
vector code): four float64 square roots a pixel, branches on the flags, the finite check and the cap. The same
values as the vector pass bit for bit (tests/flexvox_core/motion/test_gated_flow_kernel.py); ``bench/
bench_motion_throughput.py --ab gate-scalar`` runs it."""

from __future__ import annotations

import math

import numba
import numpy as np

from flexvox_core.motion.gated_flow_kernel import _hypot, _ramp, _takes_slow


@numba.njit(nogil=True, error_model="numpy")
def gate_plane_scalar(vel, conf, d0, d1, w0, w1, blend, steps, mean, has_mean, px, use_slow, slow_speed, lo, width,
                      plo, pwidth, max_mag):
    """:func:`~flexvox_core.motion.gated_flow_kernel.gate_plane`'s arguments; ``conf`` not clipped (returns None)."""
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
