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
from flexvox_core.reconstruct.oriented_nc import ANGLES, bank_index, kernel_bank, oriented_nc

from .conftest import smooth_video
from .oriented_reference import oriented_nc_reference


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
    # Measured: 0.31 of nc's error for a vertical edge, 0.44 for a horizontal one, 0.73 at 115°, 0.87 on the
    # diagonal (a staircase on this grid).
    assert err_o < 0.95 * err_i


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
       H=st.integers(1, 14), W=st.integers(1, 14))
def test_estimates_stay_within_the_samples_and_keep_them(seed, tile, H, W):
    rng = np.random.default_rng(seed)
    code = design_code(tile).code
    K = code.shape[2]
    truth = rng.random((2 * K, H, W)).astype(np.float32)
    frames = capture(truth, code)
    guide = rng.random(truth.shape).astype(np.float32)
    video, loo = oriented_nc(frames, code, guide)
    # NaN only where no sample is within the time kernel's reach (a picture smaller than the tile).
    assert np.isfinite(video).all() or min(H, W) < 4
    assert not np.isinf(video).any()
    est = video[np.isfinite(video)]
    lo, hi = float(frames.min()), float(frames.max())
    assert est.min() >= lo - 1e-6 and est.max() <= hi + 1e-6
    mask = sample_mask(truth.shape, code)
    np.testing.assert_array_equal(video[mask], truth[mask])
    finite = np.isfinite(loo)
    assert (loo[finite] >= lo - 1e-5).all() and (loo[finite] <= hi + 1e-5).all()


def test_bad_shapes_are_refused(code24):
    frames = np.zeros((2, 8, 8), np.float32)
    with pytest.raises(ValueError, match=r"`guide` must be the \(S, H, W\) = \(16, 8, 8\) video"):
        oriented_nc(frames, code24, np.zeros((8, 8, 8)))
    with pytest.raises(ValueError, match=r"`where` must be a bool \(S, H, W\) = \(16, 8, 8\) array; got float64"):
        oriented_nc(frames, code24, np.zeros((16, 8, 8)), where=np.ones((16, 8)))
    guide = np.zeros((16, 8, 8))
    guide[5, 2, 3] = np.nan
    with pytest.raises(ValueError, match=r"`guide` sub-frame 5 holds NaN or infinite values"):
        oriented_nc(frames, code24, guide)
    for bad in (np.nan, np.inf, -np.inf):  # a float16 guide, checked by its exponent bits
        held = np.full((16, 8, 8), 65504, np.float16)  # the largest finite float16 passes
        held[9, 7, 7], held[12, 0, 0] = bad, bad
        with pytest.raises(ValueError, match=r"`guide` sub-frame 9 holds NaN or infinite values"):
            oriented_nc(frames, code24, held)
    oriented_nc(frames, code24, np.full((16, 8, 8), -65504, np.float16))
    with pytest.raises(ValueError, match=r"`fallback` must be an \(S, H, W\) = \(16, 8, 8\) array"):
        oriented_nc(frames, code24, np.zeros((16, 8, 8)), fallback=np.ones((2, 8, 8)))


@pytest.mark.parametrize(("H", "W"), [(1, 1), (1, 7), (2, 3), (3, 24), (4, 2)])
def test_pictures_smaller_than_the_kernel(rng, code24, H, W):
    """The 9×9 kernels fold back more than once on a picture this small: the same as the reference (whose
    folding the brute-force leave-one-out test checks), and for a guide without edges nc's estimates."""
    truth = smooth_video(rng, 16, H, W)
    frames = capture(truth, code24)
    guide = smooth_video(rng, 16, H, W) + _edge_video(16, H, W, angle=1.1)
    got_v, got_l = oriented_nc(frames, code24, guide)
    want_v, want_l = oriented_nc_reference(frames, code24, guide)
    np.testing.assert_allclose(got_v, want_v, atol=1e-6, rtol=0)
    assert np.array_equal(np.isnan(got_l), np.isnan(want_l))
    np.testing.assert_allclose(got_l, want_l, atol=1e-6, rtol=0)
    flat_v, flat_l = oriented_nc(frames, code24, np.zeros_like(truth))
    nc, nc_loo = nc_leave_one_out(frames, code24, tensor=(1, 1, 1), time=0.25)
    reached = np.isfinite(flat_v)  # elsewhere nc takes the nearest sample, oriented nc its fallback
    assert reached.mean() > 0.5
    np.testing.assert_allclose(flat_v[reached], nc[reached], atol=1e-5, rtol=0)
    # (nc's own leave-one-out is off by up to 0.009 on pictures 1–3 px across, against brute force: not compared.)
    assert np.array_equal(np.isnan(flat_l), np.isnan(nc_loo))


