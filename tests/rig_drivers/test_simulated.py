"""What the simulated twins expose beyond the contract."""

import numpy as np
import pytest

from rig_drivers.errors import IncompatibleStateError
from rig_drivers.interfaces import PatternSequence
from rig_drivers.simulated import SimulatedProjector


class Clock:
    def __init__(self):
        self.now = 0

    def __call__(self):
        return self.now


def test_simulated_projector_tracks_the_slot_on_display():
    clock = Clock()
    masks = np.arange(4)[:, None, None] == np.arange(4)[None, :, None]  # mask k lights row k
    masks = np.broadcast_to(masks, (4, 4, 3))
    seq = PatternSequence(masks, 1000, 1000)
    with SimulatedProjector(clock_us=clock) as proj:
        with pytest.raises(IncompatibleStateError, match=r"no sequence loaded: call load_sequence\(\) first"):
            proj.current_patterns()
        proj.enable()
        proj.load_sequence(seq)
        assert np.array_equal(proj.current_patterns(), masks) and proj.current_slot() is None
        proj.start()
        clock.now = 2500
        assert proj.current_slot() == 2
        proj.pause()
        clock.now = 9000
        assert proj.current_slot() == 2 and proj.elapsed_us() == 2500
        proj.start()
        clock.now = 11000
        assert proj.current_slot() == (4500 // 1000) % 4
        proj.stop()
        assert proj.current_slot() is None and proj.elapsed_us() == 0


def test_play_once_ends_after_k_slots():
    clock = Clock()
    seq = PatternSequence(np.ones((3, 1, 1), bool), 1000, 1000, repeat=False)
    with SimulatedProjector(clock_us=clock) as proj:
        proj.enable()
        proj.load_sequence(seq)
        proj.start()
        clock.now = 2999
        assert proj.current_slot() == 2
        clock.now = 3000
        assert proj.current_slot() is None
