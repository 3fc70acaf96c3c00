"""nc's compiled time pass (flexvox_core/reconstruct/nc_time_kernel.py) against the plain numpy path it replaces."""

import itertools

import numpy as np
import pytest

import flexvox_core.reconstruct.diffusion as D
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.reconstruct import diffuse
from tests.flexvox_core.reconstruct.nc_reference import nc_naive

from .conftest import smooth_video


def _plain_time_blur(frames, code, sigma_t, dtype, present):
    """The reference: the sparse sample volume, blurred along time with OpenCV (the general path)."""
    num, order = D._sample_volume(frames, code, dtype)
    flat = num.reshape(len(num), -1)
    D._blur_rows(flat, D.gaussian_kernel(sigma_t, dtype), flat)
    return num, order


def _reference(monkeypatch, *args, **kwargs):
    """``diffuse`` with the time pass in plain numpy/OpenCV (the code before the compiled pass)."""
    with monkeypatch.context() as m:
        m.setattr(D, "_nc_time_only", lambda *a: None)
        m.setattr(D, "_time_blurred_samples", _plain_time_blur)
        return diffuse(*args, **kwargs)


CASES = [
    ((0, 0, 1), 32.0, (2, 4), (5, 20, 24)),  # still voxels' guide at K = 8: a long kernel
    ((0, 0, 1), 2.0, (4, 4), (4, 9, 13)),  # odd sizes, partial tiles
    ((0, 0, 1), 500.0, (2, 4), (2, 6, 8)),  # kernel longer than the clip: folded many times
    ((0, 0, 0.3), 1.0, (2, 2), (3, 8, 8)),
    ((0.05, 0.05, 0.95), 5.0, (4, 4), (4, 18, 22)),  # the fixed-tensor guide
    ((1, 1, 0.05), 2.0, (2, 4), (3, 10, 12)),  # the high-TR reconstruction
    ((1, 1, 1), 500.0, (2, 2), (1, 5, 7)),  # every kernel longer than its axis
]


@pytest.mark.parametrize(("tensor", "time", "tile", "shape"), CASES)
@pytest.mark.parametrize("dropped", [False, True])
def test_compiled_time_pass_matches_the_plain_one(monkeypatch, rng, tensor, time, tile, shape, dropped):
    code = design_code(tile).code
    F, H, W = shape
    truth = smooth_video(rng, F * code.shape[2], H, W)
    frames = capture(truth, code)
    missing = None
    if dropped and F > 2:
        missing = np.zeros(F, bool)
        missing[1] = True
    for dtype, tol in ((np.float32, 1e-6), (np.float64, 1e-12)):
        for keep in (True, False):
            kw = dict(tensor=tensor, time=time, missing=missing, dtype=dtype, keep_samples=keep)
            got = diffuse(frames, code, **kw)
            want = _reference(monkeypatch, frames, code, **kw)
            assert got.dtype == want.dtype == dtype
            np.testing.assert_allclose(got, want, atol=tol, rtol=0)


def test_time_only_matches_the_scipy_baseline_in_float64(rng):
    code = design_code((2, 4)).code
    frames = capture(rng.random((8 * 6, 9, 11)), code)
    fast = diffuse(frames, code, tensor=(0, 0, 1), time=20.0, dtype=np.float64)
    np.testing.assert_allclose(fast, nc_naive(frames, code, tensor=(0, 0, 1), time=20.0), atol=1e-12, rtol=0)


def test_no_sample_in_reach_takes_the_nearest_sample_as_before(monkeypatch, rng):
    # A short time kernel at K = 16 reaches no sample from most sub-frames: the nearest sample fills them.
    code = design_code((4, 4)).code
    frames = capture(rng.random((16 * 3, 8, 8)).astype(np.float32), code)
    got = diffuse(frames, code, tensor=(0, 0, 1), time=0.5)
    want = _reference(monkeypatch, frames, code, tensor=(0, 0, 1), time=0.5)
    np.testing.assert_allclose(got, want, atol=1e-6, rtol=0)
    assert np.isfinite(got).all()