def test_leave_one_out_is_the_estimate_without_the_sample(rng, code22):
    """Brute force: every other sample weighed by the folded kernels in time and space (a border pixel meets
    its own reflections, which the leave-one-out must take away too)."""
    from flexvox_core.forward import sample_mask as mask_of
    from flexvox_core.forward import sparse_volume
    from flexvox_core.reconstruct.diffusion import gaussian_kernel
    from flexvox_core.reconstruct.oriented_nc import ALPHA, SIGMA, bank_index, kernel_weights, structure

    F, H, W, K = 3, 5, 6, 4
    truth = smooth_video(rng, F * K, H, W)
    frames = capture(truth, code22)
    guide = truth + _edge_video(F * K, H, W, angle=0.3)
    _, loo = oriented_nc(frames, code22, guide, missing=[False, False, True])
    vals, mask = sparse_volume(frames, code22).astype(np.float64), mask_of((F * K, H, W), code22)
    mask[2 * K:] = False  # the dropped frame
    gt = gaussian_kernel(SIGMA, np.float64)
    r = gt.size // 2

    def fold(i, n):
        i %= 2 * n
        return 2 * n - 1 - i if i >= n else i

    checked = 0
    for s in range(2 * K):
        j = structure(guide[s]).astype(np.float64)
        for y in range(H):
            for x in range(W):
                if not mask[s, y, x]:
                    continue
                b = int(bank_index(j[0, y, x], j[1, y, x], j[2, y, x]))
                level = 0.0 if b == 0 else (0.5 if b <= ANGLES else 1.0)
                theta = 0.0 if b == 0 else ((b - 1) % ANGLES) * np.pi / ANGLES
                num = den = 0.0
                for d in range(-r, r + 1):
                    t = fold(s + d, F * K)
                    for dy in range(-4, 5):
                        for dx in range(-4, 5):
                            yy, xx = fold(y + dy, H), fold(x + dx, W)
                            if (t, yy, xx) == (s, y, x) or not mask[t, yy, xx]:
                                continue
                            w = gt[d + r] * float(kernel_weights(dx, dy, SIGMA, ALPHA, level, theta))
                            num += w * vals[t, yy, xx]
                            den += w
                assert loo[s // K, y, x] == pytest.approx(num / den, abs=1e-5)
                checked += 1
    assert checked == 2 * H * W and np.isnan(loo[2]).all()


def test_compiled_and_numpy_bank_indices_agree_at_ties_and_odd_values():
    from itertools import product

    from flexvox_core.reconstruct.oriented_nc import _HIGH, _LOW, _TAN
    from flexvox_core.reconstruct.oriented_nc_kernel import _bank_index

    t = float(np.tan(np.pi / 8))
    values = [0.0, -0.0, 1.0, -1.0, 0.5, t, -t, 2.0, 1e-45, np.inf, -np.inf, np.nan, 0.25, 0.75]
    rng = np.random.default_rng(4)
    triples = list(product(values, repeat=3)) + [tuple(v) for v in rng.normal(size=(2000, 3))]
    # Exact sector edges and level thresholds: J_xx − J_yy = a, 2 J_xy = b.
    triples += [(1 + a / 2, b / 2, 1 - a / 2) for a, b in ((t, 1.0), (1.0, t), (0.25 * 2, 0.0), (0.75 * 2, 0.0))]
    for jxx, jxy, jyy in triples:
        assert _bank_index(jxx, jxy, jyy, _LOW, _HIGH, _TAN) == int(bank_index(jxx, jxy, jyy)), (jxx, jxy, jyy)


def test_the_bank_row_pass_chooses_as_the_numpy_bank_index():
    """The branch-free row pass (float32 entries compared in float64) at ties, signed zeros, tiny, huge, infinite and
    NaN entries, and random ones: numpy's choice of the same float32 values, at every offset of a row."""
    from itertools import product

    from flexvox_core.reconstruct.oriented_nc import _HIGH, _LOW, _TAN
    from flexvox_core.reconstruct.oriented_nc_kernel import bank_row

    t = float(np.float32(np.tan(np.pi / 8)))
    values = [0.0, -0.0, 1.0, -1.0, 0.5, t, -t, 2.0, 1e-45, 3e38, np.inf, -np.inf, np.nan, 0.25, 0.75]
    rng = np.random.default_rng(4)
    triples = np.array(list(product(values, repeat=3)) + list(rng.normal(size=(2000, 3))), np.float32)
    # Exact sector edges and level thresholds (in float32): J_xx − J_yy = a, 2 J_xy = b.
    edges = [(1 + a / 2, b / 2, 1 - a / 2) for a, b in ((t, 1.0), (1.0, t), (0.5, 0.0), (1.5, 0.0))]
    triples = np.concatenate([triples, np.array(edges, np.float32)])
    n = len(triples)
    j = np.ascontiguousarray(triples.T.reshape(3, 1, n))
    want = bank_index(*(j[i, 0].astype(np.float64) for i in range(3)))
    for x0, x1 in ((0, n), (3, n - 5), (7, 8)):
        got = np.full(n, -1, np.int8)
        bank_row(j, 0, x0, x1, _LOW, _HIGH, _TAN, got)
        np.testing.assert_array_equal(got[x0:x1], want[x0:x1])
        assert (got[:x0] == -1).all() and (got[x1:] == -1).all()


def test_the_dense_bank_is_the_bank_in_rows_of_columns():
    from flexvox_core.reconstruct.oriented_nc_kernel import REACH, ROW, dense_bank

    bank = kernel_bank()
    dense = dense_bank(bank)
    n = bank.shape[1]
    assert dense.shape == (2, len(bank), 2 * REACH + 1, ROW) and dense.dtype == np.float32
    assert n == 2 * REACH + 1  # the bank fills the rows: no zero row read for nothing
    np.testing.assert_array_equal(dense[0, :, :, :n], bank)
    assert not dense[:, :, :, n:].any()
    centre = np.zeros(dense.shape[1:], bool)
    centre[:, REACH, REACH] = True
    np.testing.assert_array_equal(dense[1][~centre], dense[0][~centre])
    assert (dense[1][centre] == 0).all() and (dense[0][centre] == 1).all()
    small = dense_bank(bank[:, 2:-2, 2:-2])  # a smaller kernel sits in the middle of the rows
    np.testing.assert_array_equal(small[0, :, 2:-2, 2:n - 2], bank[:, 2:-2, 2:-2])
    with pytest.raises(ValueError, match=r"kernels of 11×11 px do not fit the dense rows \(9 px, odd sizes\)"):
        dense_bank(np.ones((2, 11, 11), np.float32))


@pytest.mark.parametrize(("tile", "shape", "dropped"), [((4, 4), (3, 13, 14), (1,)), ((2, 4), (2, 21, 19), ()),
                                                         ((2, 2), (4, 11, 9), (0, 2)), ((4, 4), (2, 1, 7), ())])
def test_the_float32_kernel_is_the_float64_kernel_to_float32_rounding(rng, tile, shape, dropped):
    """The kernel sums in float32 (dense rows away from the edges, tap lists at them), the float64 kernel it
    replaced in float64 tap by tap (with OpenCV's structure tensor, as before; no kernel is chosen otherwise on these
    pictures): within 1e-6 at values up to 1.5 (float32's rounding of sums of at most 81 terms and a division: its
    unit at 1 is 1.2e-7), the same voxels estimated and the same leave-one-outs NaN."""
    from .oriented_float64 import oriented_nc_float64

    code = design_code(tile).code
    F, H, W = shape
    K = code.shape[2]
    truth = smooth_video(rng, F * K, H, W) + _edge_video(F * K, H, W, angle=0.6) * 0.5
    frames = capture(truth, code)
    missing = np.zeros(F, bool)
    missing[list(dropped)] = True
    where = rng.random(truth.shape) < 0.7
    fallback = np.full(truth.shape, -1.0, np.float32)
    got_v, got_l = oriented_nc(frames, code, truth, where=where, fallback=fallback, missing=missing)
    want_v, want_l = oriented_nc_float64(frames, code, truth, where=where, fallback=fallback, missing=missing)
    assert np.array_equal(got_v == -1, want_v == -1) and np.array_equal(np.isnan(got_l), np.isnan(want_l))
    np.testing.assert_allclose(got_v, want_v, atol=1e-6, rtol=0)
    np.testing.assert_allclose(got_l, want_l, atol=1e-6, rtol=0)
    assert np.isfinite(got_l).any() and (got_v != -1).mean() > 0.5
    assert not np.isfinite(got_l[missing]).any()


@pytest.mark.parametrize(("H", "W"), [(1, 1), (2, 9), (5, 3), (13, 14), (84, 416), (4, 1)])
def test_the_compiled_structure_tensor_is_opencvs_to_float32_rounding(rng, H, W):
    """One pass of float32 multiply-adds against OpenCV's five filters, to float32 rounding: a gradient is a
    difference of blurred values, so its rounding is ~1e-7 of the guide's values (not of itself), and an entry's
    (2·|gradient| times that) at most 2e-6 · √(largest entry) · (largest guide value) here; written into any block
    of a larger plane, and into a strided ``out`` alike."""
    import cv2

    from flexvox_core.reconstruct.oriented_nc import _STRUCTURE_TAPS, structure
    from flexvox_core.reconstruct.oriented_nc_kernel import structure_block

    from .oriented_reference import structure_opencv

    guide = cv2.GaussianBlur(rng.random((H, W)).astype(np.float32), (0, 0), 1.5) * 3 + _edge_video(1, H, W)[0]
    want = structure_opencv(guide)
    got = structure(guide)
    assert got.dtype == np.float32 and got.shape == (3, H, W)
    np.testing.assert_allclose(got, want, atol=2e-6 * math.sqrt(want.max()) * np.abs(guide).max(), rtol=0)
    assert (got.max() > 0) == (H * W > 1)  # a single pixel has no gradient
    plane = np.full((3, H + 5, W + 7), -1.0, np.float32)
    structure_block(guide, *_STRUCTURE_TAPS, plane, 2, 3)
    np.testing.assert_array_equal(plane[:, 2:2 + H, 3:3 + W], got)  # the same bits wherever it is written
    plane[:, 2:2 + H, 3:3 + W] = -1
    assert (plane == -1).all()
    strided = np.zeros((3, H, 2 * W), np.float32)[:, :, ::2]
    assert structure(guide, out=strided) is strided
    np.testing.assert_array_equal(strided, got)
    with pytest.raises(ValueError, match=rf"`out` must have shape \(3, {H}, {W}\); got \(3, {H}, {W + 1}\)"):
        structure(guide, out=np.zeros((3, H, W + 1), np.float32))
    with pytest.raises(ValueError, match=r"structure_block is written for 7 taps, then 9"):
        structure_block(guide, _STRUCTURE_TAPS[1], _STRUCTURE_TAPS[0], plane, 2, 3)


def test_voxels_out_of_reach_keep_the_fallback(code24):
    """Frames 0 and 2 dropped: the first sub-frames of frame 0 are beyond the time kernel's reach of frame 1's
    samples and keep the fallback, as in the reference."""
    truth = np.full((24, 6, 8), 0.5, np.float32)
    frames = capture(truth, code24)
    fallback = np.full(truth.shape, 7.0, np.float32)
    missing = [True, False, True]
    got, _ = oriented_nc(frames, code24, truth, fallback=fallback, missing=missing)
    want, _ = oriented_nc_reference(frames, code24, truth, fallback=fallback, missing=missing)
    np.testing.assert_array_equal(got, want)
    assert (got[:4] == 7).all() and (got[8:16] == 0.5).all()


def test_the_same_bits_on_one_thread_and_on_two(monkeypatch, rng, code24):
    import flexvox_core.threads as threads

    truth = smooth_video(rng, 24, 20, 30)
    frames = capture(truth, code24)
    two = oriented_nc(frames, code24, truth)
    monkeypatch.setattr(threads, "workers", lambda: 1)
    one = oriented_nc(frames, code24, truth)
    for a, b in zip(one, two, strict=True):
        assert np.array_equal(a, b, equal_nan=True)


def test_the_video_can_go_into_a_dead_volume(rng, code24):
    truth = smooth_video(rng, 16, 10, 12)
    frames = capture(truth, code24)
    where = rng.random(truth.shape) < 0.5
    fallback = np.full(truth.shape, 0.25, np.float32)
    want, want_loo = oriented_nc(frames, code24, truth, where=where, fallback=fallback)
    dead = np.full(truth.shape, -1.0, np.float32)
    got, got_loo = oriented_nc(frames, code24, truth, where=where, fallback=fallback, out=dead)
    assert got is dead
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got_loo, want_loo)
    with pytest.raises(ValueError, match=r"`out` must be a writable C-contiguous float32 array of shape "
                                         r"\(16, 10, 12\) that shares no memory with the other inputs"):
        oriented_nc(frames, code24, truth, fallback=fallback, out=fallback)


