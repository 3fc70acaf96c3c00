"""Motion-aware's noise-aware smoothing: the noise read from still pixels' successive samples, a wide-kernel
weight that is 1 where the picture is flat and 0 across edges, a gather that stays a normalized convolution
(exact leave-one-out, maximum principle), noiseless captures unchanged and noisy ones better."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware, motion_compensated_nc
from flexvox_core.motion.noise_aware import MIN_PIXELS, SmoothWeights, frame_noise, wide_sigma
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video

from .loo_reference import gather_loo_errors

CODE8 = design_code((2, 4)).code


def _noisy_still(sigma, F=4, H=32, W=40, K=8, seed=0):
    rng = np.random.default_rng(seed)
    picture = rng.uniform(0.2, 0.8, (H, W)).astype(np.float32)
    frames = (picture + rng.normal(0, sigma, (F, H, W))).astype(np.float32)
    return frames, np.ones((F * K, H, W), bool), sample_mask((F * K, H, W), CODE8)


@pytest.mark.parametrize("sigma", [0.005, 0.02, 0.05])
def test_the_noise_of_a_still_scene_is_read_from_successive_samples(sigma):
    frames, still, mask = _noisy_still(sigma)
    noise = frame_noise(frames, still, mask, 8)
    assert noise.shape == (4,) and noise.dtype == np.float32
    np.testing.assert_allclose(noise, sigma, rtol=0.15)


def test_no_noise_no_still_pixels_or_one_frame_give_zero():
    frames, still, mask = _noisy_still(0.0)
    assert (frame_noise(frames, still, mask, 8) == 0).all()
    noisy, _, _ = _noisy_still(0.02)
    assert (frame_noise(noisy, ~still, mask, 8) == 0).all()  # everything moves: nothing to read
    assert (frame_noise(noisy[:1], still[:8], mask[:8], 8) == 0).all()  # one frame: no successive samples
    few = np.zeros_like(still)
    few[:, 0, : MIN_PIXELS // 4] = True  # 16 still pixels, 32 differences for a middle frame: too few
    assert (frame_noise(noisy, few, mask, 8) == 0).all()
    with pytest.raises(ValueError, match=r"`still` \(8, 32, 40\) and `mask` \(32, 32, 40\) must be"):
        frame_noise(noisy, still[:8], mask, 8)


def test_a_dropped_frame_gives_no_differences():
    frames, still, mask = _noisy_still(0.02)
    frames[1] = 5.0  # a dropped frame's content is meaningless
    mask[8:16] = False
    noise = frame_noise(frames, still, mask, 8)
    # Frame 0's only neighbour was dropped: no figure, the narrow blur alone there.
    assert noise[0] == noise[1] == 0 and 0.015 < noise[2] < 0.025 and 0.015 < noise[3] < 0.025


def test_the_wide_weight_is_one_on_flat_ground_and_zero_across_an_edge():
    guide = np.full((2, 24, 24), 0.3, np.float32)
    guide[:, :, 12:] = 0.9  # a vertical edge
    weights = SmoothWeights(guide, np.array([0.02, 0.0]))
    g = weights[0]
    assert g.shape == (24, 24) and g.dtype == np.float32
    assert 0 <= g.min() and g.max() <= 1
    assert g[:, :5].min() > 0.999 and g[:, 11:13].max() < 1e-6
    assert weights[1] is None  # no noise: the narrow blur alone
    assert len(weights) == 2
    with pytest.raises(ValueError, match=r"`noise` must hold one finite number >= 0 per sub-frame \(2\)"):
        SmoothWeights(guide, np.array([0.02, -1.0]))


def _gather_case(seed):
    rng = np.random.default_rng(seed)
    F, H, W, K = 2, 10, 12, 8
    frames = capture(rng.uniform(0.1, 0.9, (F * K, H, W)).astype(np.float32), CODE8)
    sparse, mask = sparse_volume(frames, CODE8), sample_mask((F * K, H, W), CODE8)
    flow = rng.uniform(-1, 1, (F * K, H, W, 2)).astype(np.float32)
    still = rng.uniform(size=(F * K, H, W)) < 0.3
    wide = [rng.uniform(0, 1, (H, W)).astype(np.float32) if t % 3 else None for t in range(F * K)]
    return frames, sparse, mask, flow, still, wide


def test_the_mixed_gathers_leave_one_out_is_the_gather_without_the_sample():
    frames, sparse, mask, flow, still, wide = _gather_case(3)
    F, H, W, K = 2, 10, 12, 8
    base = np.zeros_like(sparse)
    loo = np.full((F, H, W), np.nan, np.float32)
    kw = dict(time=5.0, still=still, still_value=base, wide=wide, wide_sigma=wide_sigma(K))
    motion_compensated_nc(sparse, mask, flow, loo=loo, **kw)
    errors = gather_loo_errors(sparse, mask, flow, CODE8, loo, **kw)
    assert len(errors) > 100
    assert np.median(errors) < 1e-6 and max(errors) < 1e-3
    with pytest.raises(ValueError, match=r"`wide` must give a weight plane or None for each of the 16 sub-frames"):
        motion_compensated_nc(sparse, mask, flow, wide=wide[:3], wide_sigma=1.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**16))
def test_the_mixed_gather_stays_within_the_samples(seed):
    frames, sparse, mask, flow, still, wide = _gather_case(seed)
    out = motion_compensated_nc(sparse, mask, flow, time=5.0, wide=wide, wide_sigma=2.0,
                                fallback=np.full_like(sparse, 0.5))
    assert np.isfinite(out).all()
    assert out.min() >= frames.min() - 1e-5 and out.max() <= frames.max() + 1e-5
    np.testing.assert_array_equal(out[mask], sparse[mask])


def _balls(noisy: bool):
    code = design_code((4, 4)).code
    truth = render_scene("balls", 4 * 16, 48, 64, seed=0)
    if not noisy:
        return truth, capture(truth, code), code
    effects = parse_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}})
    res = simulate_video(truth, code, effects=effects, seed=0, electrons_per_unit=1000.0)
    return truth, np.asarray(res.frames, np.float32), code


def test_a_noiseless_capture_is_unchanged_and_a_noisy_one_gains():
    truth, frames, code = _balls(False)
    np.testing.assert_array_equal(motion_aware(frames, code).video,
                                  motion_aware(frames, code, noise_aware=False).video)
    truth, frames, code = _balls(True)
    aware = float(psnr(truth, np.clip(motion_aware(frames, code).video, 0, 1)))
    blind = float(psnr(truth, np.clip(motion_aware(frames, code, noise_aware=False).video, 0, 1)))
    assert aware > blind + 0.05
    with pytest.raises(ValueError, match=r"`noise_aware` must be True or False; got 'yes'"):
        motion_aware(frames, code, noise_aware="yes")
