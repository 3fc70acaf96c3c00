"""A flow held at its own scale gives the full-size flow's planes, bit for bit, a band at a time."""

import numpy as np
import pytest

from flexvox_core.flow.estimate import FlowField, ScaledFlow, to_full_size
from flexvox_core.gaps import bridge, bridge_flow
from flexvox_core.planes import band


def _small(S=6, h=5, w=7, seed=0):
    rng = np.random.default_rng(seed)
    return (rng.normal(0, 0.5, (S, h, w, 2)).astype(np.float32),
            rng.uniform(0.2, 1, (S, h, w)).astype(np.float32))


def test_bands_and_the_whole_flow_are_to_full_sizes_values():
    vel, conf = _small()
    want_flow, want_conf = to_full_size(vel, conf, (16, 21))
    held = ScaledFlow(vel.copy(), conf.copy(), (16, 21))
    assert held.shape == (6, 16, 21, 2)
    np.testing.assert_array_equal(held.band(1, 4), want_flow[1:4])
    with pytest.raises(ValueError, match=r"sub-frames 4 to 99 must be whole numbers with 0 <= t0 <= t1 <= 6"):
        band(held, 4, 99)  # refused, not clipped as a slice would be
    assert "flow" not in held.__dict__  # no band made the whole volume
    np.testing.assert_array_equal(held.flow, want_flow)
    np.testing.assert_array_equal(held.confidence, want_conf)
    np.testing.assert_array_equal(held.band(2, 3), want_flow[2:3])  # from the whole flow, once made
    np.testing.assert_array_equal(held.magnitude, np.hypot(want_flow[..., 0], want_flow[..., 1]))


def test_band_into_makes_the_planes_in_a_given_buffer():
    vel, conf = _small()
    want_flow, _ = to_full_size(vel, conf, (16, 21))
    held = ScaledFlow(vel, conf, (16, 21))
    buf = np.full((5, 16, 21, 2), -7, np.float32)
    assert held.band_into(1, 4, buf[2:5]) is not None
    np.testing.assert_array_equal(buf[2:5], want_flow[1:4])
    assert (buf[:2] == -7).all() and "flow" not in held.__dict__
    with pytest.raises(ValueError, match=r"sub-frames 4 to 7 of 6 into `out` float32 \(3, 16, 21, 2\): they must "
                                         r"be within the sub-frames"):
        held.band_into(4, 7, buf[:3])
    with pytest.raises(ValueError, match=r"`out` float32 of shape \(2, 16, 21, 2\)"):
        held.band_into(0, 2, buf[:3])
    assert held.flow.shape == (6, 16, 21, 2)  # once made, read from it
    buf[...] = -7
    held.band_into(0, 2, buf[:2])
    np.testing.assert_array_equal(buf[:2], want_flow[:2])


def test_confidence_of_one_is_a_read_only_view():
    vel, _ = _small()
    held = ScaledFlow(vel, np.ones(vel.shape[:3], np.float32), (10, 14))
    assert held.confidence.shape == (6, 10, 14) and not held.confidence.flags.writeable
    assert float(held.confidence.min()) == 1
    assert held.small_confidence.strides == (0, 0, 0)  # held as a view of one value: no memory


def test_a_plane_put_is_read_before_and_after_the_whole_flow_is_made():
    vel, conf = _small()
    held = ScaledFlow(vel, conf, (16, 21))
    plane = np.full((16, 21, 2), 3.5, np.float32)
    held.put(2, plane)
    np.testing.assert_array_equal(held.band(2, 3)[0], plane)
    np.testing.assert_array_equal(held.flow[2], plane)
    held.put(3, plane + 1)
    np.testing.assert_array_equal(held.band(3, 4)[0], plane + 1)
    with pytest.raises(ValueError, match=r"`plane` must have shape \(16, 21, 2\)"):
        held.put(0, plane[:3])


def test_a_small_flow_of_the_wrong_shape_is_refused():
    vel, conf = _small()
    with pytest.raises(ValueError, match="`small` must be float32"):
        ScaledFlow(vel[..., 0], conf, (16, 21))


def test_a_full_flow_field_reads_as_bands_of_its_array():
    vel, conf = _small()
    field_ = FlowField(vel, conf)
    assert field_.shape == vel.shape and field_.held is vel
    np.testing.assert_array_equal(band(field_, 1, 3), vel[1:3])
    field_.put(0, np.zeros(vel.shape[1:], np.float32))
    assert not vel[0].any()