@pytest.mark.parametrize(("s0", "s1"), [(0, 8), (8, 24), (5, 11), (23, 24)])
def test_some_sub_frames_are_the_whole_ones_and_read_only_theirs(rng, code24, s0, s1):
    from tests.flexvox_core.motion.band_volumes import Counted

    truth = smooth_video(rng, 24, 10, 12)
    frames = capture(truth, code24)
    where = rng.random(truth.shape) < 0.6
    fallback = rng.uniform(0.1, 0.9, truth.shape).astype(np.float32)
    guide = truth.copy()
    guide[:s0] = np.nan  # the guide is read at these sub-frames alone
    guide[s1:] = np.nan
    want, want_loo = oriented_nc(frames, code24, truth, where=where, fallback=fallback)
    loo = np.full(frames.shape, np.nan, np.float32)
    chosen, fall = Counted(where, s1 - s0), Counted(fallback, s1 - s0)
    out = np.full((s1 - s0, 10, 12), -1.0, np.float32)
    got, got_loo = oriented_nc(frames, code24, guide, where=chosen, fallback=fall, subframes=(s0, s1), loo=loo,
                               out=out)
    assert got is out and got_loo is loo
    np.testing.assert_array_equal(got, want[s0:s1])
    f0, f1 = s0 // 8, -(-s1 // 8)  # the frames these sub-frames belong to: theirs alone are written
    assert np.isfinite(want_loo[f0:f1]).any()
    assert not np.isfinite(got_loo[:f0]).any() and not np.isfinite(got_loo[f1:]).any()
    # A sample's leave-one-out is written at its own sub-frame: those of [s0, s1) are the whole run's.
    mask = sample_mask(truth.shape, code24)[s0:s1]
    for i in range(s1 - s0):
        f = (s0 + i) // 8
        mine = mask[i]
        np.testing.assert_array_equal(got_loo[f][mine], want_loo[f][mine])
    assert chosen.handed == s1 - s0 and fall.handed == s1 - s0


