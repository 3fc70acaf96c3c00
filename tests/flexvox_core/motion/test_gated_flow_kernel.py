"""The compiled gate (gated_flow_kernel.gate_plane) gives numpy's element-wise gate bit for bit, at the edges too:
speeds at the thresholds, NaN and infinite velocities, magnitudes over the cap; and the scalar loop's it replaced."""

import numpy as np
import pytest

from flexvox_core.flow.estimate import sanitize_flow
from flexvox_core.motion.gated_flow_kernel import gate_plane, squared_below, takes_slow
from tests.flexvox_core.motion.gate_scalar_reference import gate_plane_scalar


def numpy_gate(vel, conf, d0, d1, a, blend, steps, mean, px, use_slow, slow_speed, gate, period_gate, max_mag):
    """The gate as numpy wrote it (motion/gated_flow.py before the kernel), on one plane."""
    lo, hi = gate
    slow = ((1 - a) * d0 + a * d1).astype(np.float32) if blend else d0.copy()  # as KAverageFlow.at writes it
    speed = np.hypot(slow[..., 0], slow[..., 1]) * px
    if use_slow:
        use = (speed < slow_speed) & (np.hypot(vel[..., 0], vel[..., 1]) * px < 2 * slow_speed)
        vel = np.where(use[..., None], slow, vel)
    else:
        vel = vel.copy()
    speed = np.maximum(speed, np.hypot(steps[..., 0], steps[..., 1]) * px)
    ramp = np.clip((speed - lo) / (hi - lo), 0, 1).astype(np.float32)
    if period_gate is not None:
        plo, phi = period_gate
        ramp = np.maximum(ramp, np.clip((np.hypot(mean[..., 0], mean[..., 1]) * px - plo) / (phi - plo), 0, 1))
    vel *= ramp[..., None]
    return sanitize_flow(vel, conf, max_magnitude=max_mag)


def planes(seed, h=24, w=31):
    rng = np.random.default_rng(seed)
    vel, d0, d1, steps, mean = (rng.normal(0, s, (h, w, 2)).astype(np.float32) for s in (0.3, 0.05, 0.05, 0.1, 0.5))
    vel[0, :4] = [[np.nan, 0], [np.inf, 1], [0, -np.inf], [40, 40]]  # non-finite, and over the cap (20)
    d0[1, :3] = d1[1, :3] = [[0.2, 0], [0.19999999, 0], [0.20000002, 0]]  # the K-average's speed at 0.6 (px 3)
    steps[2, :3] = [[0.05, 0], [0.01, 0], [0, 0.0499999]]  # the detector's at the gate's ends
    mean[3, :2] = [[0.3, 0], [0.5, 0]]  # the period gate's ends
    return vel, np.float32(rng.uniform(0, 1, (h, w))), d0, d1, steps, mean


@pytest.mark.parametrize("use_slow", [True, False])
@pytest.mark.parametrize("blend", [True, False])
@pytest.mark.parametrize("period_gate", [(0.9, 1.5), None])
@pytest.mark.parametrize("seed", [0, 1])
def test_gate_plane_gives_numpys_values(seed, period_gate, blend, use_slow):
    vel, conf, d0, d1, steps, mean = planes(seed)
    a = (np.float64(21.0) - 16) / 4 - 1  # as flow.baseline.blend makes it: a numpy float64
    px, slow_speed, gate, max_mag = 3.0, 0.6, (0.03, 0.15), 20.0
    want_vel, want_conf = numpy_gate(vel, conf, d0, d1, a, blend, steps, mean, np.float32(px), use_slow, slow_speed,
                                     gate, period_gate, max_mag)
    got_vel, got_conf = vel.copy(), conf.copy()
    plo, phi = period_gate or (0.0, 1.0)
    f32 = np.float32
    gate_plane(got_vel, got_conf, d0, d1, np.float64(1 - a), np.float64(a), blend, steps, mean,
               period_gate is not None, f32(px), use_slow, f32(slow_speed), f32(gate[0]), f32(gate[1] - gate[0]),
               f32(plo), f32(phi - plo), f32(max_mag))
    np.testing.assert_array_equal(got_vel, want_vel)
    np.testing.assert_array_equal(got_conf, want_conf)
    assert got_conf[0, 0] == 0 and got_vel[0, 1, 0] == 0  # a non-finite velocity: 0, trusted 0
    assert np.hypot(*got_vel[0, 3]) == pytest.approx(20, rel=1e-6)  # capped


