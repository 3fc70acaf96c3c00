import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from flexvox_core.codes import code_from_order
from flexvox_core.forward import capture, sample_mask
from flexvox_core.reconstruct import diffuse, rebin, sigmas, stability_bound
from tests.flexvox_core.reconstruct.nc_reference import nc_naive

from .conftest import smooth_video


def _frames(rng, code, F, H, W, dtype=np.float32):
    K = code.shape[2]
    return capture(rng.random((F * K, H, W)).astype(dtype), code)


# ----------------------------------------------------------------- nc against its baseline


@pytest.mark.parametrize(
    ("tensor", "time", "shape"),
    [
        ((1, 1, 1), 0.25, (2, 8, 12)),
        ((1, 1, 1), 2.0, (2, 9, 13)),  # odd sizes, partial tiles
        ((1, 1, 0), 1.0, (1, 8, 8)),  # zero eigenvalue (no temporal blur)
        ((0, 0, 1), 3.0, (3, 6, 6)),
        ((1e6, 1, 1e-6), 1e-3, (2, 8, 8)),  # ratio 1e12, kernel along x wider than the image
        ((1, 1, 1), 500.0, (1, 5, 7)),  # every kernel longer than its axis (folded)
        ((1, 0, 0), 0.01, (2, 4, 8)),  # nearly nothing in reach: nearest-sample fall-back
        # Clips longer than the time kernel's reach plus a period: the blurred mask's ends are
        # computed apart and its interior repeats one period.
        ((0.3, 0.3, 1), 2.0, (12, 6, 8)),
        ((1, 1, 0.05), 2.0, (9, 5, 7)),
        ((0, 0, 1), 8.0, (11, 4, 4)),
    ],
)
def test_fast_nc_matches_the_scipy_baseline(code24, rng, tensor, time, shape):
    F, H, W = shape
    frames = _frames(rng, code24, F, H, W, np.float64)
    fast = diffuse(frames, code24, tensor=tensor, time=time, dtype=np.float64)
    slow = nc_naive(frames, code24, tensor=tensor, time=time)
    np.testing.assert_allclose(fast, slow, atol=1e-10, rtol=0)
    fast32 = diffuse(frames, code24, tensor=tensor, time=time)
    assert fast32.dtype == np.float32
    np.testing.assert_allclose(fast32, slow, atol=2e-6, rtol=0)


def test_sigmas_and_stability_bound():
    assert sigmas((1, 0, 4), 0.5) == (1.0, 0.0, 2.0)
    assert stability_bound((1, 2, 3)) == pytest.approx(1 / 12)


# ----------------------------------------------------------------- invariants of every solver


@pytest.mark.parametrize("solver", ["nc", "explicit", "steady"])
def test_constant_video_is_unchanged(code24, solver):
    video = np.full((16, 7, 9), 0.37, np.float32)
    out = diffuse(capture(video, code24), code24, tensor=(1, 0.5, 2), time=1.5, solver=solver)
    np.testing.assert_allclose(out, video, rtol=1e-6)


@pytest.mark.parametrize("solver", ["nc", "explicit", "steady"])
@pytest.mark.parametrize("tensor", [(1, 1, 1), (0.95, 0.05, 0.05), (1, 1e-6, 0), (1e-6, 0, 1)])
def test_maximum_principle_and_kept_samples(code24, rng, solver, tensor):
    frames = _frames(rng, code24, 2, 8, 12)
    out = diffuse(frames, code24, tensor=tensor, time=2.0, solver=solver)
    assert np.isfinite(out).all()
    assert out.min() >= frames.min() and out.max() <= frames.max()
    mask = sample_mask(out.shape, code24)
    samples = np.stack([frames[f][code24.argmax(2)[np.arange(8)[:, None] % 2, np.arange(12) % 4] == k]
                        for f in range(2) for k in range(8)])
    assert np.array_equal(out[mask], samples.ravel())


def test_keep_samples_false_smooths_the_samples(code24, rng):
    frames = _frames(rng, code24, 1, 8, 8)
    kept = diffuse(frames, code24, tensor=(1, 1, 1), time=1.0)
    free = diffuse(frames, code24, tensor=(1, 1, 1), time=1.0, keep_samples=False)
    mask = sample_mask(kept.shape, code24)
    assert np.array_equal(kept[~mask], free[~mask])
    assert not np.allclose(kept[mask], free[mask])