def test_bad_sub_frames_are_refused(rng, code24):
    truth = smooth_video(rng, 16, 10, 12)
    frames = capture(truth, code24)
    for bad in ((4, 4), (-1, 3), (0, 17), (1.5, 3), "ab"):
        with pytest.raises(ValueError, match=r"`subframes` must be \(s0, s1\), whole numbers with "
                                             r"0 <= s0 < s1 <= 16; got"):
            oriented_nc(frames, code24, truth, subframes=bad)
    with pytest.raises(ValueError, match=r"`loo` must be a writable C-contiguous float32 array of shape "
                                         r"\(2, 10, 12\)"):
        oriented_nc(frames, code24, truth, loo=np.zeros((2, 10, 12)))
    with pytest.raises(ValueError, match=r"`out` must be a writable C-contiguous float32 array of shape "
                                         r"\(4, 10, 12\)"):
        oriented_nc(frames, code24, truth, subframes=(0, 4), out=np.zeros((16, 10, 12), np.float32))


def test_a_workspace_keeps_the_threads_planes_from_call_to_call(rng, code24):
    truth = smooth_video(rng, 24, 10, 12)
    frames = capture(truth, code24)
    where = rng.random(truth.shape) < 0.6
    want, want_loo = oriented_nc(frames, code24, truth, where=where)
    workspace = [(np.zeros((3, 5, 5), np.float32), np.empty((5, 5)), np.empty((5, 5)))]  # another size: not used
    loo = np.full(frames.shape, np.nan, np.float32)
    for s0 in range(0, 24, 8):
        got, _ = oriented_nc(frames, code24, truth, where=where, subframes=(s0, s0 + 8), loo=loo, workspace=workspace)
        np.testing.assert_array_equal(got, want[s0:s0 + 8])
        if s0 == 0:
            kept = {id(planes[0]) for planes in workspace}
            assert workspace and all(planes[0].shape == (3, 10, 12) for planes in workspace)
        else:
            assert kept <= {id(planes[0]) for planes in workspace}  # the planes are kept, not made again
    np.testing.assert_array_equal(loo, want_loo)


