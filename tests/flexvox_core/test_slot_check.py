"""Reading back which slot every pixel sampled (flexvox_core.slot_check)."""

import re

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
    assert check.describe() == (
        "slot accuracy 100.0% of the 32 of 64 pixels (50.0%) whose slot can be told from the ground truth; read from 4 "
        "frame(s), fewer than K = 16, each pixel taken to see one slot alone: the light a projector spills from "
        "neighbouring slots reads as wrong slots, so a right calibration can score low (58-81 % on the simulated rig): "
        "record 17 frames of the strobe scene")
    assert check.single_slot_fit and (check.frames, check.slots) == (4, 16)
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


def test_a_leaky_shutter_read_from_fewer_frames_than_k_says_the_fit_cannot_see_it():
    # 28 % of a neighbouring slot's light, as the simulated rig's projector spills: 17 frames of the strobe fit the
    # dominant slot, the code's; 3 frames of balls take the single-slot fit, which reads some pixels as the wrong
    # slot, and the line says why instead of a plain low figure.
    def leaky(video):
        return 0.72 * capture(video, CODE) + 0.28 * capture(np.roll(video, -1, axis=0), CODE)

    strobe = render_scene("strobe", 17 * 16, 24, 32, seed=0)
    full = slot_accuracy(leaky(strobe), strobe, CODE)
    assert not full.single_slot_fit and full.accuracy == 1.0 and "fewer than K" not in full.describe()
    balls = render_scene("balls", 3 * 16, 24, 32, seed=0)
    short = slot_accuracy(leaky(balls), balls, CODE)
    assert short.single_slot_fit and short.accuracy < 0.8
    assert re.search(r"read from 3 frame\(s\), fewer than K = 16, .* a right calibration can score low .*: record 17 "
                     r"frames of the strobe scene$", short.describe())


def test_the_captures_timing_warnings_come_before_the_strobe_advice():
    still = np.repeat(render_scene("drummer", 16, 8, 8, seed=0)[:1], 2 * 16, axis=0)
    line = slot_accuracy(capture(still, CODE), still, CODE).describe(["phase 0 is a guess: K = 8 here"])
    assert line == ("slot accuracy: no pixel changes enough between slots to tell its slot; the capture states: "
                    "phase 0 is a guess: K = 8 here: record the strobe scene")
