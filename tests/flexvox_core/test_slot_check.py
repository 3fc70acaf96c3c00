"""Reading back which slot every pixel sampled (flexvox_core.slot_check)."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.slot_check import slot_accuracy

CODE = design_code((4, 4)).code


def test_a_strobe_recording_tells_every_pixels_slot():
    video = render_scene("strobe", 17 * 16, 24, 32, seed=0)
    check = slot_accuracy(capture(video, CODE), video, CODE)
    assert check.accuracy == 1.0 and check.decidable_fraction == 1.0
    np.testing.assert_array_equal(check.seen, check.expected)


def test_a_phase_off_by_one_or_a_leaky_shutter():
    video = render_scene("strobe", 17 * 16, 24, 32, seed=0)
    late = capture(np.roll(video, -1, axis=0), CODE)  # every pixel sampled its slot + 1
    assert slot_accuracy(late, video, CODE).accuracy == 0.0
    # 30 % of a neighbouring slot's light: the dominant slot is still the code's
    leaky = 0.7 * capture(video, CODE) + 0.3 * late
    assert slot_accuracy(leaky, video, CODE).accuracy == 1.0


def test_few_frames_use_the_single_slot_fit_and_still_pixels_are_undecidable():
    rng = np.random.default_rng(1)
    video = rng.random((4 * 16, 8, 8)).astype(np.float32)
    video[:, :, :4] = video[:1, :, :4]  # the left half does not move
    check = slot_accuracy(capture(video, CODE), video, CODE)
    assert check.accuracy == 1.0 and (check.seen[:, :4] == -1).all() and (check.seen[:, 4:] >= 0).all()
    assert check.describe() == "slot accuracy 100.0% of the 32 of 64 pixels (50.0%) whose slot can be told from the " \
                               "ground truth"
    still = np.repeat(video[:1], 4 * 16, axis=0)
    assert slot_accuracy(capture(still, CODE), still, CODE).describe().endswith("record the strobe scene")
    few = np.repeat(video[:1], 4 * 16, axis=0)
    few[:, :4, 7] = video[:, :4, 7]  # 4 pixels of 64 change
    line = slot_accuracy(capture(few, CODE), few, CODE).describe()
    assert "too few pixels to judge the recording (under 10%)" in line


def test_bad_input_is_named():
    video = np.zeros((32, 8, 8), np.float32)
    with pytest.raises(ValueError, match=r"`truth` must have shape \(48, 8, 8\) for 3 frames of K = 16"):
        slot_accuracy(np.zeros((3, 8, 8)), video, CODE)
    with pytest.raises(ValueError, match=r"`code` must be an identity code"):
        slot_accuracy(np.zeros((2, 8, 8)), video, np.ones((4, 4, 16), bool))