def test_a_float16_guide_is_read_as_float32_of_its_values(rng, code24):
    """Motion-aware holds its high-TR guide in float16: the same bits as the float32 of those values."""
    truth = smooth_video(rng, 24, 20, 30)
    frames = capture(truth, code24)
    held = truth.astype(np.float16)
    where = rng.random(truth.shape) < 0.6
    fallback = held  # a float16 fallback too, read a band at a time
    got = oriented_nc(frames, code24, held, where=where, fallback=fallback, subframes=(4, 20))
    want = oriented_nc(frames, code24, held.astype(np.float32), where=where,
                       fallback=held.astype(np.float32), subframes=(4, 20))
    assert (held.astype(np.float32) != truth).any()  # the rounding is seen
    for a, b in zip(got, want, strict=True):
        assert a.dtype == np.float32 and np.array_equal(a, b, equal_nan=True)


def _whole_rows(wanted):
    """oriented_nc's blocks as they were before: the first wanted row to the last, every column."""
    rows = np.flatnonzero(wanted.any(axis=1))
    return [(int(rows[0]), int(rows[-1]) + 1, 0, wanted.shape[1])] if len(rows) else []


@pytest.mark.parametrize(("tile", "shape", "dropped"), [((2, 4), (2, 150, 203), False), ((4, 4), (2, 131, 97), True),
                                                         ((2, 2), (3, 70, 161), True)])