@pytest.mark.parametrize("successive", [False, True])
@pytest.mark.parametrize(("px", "slow_speed"), [(3.0, 0.6), (3.0046948, 0.6), (1.0, 0.25), (2.5, 0.0), (1e-3, 7.0)])
def test_squared_below_is_takes_slow_on_the_square(px, slow_speed, successive):
    """A speed's test at slow_speed is its float64 square's against squared_below: at the bound and the float64s
    around it, on random squares, at 0, infinity and NaN."""
    px, slow_speed = np.float32(px), np.float32(slow_speed)
    bound = squared_below(px, slow_speed, successive)

    def test(square):
        speed = np.float32(np.sqrt(np.float64(square))) * px
        zero = np.float32(0)
        return bool(takes_slow(zero, speed, slow_speed) if successive else takes_slow(speed, zero, slow_speed))

    rng = np.random.default_rng(3)
    near = [bound]
    up = down = bound
    for _ in range(4):  # the four float64s above the bound and below it
        up, down = np.nextafter(up, np.inf), np.nextafter(down, 0.0)
        near += [up, down]
    squares = [*near, *rng.uniform(0, 2 * bound + 1, 2000), *(bound * rng.uniform(0.999, 1.001, 2000)), 0.0, np.inf,
               np.nan]
    for square in squares:
        square = np.float64(square)
        assert test(square) == bool(square < bound), (square, bound)
    assert (bound > 0) == (slow_speed > 0)


@pytest.mark.parametrize("use_slow", [True, False])
@pytest.mark.parametrize("blend", [True, False])
@pytest.mark.parametrize("has_mean", [True, False])
@pytest.mark.parametrize(("h", "w"), [(37, 53), (1, 7), (5, 1)])
def test_vector_pass_gives_the_scalar_loops_values(h, w, has_mean, blend, use_slow):
    """The vector pass against the scalar loop it replaced (gate_scalar_reference.py), bit for bit, on odd sizes
    with speeds spread over the thresholds, non-finite values everywhere, magnitudes over the cap and confidences
    outside [0, 1] and NaN; and its flag for the confidences' clip."""
    rng = np.random.default_rng(h * w)
    f32 = np.float32

    def plane(scale):
        p = (rng.normal(0, scale, (h, w, 2)) * rng.choice([0.01, 0.1, 1, 10], (h, w, 2))).astype(f32)
        bad = rng.random((h, w, 2)) < 0.03
        p[bad] = rng.choice([np.nan, np.inf, -np.inf, 1e30, -0.0], bad.sum())
        return p

    vel, d0, d1, steps, mean = (plane(s) for s in (0.3, 0.1, 0.1, 0.05, 0.3))
    conf = rng.uniform(-0.2, 1.2, (h, w)).astype(f32)
    conf[rng.random((h, w)) < 0.05] = np.nan
    a = np.float64(0.3125)
    args = (d0, d1, np.float64(1 - a), a, blend, steps, mean, has_mean, f32(3.0046948), use_slow, f32(0.6),
            f32(0.03), f32(0.12), f32(0.9), f32(0.6), f32(2.0))
    want_vel, want_conf = vel.copy(), conf.copy()
    gate_plane_scalar(want_vel, want_conf, *args)
    got_vel, got_conf = vel.copy(), conf.copy()
    outside = gate_plane(got_vel, got_conf, *args)
    np.testing.assert_array_equal(got_vel.view(np.uint32), want_vel.view(np.uint32))
    np.testing.assert_array_equal(got_conf.view(np.uint32), want_conf.view(np.uint32))
    assert outside == bool(not (np.min(want_conf) >= 0 and np.max(want_conf) <= 1))
    assert (np.abs(got_vel) <= 2.0).all()  # capped
    still = vel.copy()
    still[...] = 0
    still_conf = np.full((h, w), 0.5, f32)
    assert not gate_plane(still, still_conf, *args)  # every confidence within [0, 1]: no clip
