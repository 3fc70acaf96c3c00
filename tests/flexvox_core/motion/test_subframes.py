"""The gathers' inputs: sample planes without needless copies, boxes around selected voxels."""

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume
from flexvox_core.motion.subframes import sample_planes, selected_boxes


def test_periodic_mask_shares_its_weight_planes_and_clean_values_are_views(rng):
    code = design_code((2, 4)).code  # K = 8
    truth = rng.random((8 * 3, 6, 8)).astype(np.float32)
    sparse = sparse_volume(capture(truth, code), code)
    mask = sample_mask(truth.shape, code)
    values, weights = sample_planes(sparse, mask)
    assert len(values) == len(weights) == 24
    assert np.shares_memory(weights[3], weights[11]) and np.shares_memory(weights[3], weights[19])
    for t in range(24):
        np.testing.assert_array_equal(weights[t], mask[t].astype(np.float32))
        assert np.shares_memory(values[t], sparse)


def test_values_off_sample_are_cleaned_and_an_irregular_mask_gets_its_own_planes(rng):
    sparse = rng.random((5, 4, 4)).astype(np.float32)
    mask = rng.random((5, 4, 4)) < 0.3
    sparse[0, ~mask[0]] = np.nan
    values, weights = sample_planes(sparse, mask)
    for t in range(5):
        np.testing.assert_array_equal(values[t], np.where(mask[t], sparse[t], 0))
        np.testing.assert_array_equal(weights[t], mask[t].astype(np.float32))
    assert not np.shares_memory(values[0], sparse)



def test_a_periodic_mask_with_dirt_off_its_samples_is_cleaned_plane_by_plane(rng):
    code = design_code((2, 2)).code  # K = 4
    truth = rng.random((4 * 3, 6, 8)).astype(np.float32)
    sparse = sparse_volume(capture(truth, code), code)
    mask = sample_mask(truth.shape, code)
    sparse[5, ~mask[5]] = -0.0  # equal to 0, other bits: cleaned (the same values)
    sparse[7][~mask[7]] = np.where(rng.random((~mask[7]).sum()) < 0.5, np.nan, 3.0).astype(np.float32)
    values, weights = sample_planes(sparse, mask)
    for t in range(12):
        np.testing.assert_array_equal(values[t], np.where(mask[t], sparse[t], 0))
        assert np.shares_memory(values[t], sparse) == (t not in (5, 7))
    assert not np.signbit(values[5]).any()

def test_selected_boxes_cover_every_selected_pixel():
    select = np.zeros((100, 60), bool)
    select[5, 7] = select[40:45, 10:50] = select[99, 0] = True
    covered = np.zeros_like(select)
    for (y0, y1, x0, x1), (k0, k1) in selected_boxes(select, pad=2, band=32):
        assert y0 <= k0 < k1 <= y1
        covered[k0:k1, x0:x1] = True
    assert covered[select].all()


def test_flow_at_reads_the_vectors_at_flat_indices(rng):
    from flexvox_core.motion.subframes import flow_at

    flow = rng.standard_normal((6, 7, 2)).astype(np.float32)
    flat = np.array([0, 5, 13, 41])
    u, v = flow_at(flow, flat)
    np.testing.assert_array_equal(u, flow.reshape(-1, 2)[flat, 0])
    np.testing.assert_array_equal(v, flow.reshape(-1, 2)[flat, 1])
    assert u.flags.c_contiguous and v.flags.c_contiguous and u.dtype == np.float32
    strided = np.asfortranarray(flow)  # any layout
    np.testing.assert_array_equal(flow_at(strided, flat)[1], v)
