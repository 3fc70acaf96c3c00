"""The speed classes held a bit per voxel read back as the bool volumes."""

import numpy as np
import pytest

from flexvox_core.flow.estimate import ScaledFlow
from flexvox_core.motion.packed import PackedVolume
from flexvox_core.motion.stages import packed_speed_classes, speed_classes
from flexvox_core.planes import band


def test_a_packed_volume_reads_back_its_planes_and_counts():
    rng = np.random.default_rng(0)
    want = rng.random((5, 7, 13)) < 0.3  # 13 columns: a partial byte
    want[2] = False
    packed = PackedVolume(want.shape)
    assert not packed.any()
    for t, plane in enumerate(want):
        packed.put(t, plane)
    got = band(packed, 0, 5)
    assert got.dtype == np.bool_ and got.flags.c_contiguous
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(packed.band(1, 3), want[1:3])
    np.testing.assert_array_equal(packed.band(3, 99), want[3:])
    assert packed.any() and not packed.any_in(2, 3) and packed.any_in(1, 3)
    np.testing.assert_array_equal(packed.counts, want.sum(axis=(1, 2)))
    with pytest.raises(ValueError, match=r"`plane` must have shape \(7, 13\)"):
        packed.put(0, want[0, :3])


@pytest.mark.parametrize("speeds", [(0.2, 0.6), (None, 0.6), (0.2, None), (None, None)])
def test_packed_speed_classes_are_the_volumes(speeds):
    rng = np.random.default_rng(1)
    small = rng.normal(0, 0.4, (6, 5, 7, 2)).astype(np.float32)
    flow = ScaledFlow(small, np.ones((6, 5, 7), np.float32), (10, 15))
    skip = np.array([False, False, True, False, False, True])
    want = speed_classes(flow.flow, *speeds, skip)
    got = packed_speed_classes(flow, *speeds, skip)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g.band(0, 6), w)
        assert g.any() == bool(w.any())
    assert want[0].any() or speeds[0] is None
    assert want[2].any()