def test_blocks_of_rows_and_columns_give_the_whole_rows_bits(monkeypatch, rng, tile, shape, dropped):
    """The structure tensor and the time blur made over each band's wanted columns alone (and their margins) give
    the bits of whole rows, on odd sizes and with a dropped frame."""
    import flexvox_core.reconstruct.oriented_nc as module

    code = design_code(tile).code
    F, H, W = shape
    K = code.shape[2]
    truth = smooth_video(rng, F * K, H, W) + _edge_video(F * K, H, W, angle=0.6) * 0.3
    guide = (truth + rng.normal(0, 0.05, truth.shape)).astype(np.float32)  # texture: every kernel of the bank
    frames = capture(truth, code)
    missing = None
    if dropped:
        missing = np.zeros(F, bool)
        missing[1] = True
    # Blobs of wanted voxels (as motion-aware's moving voxels), some reaching the picture's edges, a few alone.
    y, x = np.mgrid[0:H, 0:W]
    where = np.zeros(truth.shape, bool)
    for s in range(F * K):
        for _ in range(3):
            cy, cx, r = rng.uniform(-5, H + 5), rng.uniform(-5, W + 5), rng.uniform(3, 25)
            where[s] |= (y - cy) ** 2 + (x - cx) ** 2 < r * r
        where[s] |= rng.random((H, W)) < 0.002
    where[3] = False  # a sub-frame with nothing wanted
    fallback = rng.uniform(0.1, 0.9, truth.shape).astype(np.float32)
    got = oriented_nc(frames, code, guide, where=where, fallback=fallback, missing=missing)
    blocks = [module._blocks(where[s]) for s in range(F * K)]
    assert any(len(b) > 1 for b in blocks) and any(x1 - x0 < W for b in blocks for _, _, x0, x1 in b)
    monkeypatch.setattr(module, "_blocks", _whole_rows)
    want = oriented_nc(frames, code, guide, where=where, fallback=fallback, missing=missing)
    for a, b in zip(got, want, strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert np.isfinite(got[1]).any()


def test_blocks_cover_every_wanted_voxel(rng):
    from flexvox_core.reconstruct.oriented_nc import ALIGN, BLOCK_ROWS, _aligned_columns, _blocks

    wanted = rng.random((200, 77)) < 0.002
    wanted[:, 40:] = False  # some bands' columns end before others'
    wanted[130:140] = False
    covered = np.zeros_like(wanted)
    for y0, y1, x0, x1 in _blocks(wanted):
        assert y0 < y1 and x0 < x1
        covered[y0:y1, x0:x1] = True
        a0, a1 = _aligned_columns(x0, x1, 77)
        assert a0 % ALIGN == 0 and (a1 % ALIGN == 0 or a1 == 77) and a0 <= x0 and x1 <= a1
    assert covered[wanted].all()
    assert _blocks(np.zeros((5, 6), bool)) == []
    full = np.ones((3 * BLOCK_ROWS + 5, 77), bool)
    assert _blocks(full) == [(0, 3 * BLOCK_ROWS + 5, 0, 77)]  # bands over the same columns: one block


@pytest.mark.parametrize("W", [640, 203, 97])
def test_a_blocks_structure_tensor_is_the_whole_pictures_bits(rng, W):
    """A block's tensor, made over its span and :data:`_PAD` px around (aligned to ALIGN columns, or not), is the
    whole picture's there bit for bit: each pixel's arithmetic is the same wherever the vector loops end."""
    from flexvox_core.reconstruct.oriented_nc import _PAD, _aligned_columns, structure

    H = 90
    guide = rng.random((H, W)).astype(np.float32)
    whole = structure(guide)
    spans = [(0, W), (W - 1, W), (W - 7, W), (W // 2, W), (3, 11), (W // 3, W // 3 + 17)]
    spans += [tuple(sorted(rng.integers(0, W, 2) + (0, 1))) for _ in range(20)]
    for x0, x1 in spans:
        y0, y1 = int(rng.integers(0, H - 10)), H - int(rng.integers(0, 3))
        b0, b1 = max(0, y0 - _PAD), min(H, y1 + _PAD)
        for a0, a1 in (_aligned_columns(x0, x1, W), (max(0, x0 - _PAD), min(W, x1 + _PAD))):
            part = structure(guide[b0:b1, a0:a1])
            assert np.array_equal(part[:, y0 - b0:y1 - b0, x0 - a0:x1 - a0], whole[:, y0:y1, x0:x1]), (x0, x1)


def _blocks_numpy(wanted):
    """oriented_nc's blocks found by numpy (the compiled row scan's reference): each band's wanted rows by
    ``any`` along them, its columns by ``any`` across its rows."""
    from flexvox_core.reconstruct.oriented_nc import BLOCK_ROWS, _aligned_columns

    W = wanted.shape[1]
    rows = wanted.any(axis=1)
    out = []
    for r0 in range(0, wanted.shape[0], BLOCK_ROWS):
        ys = np.flatnonzero(rows[r0:r0 + BLOCK_ROWS])
        if not len(ys):
            continue
        y0, y1 = r0 + int(ys[0]), r0 + int(ys[-1]) + 1
        xs = np.flatnonzero(wanted[y0:y1].any(axis=0))
        x0, x1 = int(xs[0]), int(xs[-1]) + 1
        if out and _aligned_columns(*out[-1][2:], W) == _aligned_columns(x0, x1, W):
            p0, _, p2, p3 = out[-1]
            out[-1] = (p0, y1, min(p2, x0), max(p3, x1))
        else:
            out.append((y0, y1, x0, x1))
    return out


@pytest.mark.parametrize("W", [1, 7, 8, 9, 16, 77, 640])
def test_the_compiled_row_scan_finds_numpys_blocks(rng, W):
    """The blocks from the compiled scan (8 columns a word, the rest one by one) are numpy's, on widths around a
    word's, on views that are not contiguous, at any density, wanted voxels in the first and last columns too."""
    from flexvox_core.reconstruct.oriented_nc import BLOCK_ROWS, _blocks

    for density in (0.0, 0.0005, 0.01, 0.3, 1.0):
        for H in (1, 5, BLOCK_ROWS + 3, 3 * BLOCK_ROWS):
            wanted = rng.random((H, W + 1)) < density
            wanted[rng.integers(0, H), [0, -1]] = density > 0
            for plane in (wanted[:, :W], wanted[:, 1:], np.ascontiguousarray(wanted[:, 1:])):
                assert _blocks(plane) == _blocks_numpy(plane)


def test_a_float16_guide_block_is_converted_to_its_float32_values():
    """The guide's float16 blocks go to float32 through OpenCV: every finite float16 value (subnormals, ±0, the
    largest) is numpy's float32 of it bit for bit; blocks too small for OpenCV (1×1) and strided ones too."""
    from flexvox_core.reconstruct.oriented_nc import _as_float32

    every = np.arange(1 << 16, dtype=np.uint16).view(np.float16)
    every = every[np.isfinite(every)]
    plane = np.resize(every, (2, every.size // 2 + 1))
    got = _as_float32(plane)
    assert got.dtype == np.float32 and got.flags.c_contiguous
    np.testing.assert_array_equal(got.view(np.uint32), plane.astype(np.float32).view(np.uint32))
    big = np.resize(every, (40, 50))
    for block in (big[3:4, 5:6], big[3:20, 5:6], big[3:4, 5:40], big[3:20:2, 5:40], big[1:39, 7:49]):
        got = _as_float32(block)
        assert got.shape == block.shape and got.dtype == np.float32 and got.flags.c_contiguous
        np.testing.assert_array_equal(got.view(np.uint32), block.astype(np.float32).view(np.uint32))


@pytest.mark.parametrize(("tile", "shape", "dropped"), [((2, 4), (2, 12, 17), False), ((2, 2), (4, 11, 9), True),
                                                         ((4, 4), (4, 23, 30), True)])
def test_a_plan_without_the_fallback_copied_writes_the_wanted_voxels_alone(rng, tile, shape, dropped):
    """``OrientedNc.run(..., fill=False)``: at the wanted voxels the bits of ``oriented_nc`` (the fallback's value
    where no sample is in reach), every other voxel of ``out`` as it was; the same leave-one-out. Odd sizes, dropped
    frames."""
    from flexvox_core.reconstruct.oriented_nc import OrientedNc

    code = design_code(tile).code
    F, H, W = shape
    K = code.shape[2]
    truth = smooth_video(rng, F * K, H, W) + _edge_video(F * K, H, W, angle=0.6) * 0.5
    frames = capture(truth, code)
    missing = np.array([False, True, True, False]) if dropped else None  # two dropped: a gap beyond nc's reach
    where = rng.random(truth.shape) < 0.4
    fallback = rng.uniform(0.1, 0.9, truth.shape).astype(np.float32)
    want, want_loo = oriented_nc(frames, code, truth, where=where, fallback=fallback, missing=missing)
    plan = OrientedNc(frames, code, truth, missing=missing)
    loo = np.full(frames.shape, np.nan, np.float32)
    for s0, s1 in ((0, K), (K, F * K)):
        out = np.full((s1 - s0, H, W), -7.0, np.float32)
        got, _ = plan.run(s0, s1, where[s0:s1], fallback[s0:s1], out=out, loo=loo, fill=False)
        assert got is out
        chosen = where[s0:s1]
        np.testing.assert_array_equal(got[chosen], want[s0:s1][chosen])
        assert (got[~chosen] == -7).all()
    np.testing.assert_array_equal(loo, want_loo)
    if dropped:  # the gap's middle sub-frames have no sample in reach: the fallback's value
        assert (want[where] == fallback[where]).any()
    with pytest.raises(ValueError, match=r"`fill=False` needs the voxels to estimate and a fallback"):
        plan.run(0, K, None, fallback[:K], fill=False)