@pytest.mark.parametrize("scale", [1e-12, 1e6])
@pytest.mark.parametrize("solver", ["nc", "explicit", "steady"])
def test_tiny_and_huge_intensities_scale_exactly(code24, rng, scale, solver):
    frames = _frames(rng, code24, 2, 8, 8, np.float64) + 0.1
    base = diffuse(frames, code24, tensor=(1, 1, 0.5), time=1.0, solver=solver, dtype=np.float64)
    scaled = diffuse(frames * scale, code24, tensor=(1, 1, 0.5), time=1.0, solver=solver, dtype=np.float64)
    np.testing.assert_allclose(scaled / scale, base, rtol=1e-6)
    s32 = diffuse((frames * scale).astype(np.float32), code24, tensor=(1, 1, 0.5), time=1.0, solver=solver)
    assert np.isfinite(s32).all()
    np.testing.assert_allclose(s32 / scale, base, rtol=1e-4)


@pytest.mark.parametrize("solver", ["nc", "explicit"])
def test_float32_agrees_with_float64(code24, rng, solver):
    video = smooth_video(rng, 16, 11, 13, np.float64)
    frames = capture(video, code24)
    a = diffuse(frames, code24, tensor=(1, 1, 1), time=1.0, solver=solver, dtype=np.float64)
    b = diffuse(frames.astype(np.float32), code24, tensor=(1, 1, 1), time=1.0, solver=solver)
    assert a.dtype == np.float64 and b.dtype == np.float32
    np.testing.assert_allclose(b, a, atol=1e-5)


def test_k1_single_frame_and_odd_sizes(rng):
    one = code_from_order([[0]])
    frames = rng.random((1, 5, 3)).astype(np.float32)
    for solver in ("nc", "explicit", "steady"):
        out = diffuse(frames, one, solver=solver)
        assert np.array_equal(out, frames)  # every voxel is a sample
    code = code_from_order([[0, 3], [2, 1]])
    for H, W in ((1, 1), (1, 5), (3, 1), (5, 7)):
        f = rng.random((1, H, W)).astype(np.float32)
        for tensor in ((1, 1, 0), (0, 0, 1), (1, 1, 1)):
            for solver in ("nc", "explicit", "steady"):
                out = diffuse(f, code, tensor=tensor, time=0.5, solver=solver)
                assert out.shape == (4, H, W)
                assert np.isfinite(out).all()
                assert out.min() >= f.min() and out.max() <= f.max()


def test_no_sample_in_reach_falls_back_to_the_nearest_sample_of_the_pixel(code22, rng):
    frames = rng.random((3, 4, 4)).astype(np.float32)
    out = diffuse(frames, code22, tensor=(0, 0, 1), time=0.02)  # σt = 0.2: nothing in reach
    order = code22.argmax(2)
    for y in range(4):
        for x in range(4):
            times = np.arange(3) * 4 + order[y % 2, x % 2]
            nearest = np.abs(np.arange(12)[:, None] - times[None]).argmin(1)
            # ties (equidistant samples) may go either way
            close = np.isclose(out[:, y, x][:, None], frames[:, y, x][None], rtol=1e-6, atol=0)
            assert close.any(axis=1).all()
            d = np.abs(np.arange(12)[:, None] - times[None])
            unique = (d == d.min(1, keepdims=True)).sum(1) == 1
            np.testing.assert_allclose(out[unique, y, x], frames[nearest[unique], y, x], rtol=1e-6)


# ----------------------------------------------------------------- the paper's limiting cases


def test_limiting_tensors_are_local_like_the_matching_rebinning(code24, rng):
    """(0,0,1) mixes only a pixel's own samples, as [1, 1/K]; (1,1,0) only a sub-frame's, as [K, 1/K]."""
    frames = _frames(rng, code24, 2, 8, 12)
    bumped = frames.copy()
    bumped[1, 3, 5] += 0.5
    for tensor in ((0, 0, 1), (1, 1, 0)):
        diff = diffuse(bumped, code24, tensor=tensor, time=4.0) != diffuse(frames, code24, tensor=tensor, time=4.0)
        changed = np.argwhere(diff)
        if tensor == (0, 0, 1):
            assert {(int(y), int(x)) for _, y, x in changed} == {(3, 5)}
        else:
            slot = 8 + int(code24.argmax(2)[1, 1])
            assert set(changed[:, 0].tolist()) == {slot}
            assert len(changed) > 1