def test_same_bits_on_one_thread_and_on_several(monkeypatch, rng):
    import flexvox_core.threads as threads

    code = design_code((4, 4)).code
    frames = capture(rng.random((16 * 3, 70, 40)).astype(np.float32), code)
    runs = []
    for n in (1, 2, 3):
        monkeypatch.setattr(threads, "workers", lambda n=n: n)
        runs.append([diffuse(frames, code, tensor=t, time=n_) for t, n_ in (((0, 0, 1), 32.0), ((1, 1, 0.05), 2.0))])
    for other in runs[1:]:
        for a, b in zip(runs[0], other, strict=True):
            np.testing.assert_array_equal(a, b)


def test_time_weights_sum_to_the_blurred_mask():
    # Each sub-frame's weights on a slot's samples add up to the time-blurred mask of that slot.
    g = D.gaussian_kernel(3.0, np.float64)
    K, F = 4, 5
    weight, first = D.time_weights(g, K, F, None)
    S = F * K
    blurred = D._fold_matrix(g, S) @ (np.arange(S)[:, None] % K == np.arange(K)[None, :]).astype(float)
    np.testing.assert_allclose(weight.sum(axis=2), blurred, atol=1e-14)
    assert (first >= 0).all() and (first + weight.shape[2] <= F).all()


@pytest.mark.parametrize(("tensor", "time"), [((0, 0, 1), 8.0), ((0, 0, 0.3), 1.0), ((0.05, 0.05, 0.95), 5.0)])
@pytest.mark.parametrize("dropped", [False, True])
@pytest.mark.parametrize("held", ["array", "packed", "bands"])
def test_diffuse_where_writes_diffuse_at_the_chosen_voxels_alone(monkeypatch, rng, tensor, time, dropped, held):
    from flexvox_core.motion.packed import PackedVolume
    from flexvox_core.reconstruct.diffusion import diffuse_where

    code = design_code((2, 4)).code
    F, H, W = 4, 40, 13  # a row's bits end in a partial byte
    frames = capture(smooth_video(rng, F * 8, H, W), code)
    missing = np.array([False, True, False, False]) if dropped else None
    where = rng.random((F * 8, H, W)) < 0.3
    where[:, 5:37] = False  # whole rows without a chosen voxel (the kernel skips them)
    before = rng.random(where.shape).astype(np.float32)
    out = before.copy()
    chosen = where
    if held != "array":  # held a bit per voxel: the bits read by the kernel as they are, or (an object without
        chosen = PackedVolume(where.shape)  # them) read SELECT_BAND sub-frames at a time (bands of 5: the last short)
        for t in range(len(where)):
            chosen.put(t, where[t])
        if held == "bands":
            chosen = _Bands(chosen)
            monkeypatch.setattr(D, "SELECT_BAND", 5)
    assert diffuse_where(frames, code, out, chosen, tensor=tensor, time=time, missing=missing) is out
    full = diffuse(frames, code, tensor=tensor, time=time, missing=missing)
    np.testing.assert_array_equal(out[where], full[where])  # the same bits: the same pass, samples kept
    np.testing.assert_array_equal(out[~where], before[~where])


class _Bands:
    """A selection read by bands alone (no ``packed`` bits)."""

    def __init__(self, packed):
        self.shape, self.band = packed.shape, packed.band


def test_diffuse_where_refuses_a_wrong_volume(rng):
    from flexvox_core.reconstruct.diffusion import diffuse_where

    code = design_code((2, 2)).code
    frames = capture(rng.random((8, 4, 4)).astype(np.float32), code)
    where = np.ones((8, 4, 4), bool)
    for out in (np.zeros((8, 4, 4)), np.zeros((4, 4, 4), np.float32), np.zeros((8, 4, 4), np.float32)[:, :, ::-1]):
        with pytest.raises(ValueError, match="`out` must be a writable C-contiguous float32 array"):
            diffuse_where(frames, code, out, where, tensor=(0, 0, 1), time=1.0)
    with pytest.raises(ValueError, match="`where` must have shape"):
        diffuse_where(frames, code, np.zeros((8, 4, 4), np.float32), where[:4], tensor=(0, 0, 1), time=1.0)
    from flexvox_core.motion.packed import PackedVolume

    with pytest.raises(ValueError, match=r"`where` must have shape \(8, 4, 4\); got \(8, 4, 5\)"):
        diffuse_where(frames, code, np.zeros((8, 4, 4), np.float32), PackedVolume((8, 4, 5)), tensor=(0, 0, 1),
                      time=1.0)
    wrong = PackedVolume((8, 4, 4))
    wrong.packed = np.zeros((8, 4, 2), np.uint8)
    with pytest.raises(ValueError, match=r"`where`.packed must be a C-contiguous uint8 array of shape \(8, 4, 1\)"):
        diffuse_where(frames, code, np.zeros((8, 4, 4), np.float32), wrong, tensor=(0, 0, 1), time=1.0)


