"""planes.band: one rule for every kind of volume read a band of sub-frames at a time."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.motion.packed import PackedVolume
from flexvox_core.motion.sample_bands import SampleMask
from flexvox_core.planes import band


def _volumes():
    packed = PackedVolume((8, 4, 4))
    for t in range(8):
        packed.put(t, np.ones((4, 4), bool))
    return {"array": np.zeros((8, 4, 4), bool), "packed": packed,
            "mask": SampleMask(design_code((2, 2)).code, (8, 4, 4))}


@pytest.mark.parametrize("kind", ["array", "packed", "mask"])
@pytest.mark.parametrize("t0, t1", [(-1, 2), (2, 9), (5, 3), (2.5, 4), (0, True)])
def test_a_range_outside_the_volume_or_not_whole_is_refused_in_words_for_every_kind(kind, t0, t1):
    with pytest.raises(ValueError, match=rf"sub-frames {t0!r} to {t1!r} must be whole numbers with "
                                         r"0 <= t0 <= t1 <= 8 \(the volume's sub-frames\)"):
        band(_volumes()[kind], t0, t1)


@pytest.mark.parametrize("kind", ["array", "packed", "mask"])
def test_a_range_within_gives_those_sub_frames(kind):
    assert band(_volumes()[kind], 2, 5).shape == (3, 4, 4)
    assert band(_volumes()[kind], 8, 8).shape == (0, 4, 4)