def test_limiting_tensors_are_exact_where_the_rebinning_is(code24, rng):
    static = np.repeat(rng.random((1, 8, 12)).astype(np.float32), 16, axis=0)
    f = capture(static, code24)
    np.testing.assert_array_equal(rebin(f, code24, "1x1x8"), static)
    np.testing.assert_allclose(diffuse(f, code24, tensor=(0, 0, 1), time=3.0), static, rtol=1e-6)
    flat = np.repeat(np.repeat(rng.random((16, 1, 1)).astype(np.float32), 8, 1), 12, 2)
    f = capture(flat, code24)
    np.testing.assert_array_equal(rebin(f, code24, "2x4x1"), flat)
    np.testing.assert_allclose(diffuse(f, code24, tensor=(1, 1, 0), time=3.0), flat, rtol=1e-6)


def test_ct_only_equals_rebin_1xK_within_interpolation(code22, rng):
    """Linear-in-time video: nc with (0,0,1), σt = K, is exact in the interior (a symmetric
    Gaussian on an evenly spaced sample train reproduces a line), while re-binning [1, 1/K]
    with interpolation between frame centres is off by the sample's offset from its frame
    centre: |D − R| ≤ |slope|·(K − 1)/2."""
    K, F, H, W = 4, 16, 4, 6
    base = rng.random((H, W))
    slope = rng.uniform(-0.01, 0.01, (H, W))
    video = (base[None] + slope[None] * np.arange(F * K)[:, None, None]).astype(np.float64)
    frames = capture(video, code22)
    D = diffuse(frames, code22, tensor=(0, 0, 1), time=K * K / 2.0, dtype=np.float64)
    R = rebin(frames, code22, "1x1x4", interpolate=True, dtype=np.float64)
    inner = slice(4 * K, (F - 4) * K)
    # exact up to the kernel's truncation at 4σ (edge weight e^-8): |error| << slope·K
    np.testing.assert_allclose(D[inner], video[inner], atol=1e-4)
    bound = np.abs(slope) * (K - 1) / 2
    assert np.all(np.abs(D[inner] - R[inner]) <= bound[None] + 1e-4)
    assert np.abs(D[inner] - R[inner]).max() > 0.25 * bound.max()  # the bound is the right size


def test_cxcy_only_equals_rebin_Kx1_within_interpolation(code22, rng):
    """Video linear in space in every sub-frame: nc with (1,1,0), σ = one tile pitch, is exact
    in the interior; re-binning [K, 1/K] with interpolation between tile centres is off by
    the gradient times the sample's offset from its tile centre (≤ (|gy| + |gx|)/2 here)."""
    S, H, W = 4, 32, 32
    gy = rng.uniform(-0.01, 0.01, S)
    gx = rng.uniform(-0.01, 0.01, S)
    yy, xx = np.mgrid[:H, :W]
    video = 0.5 + gy[:, None, None] * yy[None] + gx[:, None, None] * xx[None]
    frames = capture(video, code22)
    D = diffuse(frames, code22, tensor=(1, 1, 0), time=2.0, dtype=np.float64)  # σ = 2
    R = rebin(frames, code22, "2x2x1", interpolate=True, dtype=np.float64)
    inner = (slice(None), slice(8, -8), slice(8, -8))
    np.testing.assert_allclose(D[inner], video[inner], atol=1e-4)
    bound = (np.abs(gy) + np.abs(gx)) / 2
    assert np.all(np.abs(D[inner] - R[inner]) <= bound[:, None, None] + 1e-4)


# ----------------------------------------------------------------- explicit and steady


def test_explicit_runs_to_the_steady_state_and_steady_is_harmonic(code22, rng):
    frames = _frames(rng, code22, 1, 6, 6, np.float64)
    tensor = (1.0, 0.5, 2.0)
    steady = diffuse(frames, code22, tensor=tensor, solver="steady", dtype=np.float64)
    long = diffuse(frames, code22, tensor=tensor, time=2000.0, solver="explicit", dtype=np.float64)
    np.testing.assert_allclose(long, steady, atol=1e-5)
    # discrete harmonic at missing voxels: Σ c_i D_i² = 0 (reflecting ends)
    p = np.pad(steady, 1, mode="edge")
    lap = (tensor[2] * (p[2:, 1:-1, 1:-1] + p[:-2, 1:-1, 1:-1] - 2 * steady)
           + tensor[1] * (p[1:-1, 2:, 1:-1] + p[1:-1, :-2, 1:-1] - 2 * steady)
           + tensor[0] * (p[1:-1, 1:-1, 2:] + p[1:-1, 1:-1, :-2] - 2 * steady))
    mask = sample_mask(steady.shape, code22)
    assert np.abs(lap[~mask]).max() < 1e-5


