"""Oriented normalized convolution (flexvox_core/reconstruct/oriented_nc.py): the compiled kernel against the
plain numpy reference, isotropic nc where the guide has no edges, and the edge-following kernel at an edge."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask
from flexvox_core.reconstruct.diffusion import nc_leave_one_out
from flexvox_core.reconstruct.oriented_nc import ANGLES, bank_index, kernel_bank, oriented_nc, oriented_nc_reference

from .conftest import smooth_video


def _edge_video(S, H, W, *, angle=0.0, lo=0.2, hi=0.8):
    """A still picture: a straight edge through the centre, its normal at ``angle`` (radians) from x."""
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    side = (x - W / 2 + 0.3) * math.cos(angle) + (y - H / 2 + 0.3) * math.sin(angle)
    return np.broadcast_to(np.where(side > 0, hi, lo), (S, H, W)).astype(np.float32)


@pytest.mark.parametrize(("tile", "shape", "dropped"), [((2, 4), (2, 12, 17), False), ((2, 2), (3, 11, 9), True),
                                                         ((4, 4), (2, 13, 14), False)])
def test_compiled_kernel_matches_the_numpy_reference(rng, tile, shape, dropped):
    code = design_code(tile).code
    F, H, W = shape
    K = code.shape[2]
    truth = smooth_video(rng, F * K, H, W) + _edge_video(F * K, H, W, angle=0.6) * 0.5
    frames = capture(truth, code)
    missing = None
    if dropped:
        missing = np.zeros(F, bool)
        missing[1] = True
    where = rng.random(truth.shape) < 0.6
    fallback = np.full(truth.shape, -1.0, np.float32)
    got_v, got_l = oriented_nc(frames, code, truth, where=where, fallback=fallback, missing=missing)
    want_v, want_l = oriented_nc_reference(frames, code, truth, where=where, fallback=fallback, missing=missing)
    np.testing.assert_allclose(got_v, want_v, atol=1e-6, rtol=0)
    assert np.array_equal(np.isnan(got_l), np.isnan(want_l))
    np.testing.assert_allclose(got_l, want_l, atol=1e-6, rtol=0)
    assert (got_v[~where] == -1).all()  # outside `where`: the fallback
    assert np.isfinite(got_l).any()
    if dropped:
        assert np.isnan(got_l[1]).all()  # a dropped frame has no samples to leave out


def test_a_guide_without_edges_gives_isotropic_nc(rng, code24):
    """Anisotropy 0 everywhere: the kernel is nc's (tensor (1, 1, 1), n = 0.25), its leave-one-out too."""
    truth = smooth_video(rng, 16, 14, 18)
    frames = capture(truth, code24)
    video, loo = oriented_nc(frames, code24, np.zeros_like(truth))
    nc, nc_loo = nc_leave_one_out(frames, code24, tensor=(1, 1, 1), time=0.25)
    np.testing.assert_allclose(video, nc, atol=1e-5, rtol=0)
    assert np.array_equal(np.isnan(loo), np.isnan(nc_loo))
    np.testing.assert_allclose(loo, nc_loo, atol=1e-5, rtol=0)


@pytest.mark.parametrize("angle", [0.0, math.pi / 4, math.pi / 2, 2.0])
def test_at_an_edge_the_kernel_follows_it(angle):
    """A still edge sampled sparsely (K = 16): guided by the picture, the estimate beside the edge is closer
    to the truth than isotropic nc's, which mixes in samples from across it."""
    code = design_code((4, 4)).code
    truth = _edge_video(32, 40, 40, angle=angle)
    frames = capture(truth, code)
    oriented, _ = oriented_nc(frames, code, truth)
    iso, _ = nc_leave_one_out(frames, code, tensor=(1, 1, 1), time=0.25)
    near = np.abs(truth - np.roll(truth, 1, axis=2)) + np.abs(truth - np.roll(truth, 1, axis=1)) > 0
    near = near | np.roll(near, -1, axis=2) | np.roll(near, -1, axis=1)
    near[:, :6] = near[:, -6:] = False
    near[:, :, :6] = near[:, :, -6:] = False
    err_o = float(np.mean((oriented - truth)[near] ** 2))
    err_i = float(np.mean((iso - truth)[near] ** 2))
    # Measured: 0.31 of nc's error along an axis, 0.73 at 115°, 0.87 on the diagonal (a staircase on this grid).
    assert err_o < 0.9 * err_i


def test_bank_index_reads_direction_and_strength():
    # No gradient: isotropic. A gradient along x (a vertical edge): the strongest level, direction 0.
    assert bank_index(0.0, 0.0, 0.0) == 0
    assert bank_index(1.0, 0.0, 0.0) == 1 + ANGLES + 0
    assert bank_index(0.0, 0.0, 1.0) == 1 + ANGLES + 4  # along y: 90°
    assert bank_index(0.5, 0.5, 0.5) == 1 + ANGLES + 2  # along the diagonal: 45°
    assert bank_index(1.0, 0.0, 0.45) == 1 + 0  # A = 0.38: the middle level
    assert bank_index(1.0, 0.0, 0.9) == 0  # A = 0.05: isotropic
    bank = kernel_bank()
    assert bank.shape[0] == 1 + 2 * ANGLES and (bank[:, bank.shape[1] // 2, bank.shape[2] // 2] == 1).all()
    vertical_edge = bank[1 + ANGLES + 0]  # narrow across x, long along y
    assert (vertical_edge.sum(axis=1) > 0).sum() > (vertical_edge.sum(axis=0) > 0).sum()


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), tile=st.sampled_from([(2, 2), (2, 4), (4, 4)]),
       H=st.integers(5, 14), W=st.integers(5, 14))
def test_estimates_stay_within_the_samples_and_keep_them(seed, tile, H, W):
    rng = np.random.default_rng(seed)
    code = design_code(tile).code
    K = code.shape[2]
    truth = rng.random((2 * K, H, W)).astype(np.float32)
    frames = capture(truth, code)
    guide = rng.random(truth.shape).astype(np.float32)
    video, loo = oriented_nc(frames, code, guide, fallback=np.full(truth.shape, 0.5, np.float32))
    assert np.isfinite(video).all()
    lo, hi = float(frames.min()), float(frames.max())
    assert video.min() >= lo - 1e-6 and video.max() <= hi + 1e-6
    mask = sample_mask(truth.shape, code)
    np.testing.assert_array_equal(video[mask], truth[mask])
    finite = np.isfinite(loo)
    assert (loo[finite] >= lo - 1e-5).all() and (loo[finite] <= hi + 1e-5).all()


def test_bad_shapes_are_refused(code24):
    frames = np.zeros((2, 8, 8), np.float32)
    with pytest.raises(ValueError, match=r"`guide` must be the \(S, H, W\) = \(16, 8, 8\) video"):
        oriented_nc(frames, code24, np.zeros((8, 8, 8)))
    with pytest.raises(ValueError, match=r"`where` must be a bool \(S, H, W\) = \(16, 8, 8\) array"):
        oriented_nc(frames, code24, np.zeros((16, 8, 8)), where=np.ones((16, 8)))
    with pytest.raises(ValueError, match=r"`fallback` must be an \(S, H, W\) = \(16, 8, 8\) array"):
        oriented_nc(frames, code24, np.zeros((16, 8, 8)), fallback=np.ones((2, 8, 8)))
