"""The samples' mask a band of sub-frames at a time: the whole mask's sub-frames, and what reads it."""

import numpy as np
import pytest

from flexvox_core import planes
from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask
from flexvox_core.gaps import interpolated_subframes
from flexvox_core.motion import motion_aware
from flexvox_core.motion.noise_aware import frame_noise
from flexvox_core.motion.sample_bands import SampleMask
from flexvox_core.simulate.scenes import render_scene
from tests.flexvox_core.motion.band_volumes import Counted

CODE = design_code((2, 4)).code  # K = 8


def whole_mask(shape, missing):
    mask = sample_mask(shape, CODE)
    if missing is not None:
        mask[interpolated_subframes(missing, 8)] = False
    return mask


@pytest.mark.parametrize("missing", [None, np.array([False, True, False, False, True])])
def test_a_band_is_the_whole_masks_sub_frames(missing):
    shape = (40, 11, 13)
    mask = SampleMask(CODE, shape, missing)
    whole = whole_mask(shape, missing)
    assert mask.shape == shape
    for t0, t1 in ((0, 40), (0, 1), (3, 21), (7, 9), (39, 40), (12, 12)):
        got = planes.band(mask, t0, t1)
        assert got.dtype == bool and got.flags.c_contiguous and got.shape == (t1 - t0, 11, 13)
        np.testing.assert_array_equal(got, whole[t0:t1])
    got[...] = True  # a band is the caller's own
    np.testing.assert_array_equal(planes.band(mask, 0, 40), whole)


def test_bad_masks_are_refused():
    with pytest.raises(ValueError, match=r"`shape` S = 12 must be a positive multiple of K = 8"):
        SampleMask(CODE, (12, 4, 4))
    with pytest.raises(ValueError, match=r"`missing` must hold one flag per frame \(2\); got shape \(3,\)"):
        SampleMask(CODE, (16, 4, 4), np.zeros(3, bool))
    with pytest.raises(ValueError, match=r"sub-frames 10 to 17 are not within the mask's 16"):
        SampleMask(CODE, (16, 4, 4)).band(10, 17)


def test_the_noise_reads_the_mask_a_frame_at_a_time():
    rng = np.random.default_rng(2)
    F, H, W = 4, 16, 20
    frames = rng.normal(0.5, 0.02, (F, H, W)).astype(np.float32)
    still = rng.random((F * 8, H, W)) < 0.9
    missing = np.array([False, False, True, False])
    whole = whole_mask(still.shape, missing)
    counted = Counted(whole, 8)
    got = frame_noise(frames, still, counted, 8)
    np.testing.assert_array_equal(got, frame_noise(frames, still, whole, 8))
    np.testing.assert_array_equal(got, frame_noise(frames, still, SampleMask(CODE, still.shape, missing), 8))
    assert (got[[0, 1]] > 0).all() and counted.calls == F


@pytest.mark.parametrize("dropped", [False, True])
def test_motion_aware_gives_the_whole_masks_bits(monkeypatch, dropped):
    import flexvox_core.motion.stages as P

    code = design_code((4, 4)).code
    truth = render_scene("balls", 16 * 4, 40, 52, seed=2)
    frames = capture(truth, code)
    frames += np.random.default_rng(0).normal(0, 0.01, frames.shape).astype(np.float32)  # the noise stage runs
    missing = np.array([False, True, False, False]) if dropped else None
    seen = []
    real = P.CpuStages.samples

    def samples(self):
        real(self)
        seen.append(self.mask)

    monkeypatch.setattr(P.CpuStages, "samples", samples)
    got = motion_aware(frames, code, missing=missing).video
    assert isinstance(seen[0], SampleMask)

    def whole(self):  # the mask as a volume, as before it was made a band at a time
        w = self.window
        mask = sample_mask((w.S, *w.frames.shape[1:]), w.code)
        if w.missing is not None:
            mask[interpolated_subframes(w.missing, w.K)] = False
        self.mask = mask

    monkeypatch.setattr(P.CpuStages, "samples", whole)
    np.testing.assert_array_equal(got, motion_aware(frames, code, missing=missing).video)