def test_explicit_from_mean_or_nc_obeys_the_range(code24, rng):
    frames = _frames(rng, code24, 1, 8, 8)
    for init in ("nc", "mean"):
        out = diffuse(frames, code24, tensor=(1e-6, 1, 1e6 * 1e-6), time=3.0, solver="explicit", init=init)
        assert out.min() >= frames.min() and out.max() <= frames.max()


# ----------------------------------------------------------------- hypothesis


@st.composite
def cases(draw):
    m, n = draw(st.integers(1, 3)), draw(st.integers(1, 3))
    K = m * n
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    code = code_from_order(rng.permutation(K).reshape(m, n))
    F = draw(st.integers(1, 2))
    H, W = draw(st.integers(1, 9)), draw(st.integers(1, 9))
    exps = [draw(st.one_of(st.just(None), st.floats(-6, 0))) for _ in range(3)]
    tensor = tuple(0.0 if e is None else 10.0**e for e in exps)
    if max(tensor) == 0:
        tensor = (0.0, 0.0, 1.0)
    time = draw(st.floats(1e-3, 5.0))
    frames = rng.random((F, H, W)) * 10.0 ** draw(st.integers(-12, 6))
    return frames, code, tensor, time


@given(cases())
def test_no_nan_and_maximum_principle_for_drawn_tensors_and_shapes(case):
    frames, code, tensor, time = case
    for solver in ("nc", "explicit"):
        out = diffuse(frames, code, tensor=tensor, time=time, solver=solver)
        assert out.shape == (frames.shape[0] * code.shape[2],) + frames.shape[1:]
        assert np.isfinite(out).all()
        lo, hi = np.float32(frames.min()), np.float32(frames.max())
        assert out.min() >= lo and out.max() <= hi


# ----------------------------------------------------------------- misuse


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"tensor": (1, -1, 1)}, r"`tensor` entries must be finite and >= 0"),
        ({"tensor": (0, 0, 0)}, r"`tensor` must have at least one positive entry"),
        ({"tensor": (1, 1)}, r"`tensor` must be three numbers"),
        ({"tensor": (1, np.inf, 1)}, r"`tensor` entries must be finite"),
        ({"time": 0}, r"`time` must be a positive finite number; got 0"),
        ({"solver": "cg"}, r"`solver` must be one of nc, explicit, steady; got 'cg'"),
        ({"init": "zeros"}, r"`init` must be 'nc' or 'mean'"),
        ({"dtype": np.float16}, r"`dtype` must be float32 or float64"),
        ({"solver": "explicit", "tensor": (1e6, 1e6, 1e6), "time": 1.0}, r"more than 20000"),
        # a blur no recording is long enough for, whose kernel would not fit in memory: refused by its σ
        ({"time": 1e12}, r"time 1000000000000.0 with tensor \(0.15, 0.15, 1.0\) asks for a blur of "
                         r"σ = sqrt\(2·time·c\) = \(5.48e\+05, 5.48e\+05, 1.41e\+06\); at most 10000"),
        ({"time": 1e308}, r"asks for a blur of σ = sqrt\(2·time·c\) = \(inf, inf, inf\); at most 10000"),
        ({"tensor": (1e308, 1e308, 1)}, r"asks for a blur of σ = sqrt\(2·time·c\) = \(inf, inf, 1.73\)"),
    ],
)
def test_misuse_is_refused(code22, kw, match):
    with pytest.raises(ValueError, match=match):
        diffuse(np.zeros((1, 4, 4), np.float32), code22, **kw)


def test_nan_input_names_the_frame(code22):
    frames = np.zeros((3, 4, 4), np.float32)
    frames[2, 1, 1] = np.inf
    with pytest.raises(ValueError, match=r"`frames` camera frame 2 holds NaN or infinite values"):
        diffuse(frames, code22)
    with pytest.raises(ValueError, match=r"`frames` must have shape \(F, H, W\)"):
        diffuse(np.zeros((4, 4)), code22)


