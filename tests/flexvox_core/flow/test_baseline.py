"""Long-baseline velocity of the K-average: accurate where successive-sub-frame flow of a
high-TR reconstruction swims."""

import math

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.flow import estimate_flow
from flexvox_core.flow.baseline import kaverage_velocity
from flexvox_core.forward import capture
from flexvox_core.motion.pipeline import STEP1_TENSOR, STEP1_TIME, gated_flow
from flexvox_core.reconstruct.diffusion import diffuse
from flexvox_core.simulate.textures import fine_texture, shift_image

K = 16
VELOCITY = (0.15, 0.05)  # px per sub-frame, like the built-in `pan` scene


@pytest.fixture(scope="module")
def slow_pan():
    """High-TR reconstruction of a fine texture panning slowly, captured with a 4x4 code."""
    rng = np.random.default_rng(3)
    tex = fine_texture(64, 80, rng)
    truth = np.stack([shift_image(tex, VELOCITY[0] * s, VELOCITY[1] * s) for s in range(4 * K)])
    return diffuse(capture(truth, design_code((4, 4)).code), design_code((4, 4)).code,
                   tensor=STEP1_TENSOR, time=STEP1_TIME)


def _error(flow):
    inner = flow[:, 8:-8, 8:-8]  # away from the wrapping borders
    return np.hypot(inner[..., 0] - VELOCITY[0], inner[..., 1] - VELOCITY[1])


def _mean_error(flow):
    return float(np.mean(_error(flow)))


def test_slow_motion_is_measured_far_better_than_by_successive_flow(slow_pan):
    slow = kaverage_velocity(slow_pan, K)
    successive = estimate_flow(slow_pan, consistency=False)
    assert slow.flow.shape == (*slow_pan.shape, 2)
    assert _mean_error(slow.flow) < 0.03
    assert _mean_error(successive.flow) > 3 * _mean_error(slow.flow)


def test_still_video_has_zero_velocity(rng):
    still = np.repeat(fine_texture(40, 48, rng)[None], 3 * K, axis=0)
    assert float(np.abs(kaverage_velocity(still, K).flow).max()) < 1e-3


def test_measurements_every_stride_are_interpolated_in_time(slow_pan):
    every = kaverage_velocity(slow_pan, K, stride=1)
    sparse = kaverage_velocity(slow_pan, K, stride=K)
    assert sparse.params["stride"] == K and sparse.params["baseline"] == K
    assert _mean_error(sparse.flow) < 0.03
    assert float(np.abs(every.flow - sparse.flow)[:, 8:-8, 8:-8].mean()) < 0.02


def test_short_clip_uses_the_whole_clip_as_baseline(rng):
    v = rng.uniform(0, 1, (5, 20, 20)).astype(np.float32)
    ff = kaverage_velocity(v, K)
    assert ff.params["baseline"] == 4 and ff.flow.shape == (5, 20, 20, 2)
    assert np.isfinite(ff.flow).all()


@pytest.mark.parametrize(("args", "kwargs", "match"), [
    ((np.zeros((1, 8, 8)), 4), {}, r"needs at least 2 sub-frames for flow; got 1"),
    ((np.zeros((4, 8, 8)), 0), {}, r"`K` must be a whole number >= 1; got 0"),
    ((np.zeros((4, 8, 8)), 4), {"stride": 0}, r"`stride` must be a whole number >= 1; got 0"),
    ((np.zeros((4, 8, 8)), 4), {"scale": 1.5}, r"`scale` must be in \(0, 1\]"),
    ((np.full((4, 8, 8), np.nan), 4), {}, r"NaN or infinite"),
])
def test_bad_arguments(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        kaverage_velocity(*args, **kwargs)


def test_gated_flow_takes_the_long_baseline_velocity_for_slow_motion(slow_pan):
    hybrid = gated_flow(slow_pan, K, backend="dis")
    plain = gated_flow(slow_pan, K, backend="dis", slow_speed=None)
    # Where the successive flow is wild (> 2 x slow_speed) it is kept: compare medians.
    assert float(np.median(_error(hybrid.flow))) < 0.03 < float(np.median(_error(plain.flow)))
    with pytest.raises(ValueError, match=r"`slow_speed` must be a number >= 0"):
        gated_flow(slow_pan, K, backend="dis", slow_speed=-1.0)
    assert math.isfinite(hybrid.seconds) and hybrid.seconds > 0