# --------------------------------------------------------------------------- nc's finish, compiled


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_finish_plane_has_the_bits_of_its_numpy_reference(dtype):
    # One pass (divide above the floor, clip as np.clip, samples back) against the numpy steps it replaces: the
    # blurred mask at, just above and just below the floor, zeros and signed zeros at the range's ends.
    from flexvox_core.reconstruct.nc_time_kernel import finish_plane

    rng = np.random.default_rng(11)
    n = 1031  # odd
    floor = dtype(1e-12 * 0.37)
    den = rng.uniform(0.01, 1.0, n).astype(dtype)
    den[::7] = floor
    den[1::7] = np.nextafter(floor, dtype(1))
    den[2::7] = np.nextafter(floor, dtype(0))
    den[3::11] = 0
    num = (den * rng.uniform(-0.2, 1.2, n)).astype(dtype)
    num[4::13] = 0
    num[5::13] = -0.0
    own = rng.uniform(0, 1, n).astype(dtype)
    slot = rng.random(n) < 0.3
    for (lo, hi), keep in itertools.product([(dtype(0), dtype(0.8)), (dtype(-1), dtype(-0.0))], (True, False)):
        a, b = num.copy(), num.copy()
        low_a = finish_plane(a, den, floor, lo, hi, own, slot, keep)
        low_b = D._finish_numpy(b, den, floor, lo, hi, own, slot, keep)
        assert low_a == low_b == np.count_nonzero(den <= floor)
        assert a.tobytes() == b.tobytes()


def _nc_finished_by_numpy(monkeypatch, *args, **kwargs):
    with monkeypatch.context() as m:
        m.setattr(D, "_finish_plane", D._finish_numpy)
        return diffuse(*args, **kwargs)


@pytest.mark.parametrize(("tensor", "time", "tile", "shape", "missing"), [
    ((0.05, 0.05, 0.95), 5.0, (4, 4), (6, 19, 23), None),  # the guides' tensor, odd sizes: ends and an interior
    ((1, 1, 0.05), 2.0, (2, 4), (5, 10, 13), [False, True, False, False, True]),  # high-TR, dropped frames
    ((0.2, 0.0, 0.3), 0.5, (2, 2), (4, 9, 11), None),  # voxels without a sample in reach (nearest sample)
    ((1, 1, 1), 30.0, (2, 2), (3, 7, 9), [False, False, True]),  # a long kernel, a dropped frame
])
@pytest.mark.parametrize("keep_samples", [True, False])
def test_nc_with_compiled_finish_has_the_same_bits(monkeypatch, tensor, time, tile, shape, missing, keep_samples):
    code = design_code(tile).code
    frames = np.random.default_rng(5).uniform(0.1, 0.9, shape).astype(np.float32)
    frames[:, :2, :3] = 0.1  # the range's end reached
    kw = dict(tensor=tensor, time=time, missing=missing, keep_samples=keep_samples)
    kept = diffuse(frames, code, **kw)
    ref = _nc_finished_by_numpy(monkeypatch, frames, code, **kw)
    assert kept.tobytes() == ref.tobytes()
    if tensor == (0.2, 0.0, 0.3):
        # the nearest-sample fill ran (some voxel has no sample within the kernels' reach)
        assert np.isfinite(kept).all()


def test_nc_with_compiled_finish_has_the_same_bits_on_a_multiplexed_capture(monkeypatch):
    # A multiplexed capture, demultiplexed first (as every reconstruction takes it): nc on its identity capture.
    from flexvox_core import multiplexed_code
    from flexvox_core.reconstruct import as_identity_capture

    mc = multiplexed_code((1, 3), placement=[[0, 1, 2]])
    video = np.random.default_rng(8).uniform(0.2, 0.8, (9, 7, 11)).astype(np.float32)
    f, c = as_identity_capture(capture(video, mc.code), mc)
    kept = diffuse(f, c, tensor=(1, 1, 0.05), time=2.0)
    assert kept.tobytes() == _nc_finished_by_numpy(monkeypatch, f, c, tensor=(1, 1, 0.05), time=2.0).tobytes()