@given(
    tensor=st.sampled_from([(1.0, 1.0, 0.05), (0.05, 0.05, 0.95), (0.0, 0.0, 1.0), (0.3, 0.1, 0.0)]),
    time=st.floats(0.5, 40.0),
    s0=st.integers(0, 23),
    length=st.integers(1, 24),
    dropped=st.sampled_from([None, 0, 1, 2]),
    seed=st.integers(0, 2**16),
)
def test_subframes_are_the_whole_runs_rows(tensor, time, s0, length, dropped, seed):
    # A streaming run asks for one frame of a short window: the same values, computed alone.
    code = code_from_order([[0, 5, 7, 2], [6, 3, 1, 4]])  # K = 8
    frames = np.random.default_rng(seed).uniform(0.1, 0.9, (3, 6, 8)).astype(np.float32)
    missing = None if dropped is None else np.arange(3) == dropped
    s1 = min(24, s0 + length)
    whole = diffuse(frames, code, tensor=tensor, time=time, missing=missing)
    part = diffuse(frames, code, tensor=tensor, time=time, missing=missing, subframes=(s0, s1))
    assert part.shape == (s1 - s0, 6, 8) and np.isfinite(part).all()
    np.testing.assert_allclose(part, whole[s0:s1], rtol=0, atol=2e-6)


@pytest.mark.parametrize(("subframes", "kw", "message"), [
    ((4, 4), {}, r"`subframes` must satisfy 0 <= s0 < s1 <= 16 \(the clip's sub-frames\); got \(4, 4\)"),
    ((0, 17), {}, r"must satisfy 0 <= s0 < s1 <= 16 .*; got \(0, 17\)"),
    ("ab", {}, r"`subframes` must be two whole numbers \(s0, s1\) or None; got 'ab'"),
    ((0, 8), {"solver": "explicit"}, r"`subframes` needs solver='nc'; got solver='explicit'"),
])
def test_bad_subframes_are_refused_by_name(subframes, kw, message):
    code = code_from_order([[0, 5, 7, 2], [6, 3, 1, 4]])
    frames = np.full((2, 4, 8), 0.5, np.float32)
    with pytest.raises(ValueError, match=message):
        diffuse(frames, code, subframes=subframes, **kw)


NC_END_CASES = [
    ((0.05, 0.05, 0.95), 5.0, 6),  # the guides' tensor: ends and an interior
    ((1.0, 1.0, 0.05), 2.0, 4),  # the high-TR tensor: a short kernel
    ((0.0, 0.0, 0.3), 1.0, 3),  # the two ends overlap; sub-frames without a sample in reach
    ((1.0, 1.0, 1.0), 30.0, 9),  # a long kernel (filtered on OpenCV's threads)
    ((0.5, 0.5, 1.0), 500.0, 2),  # a kernel longer than the clip: blurred whole
]
"""(tensor, time, F) of the tests of nc's ends and interior made as they are finished."""


@pytest.mark.parametrize(("tensor", "time", "F"), NC_END_CASES)
def test_nc_finishes_the_ends_as_made_with_the_same_bits_as_when_held(monkeypatch, tensor, time, F):
    # diffuse's nc finishes the clip's end sub-frames as their blurred mask is made, a band of columns at a time;
    # with the ends held (as the leave-one-out reads them) every bit is the same.
    import flexvox_core.reconstruct.diffusion as D

    code = code_from_order([[0, 5, 7, 2], [6, 3, 1, 4]])  # K = 8
    frames = np.random.default_rng(3).uniform(0.1, 0.9, (F, 12, 20)).astype(np.float32)
    monkeypatch.setattr(D, "_CHUNK", 64)  # several bands of columns, the last one short (240 = 3·64 + 48)
    streamed = diffuse(frames, code, tensor=tensor, time=time)
    held = D._PeriodicDenominator
    monkeypatch.setattr(D, "_PeriodicDenominator", lambda den_k, F, gt, ends=None: held(den_k, F, gt))
    np.testing.assert_array_equal(streamed, diffuse(frames, code, tensor=tensor, time=time))


@pytest.mark.parametrize(("tensor", "time", "F"), NC_END_CASES)
@pytest.mark.parametrize("missing", [False, True])
def test_nc_blurs_in_space_as_it_finishes_with_the_same_bits_as_before(monkeypatch, tensor, time, F, missing):
    # diffuse's nc blurs the numerator's interior sub-frames in space just before it finishes each (the ends' first,
    # beside the mask's planes); with every sub-frame blurred first, in a pass of its own, every bit is the same.
    import flexvox_core.reconstruct.diffusion as D

    code = code_from_order([[0, 5, 7, 2], [6, 3, 1, 4]])  # K = 8
    frames = np.random.default_rng(5).uniform(0.1, 0.9, (F, 11, 19)).astype(np.float32)
    gone = (np.arange(F) == F // 2) if missing else None
    late = diffuse(frames, code, tensor=tensor, time=time, missing=gone)
    monkeypatch.setattr(D, "_BLUR_AT_FINISH", False)
    np.testing.assert_array_equal(late, diffuse(frames, code, tensor=tensor, time=time, missing=gone))