def test_the_flow_bridged_at_its_own_scale_is_the_full_flow_bridged_to_rounding():
    vel, conf = _small(S=8 * 4)
    missing = np.array([False, True, False, False, True, True, False, True])  # gaps inside and at the end
    full, _ = to_full_size(vel, conf, (16, 21))
    bridge_flow(full, missing, 4, margin=2)
    held = ScaledFlow(vel.copy(), conf, (16, 21))
    bridge_flow(held.held, missing, 4, margin=2)
    changed = ~np.all(held.flow == to_full_size(vel, conf, (16, 21))[0], axis=(1, 2, 3))
    assert changed.sum() >= 4 * 4  # the gaps' sub-frames and their margins were bridged
    np.testing.assert_allclose(held.flow, full, rtol=0, atol=1e-5)


def test_bridge_sets_a_held_flows_gap_planes_as_an_arrays():
    vel, conf = _small(S=4 * 4)
    missing = np.array([False, True, False, False])
    rng = np.random.default_rng(1)
    video = rng.uniform(0, 1, (16, 16, 21)).astype(np.float32)
    full = to_full_size(vel, conf, (16, 21))[0]
    want_video = video.copy()
    bridge(want_video, missing, 4, flow=full)
    held = ScaledFlow(vel, conf, (16, 21))
    got_video = video.copy()
    bridge(got_video, missing, 4, flow=held)
    np.testing.assert_array_equal(got_video, want_video)
    assert sorted(held._put) == [4, 5, 6, 7]  # the gap's velocity, set
    np.testing.assert_array_equal(held.flow, full)


@pytest.mark.parametrize("shape", [(1, 1, 2), (7, 5, 2), (160, 213, 2)])
def test_scaled_vectors_are_numpy_s_product_bit_for_bit(shape):
    from flexvox_core.flow.estimate import scaled_vectors

    rng = np.random.default_rng(3)
    plane = (rng.normal(size=shape) * 10.0 ** rng.integers(-8, 8, size=shape)).astype(np.float32)
    plane.flat[0] = np.nan
    ratio = np.array([640 / 213, 480 / 160], np.float32)
    got = scaled_vectors(plane, ratio)
    assert got.dtype == np.float32 and got.shape == shape and got is not plane
    np.testing.assert_array_equal(got.view(np.uint32), (plane * ratio).view(np.uint32))


@pytest.mark.parametrize("small, size", [((5, 7), (16, 21)), ((160, 213), (480, 640)), ((11, 3), (31, 8)),
                                         ((4, 4), (4, 4)), ((33, 45), (97, 131)), ((7, 9), (21, 27))])
def test_resize_tables_are_opencvs_bilinear_resize_bit_for_bit(small, size):
    import cv2

    from flexvox_core.flow.estimate import resize_at, resize_tables

    plane = np.random.default_rng(3).normal(0, 3, (*small, 2)).astype(np.float32)
    plane[0, 0] = np.inf  # carried as the resize carries it (read as still downstream)
    want = cv2.resize(plane, size[::-1], interpolation=cv2.INTER_LINEAR)
    np.testing.assert_array_equal(resize_at(plane, *resize_tables(small, size)), want)


def test_scaled_is_the_plane_where_no_full_size_plane_was_set():
    from flexvox_core.flow.estimate import resize_at

    vel, conf = _small()
    held = ScaledFlow(vel, conf, (16, 21))
    for t in range(6):
        np.testing.assert_array_equal(resize_at(*held.scaled(t)), held.plane(t))
    held.put(2, np.ones((16, 21, 2), np.float32))
    assert held.scaled(2) is None and held.scaled(3) is not None  # a plane put is read as put
    held.flow  # noqa: B018 - the whole volume made: read from it
    assert held.scaled(3) is None


def test_flow_at_reads_a_voxel_of_the_plane_or_of_the_small_flow_with_the_same_bits():
    import numba

    from flexvox_core.flow.estimate import ScaledFlow
    from flexvox_core.motion.flow_kernel import flow_at

    small = np.random.default_rng(5).normal(0, 2, (3, 7, 9, 2)).astype(np.float32)
    flow = ScaledFlow(small, np.ones((3, 7, 9), np.float32), (17, 23))
    scaled, plane = flow.scaled(1), flow.plane(1)
    assert scaled is not None

    @numba.njit
    def compiled(flow_t, y, x):  # type: ignore[no-untyped-def]
        return flow_at(flow_t, y, x)

    for y, x in ((0, 0), (16, 22), (8, 5), (3, 19)):
        want = (plane[y, x, 0], plane[y, x, 1])
        assert flow_at(scaled, y, x) == want and flow_at(plane, y, x) == want
        assert compiled(scaled, y, x) == want and compiled(plane, y, x) == want
