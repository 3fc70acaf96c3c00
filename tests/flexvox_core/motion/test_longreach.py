"""Slow and still voxels: the range-weighted long-reach gather, the period gate, still voxels exact."""

import numpy as np
import pytest

from flexvox_core.codes import code_from_order
from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.motion.longreach import long_reach_nc
from flexvox_core.motion.pipeline import STEP1_TENSOR, STEP1_TIME, gated_flow
from flexvox_core.reconstruct.diffusion import diffuse
from flexvox_core.simulate.scenes import render_scene

CODE = design_code((2, 4)).code  # K = 8


def _sampled(truth, code=CODE):
    frames = capture(truth, code)
    return frames, sparse_volume(frames, code), sample_mask(truth.shape, code)


def test_still_texture_along_zero_flow_is_exact(rng):
    # Zero flow reads each pixel's own samples only: a still texture comes back exactly.
    truth = np.repeat(rng.random((1, 10, 12)).astype(np.float32), 8 * 4, axis=0)
    _, sparse, mask = _sampled(truth)
    zero = np.zeros((*truth.shape, 2), np.float32)
    guide = np.full(truth.shape, 0.5, np.float32)
    out = long_reach_nc(sparse, mask, zero, guide, np.ones(truth.shape, bool), reach=8, sigma_t=8,
                        sigma_s=0, h=10.0)
    assert np.abs(out - truth).max() < 1e-5


def test_range_weight_keeps_a_sudden_change_sharp(rng):
    # A pixel-wise texture that changes at once half-way (a cut, or an occlusion): without the
    # range weight the long reach blends both sides; with it, each side keeps its own samples.
    S = 8 * 6
    truth = np.empty((S, 10, 12), np.float32)
    truth[: S // 2] = rng.uniform(0.0, 0.3, (10, 12))
    truth[S // 2:] = rng.uniform(0.7, 1.0, (10, 12))
    _, sparse, mask = _sampled(truth)
    zero = np.zeros((*truth.shape, 2), np.float32)
    guide = np.where(truth < 0.5, 0.15, 0.85).astype(np.float32)  # a coarse short-reach estimate
    sel = np.ones(truth.shape, bool)
    near = slice(S // 2 - 6, S // 2 + 6)
    weighted = long_reach_nc(sparse, mask, zero, guide, sel, reach=8, sigma_t=8, sigma_s=0, h=0.1)
    blind = long_reach_nc(sparse, mask, zero, guide, sel, reach=8, sigma_t=8, sigma_s=0, h=1e3)
    assert np.abs(weighted[near] - truth[near]).max() < 0.02
    assert np.abs(blind[near] - truth[near]).max() > 0.2


@pytest.mark.parametrize("flow_kind", ["huge", "nan", "out"])
def test_hard_flows_stay_finite_within_range_and_outside_select_is_the_guide(rng, flow_kind):
    truth = rng.uniform(0.2, 0.8, (8 * 3, 12, 16)).astype(np.float32)
    _, sparse, mask = _sampled(truth)
    flow = {"huge": np.full((*truth.shape, 2), 50.0, np.float32),
            "nan": np.where(rng.random((*truth.shape, 2)) < 0.3, np.nan, 0.3).astype(np.float32),
            "out": np.full((*truth.shape, 2), -30.0, np.float32)}[flow_kind]
    guide = diffuse(capture(truth, CODE), CODE, tensor=(1, 1, 0.05), time=2.0)
    sel = rng.random(truth.shape) < 0.5
    out = long_reach_nc(sparse, mask, flow, guide, sel, reach=8, sigma_t=8)
    assert np.isfinite(out).all()
    assert out.min() >= truth.min() - 1e-6 and out.max() <= truth.max() + 1e-6
    assert np.array_equal(out[~sel], guide[~sel])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"reach": -1}, r"`reach` must be"),
        ({"sigma_t": 0}, r"`sigma_t` must be a finite number > 0"),
        ({"h": float("nan")}, r"`h` must be a finite number > 0"),
        ({"guide": np.zeros((2, 2, 2), np.float32)}, r"must match"),
    ],
)
def test_bad_arguments(kwargs, match):
    shape = (8, 4, 4)
    args = {"sparse": np.zeros(shape, np.float32), "mask": np.zeros(shape, bool),
            "flow": np.zeros((*shape, 2), np.float32), "guide": np.zeros(shape, np.float32),
            "select": np.ones(shape, bool), "reach": 2, "sigma_t": 2.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        long_reach_nc(**args)


def test_motion_aware_reconstructs_a_still_scene_exactly_away_from_the_ends():
    # Still voxels take their own samples averaged in time: exact for a still scene. (In the first
    # and last frame the motion detector sees a little false motion: 2 % of the voxels here.)
    # The refinement diffuses along the trajectories only (in time alone where still), so it keeps
    # that; it spreads the ends' few false-motion errors over a few sub-frames there.
    truth = render_scene("static", 8 * 4, 48, 64)
    frames = capture(truth, CODE)
    video = motion_aware(frames, CODE).video
    assert np.abs(video - truth)[8:-8].max() < 1e-4
    assert np.abs(video - truth)[:8].mean() < 0.005 and np.mean(np.abs(video - truth) < 1e-2) > 0.97
    unrefined = motion_aware(frames, CODE, refine_time=0.0).video
    assert np.mean(np.abs(unrefined - truth) < 1e-4) > 0.95


def test_long_reach_pays_on_a_slow_pan():
    truth = render_scene("pan", 8 * 4, 48, 64)
    frames = capture(truth, CODE)
    long = psnr(truth, motion_aware(frames, CODE).video)
    short = psnr(truth, motion_aware(frames, CODE, slow_reach=0).video)
    assert long > short + 1.0  # measured: 26.1 against 24.3 dB


def test_period_gate_sees_motion_aliased_in_the_k_average():
    # The fan's 3 blades pass every 16 sub-frames: at K = 16 its K-average is exactly still.
    code = design_code((4, 4)).code
    truth = render_scene("fan", 16 * 4, 96, 128)
    high_tr = diffuse(capture(truth, code), code, tensor=STEP1_TENSOR, time=STEP1_TIME)
    blades = np.abs(np.diff(truth, axis=0)).max(axis=0) > 0.02
    with_gate = gated_flow(high_tr, 16, backend="dis", scale=1.0).magnitude
    without = gated_flow(high_tr, 16, backend="dis", scale=1.0, period_gate=None).magnitude
    assert (with_gate[:, blades] > 0.5).mean() > 0.5  # measured 0.63
    assert (without[:, blades] > 0.5).mean() < 0.3  # measured 0.17
    assert (with_gate[:, ~blades] > 0.5).mean() < 0.15  # the still wall mostly stays still (0.075)


def test_bad_slow_reach_and_period_gate():
    frames = np.full((2, 8, 8), 0.5, np.float32)
    with pytest.raises(ValueError,
                       match=r"`slow_reach` must be a number from 0 to 1000 \(sampling periods\) or None; got -1"):
        motion_aware(frames, CODE, slow_reach=-1)
    with pytest.raises(ValueError, match=r"`period_gate` must be two thresholds"):
        gated_flow(np.zeros((16, 8, 8), np.float32), 8, backend="dis", period_gate=(2.0, 1.0))


def test_box_and_list_gathers_agree(rng, monkeypatch):
    # Dense selections are gathered as their bounding box, sparse ones as a list of voxels.
    import flexvox_core.motion.longreach as lr

    truth = rng.uniform(0.2, 0.8, (8 * 3, 20, 24)).astype(np.float32)
    _, sparse, mask = _sampled(truth)
    flow = rng.normal(0, 0.4, (*truth.shape, 2)).astype(np.float32)
    guide = diffuse(capture(truth, CODE), CODE, tensor=(1, 1, 0.05), time=2.0)
    sel = rng.random(truth.shape) < 0.1
    results = []
    for dense in (0.0, 2.0):  # always the box; always the list
        monkeypatch.setattr(lr, "DENSE", dense)
        results.append(long_reach_nc(sparse, mask, flow, guide, sel, reach=8, sigma_t=8, sigma_s=0.3, h=0.1))
    assert np.allclose(results[0], results[1], atol=1e-5)
    assert not np.allclose(results[0][sel], guide[sel], atol=1e-3)  # the gather did something


def test_values_outside_the_samples_are_ignored(rng):
    # Only sampled voxels are read: NaN where there is no sample changes nothing.
    truth = rng.uniform(0.2, 0.8, (8 * 3, 12, 16)).astype(np.float32)
    _, sparse, mask = _sampled(truth)
    flow = rng.normal(0, 0.3, (*truth.shape, 2)).astype(np.float32)
    guide = np.full(truth.shape, 0.5, np.float32)
    sel = np.ones(truth.shape, bool)
    clean = long_reach_nc(sparse, mask, flow, guide, sel, reach=8, sigma_t=8)
    dirty = np.where(mask, sparse, np.nan).astype(np.float32)
    assert np.array_equal(long_reach_nc(dirty, mask, flow, guide, sel, reach=8, sigma_t=8), clean)


def test_writing_into_the_guide_gives_the_same_result(rng):
    truth = rng.uniform(0.2, 0.8, (8 * 3, 12, 16)).astype(np.float32)
    _, sparse, mask = _sampled(truth)
    flow = rng.normal(0, 0.3, (*truth.shape, 2)).astype(np.float32)
    guide = diffuse(capture(truth, CODE), CODE, tensor=(1, 1, 0.05), time=2.0)
    sel = rng.random(truth.shape) < 0.5
    kw = dict(reach=6, sigma_t=6, sigma_s=0.3, h=0.1)
    expected = long_reach_nc(sparse, mask, flow, guide, sel, **kw)
    inplace = guide.copy()
    got = long_reach_nc(sparse, mask, flow, inplace, sel, out=inplace, **kw)
    assert got is inplace
    np.testing.assert_array_equal(got, expected)
    with pytest.raises(ValueError, match="`out` must be float32 of shape"):
        long_reach_nc(sparse, mask, flow, guide, sel, out=np.empty((3, 12, 16), np.float32), **kw)


# The compiled gather that reads the frames (long_reach) against its numpy reference and the remap version.

def _lattice_case(rng, tile, F, H, W, missing=None, speed=0.6):
    from flexvox_core.gaps import interpolated_subframes

    code = design_code(tile).code if isinstance(tile, tuple) else code_from_order(tile)
    K = code.shape[2]
    truth = rng.uniform(0.2, 0.8, (F * K, H, W)).astype(np.float32)
    frames = capture(truth, code)
    flow = rng.normal(0, speed, (F * K, H, W, 2)).astype(np.float32)
    guide = (truth + rng.normal(0, 0.05, truth.shape)).astype(np.float32)
    sel = rng.random(truth.shape) < 0.3
    sparse, mask = sparse_volume(frames, code), sample_mask(truth.shape, code)
    if missing is not None:
        frames[np.asarray(missing)] = np.nan  # a dropped frame's values must not be read
        gap = interpolated_subframes(missing, K)
        mask[gap] = False
        sparse[gap] = 0
    return code, frames, flow, guide, sel, sparse, mask


@pytest.mark.parametrize("tile, F, H, W, missing, sigma_s", [
    ((2, 4), 4, 13, 17, None, 0.3),
    ((2, 4), 5, 11, 19, [False, True, False, False, True], 0.3),
    ((4, 4), 3, 15, 13, None, 0.3),
    ((4, 4), 4, 9, 21, [True, False, True, False], 0.6),
    ((4, 4), 3, 10, 11, None, 0.0),
    ([[0, 2, 1, 3]], 6, 9, 10, [False, False, True, False, False, False], 0.3),  # 1×4: two pixels of a cell hold k
])
def test_compiled_gather_is_the_reference(rng, tile, F, H, W, missing, sigma_s):
    from flexvox_core.motion.longreach import LongReachPlan, long_reach
    from tests.flexvox_core.motion.longreach_reference import long_reach_reference

    code, frames, flow, guide, sel, _, _ = _lattice_case(rng, tile, F, H, W, missing)
    K = code.shape[2]
    flow[0, :3, :3] = np.nan  # read as still
    flow[1, -2:, -3:] = 40.0  # every read beyond the picture
    plan = LongReachPlan.of(F * K, reach=K, sigma_t=K * 0.75, sigma_s=sigma_s, h=0.1)
    miss = None if missing is None else np.array(missing)
    for write_samples in (False, True):
        want = long_reach_reference(frames, code, flow, guide, sel, plan, miss, write_samples)
        got = long_reach(frames, code, flow, guide, sel, plan, missing=miss, write_samples=write_samples)
        assert got.dtype == np.float32
        np.testing.assert_allclose(got, want, atol=2e-5, rtol=0)
        assert np.isfinite(got).all()
    changed = sel & (np.abs(got - guide) > 1e-3)
    assert changed.mean() > 0.5 * sel.mean()  # the gather did something


def test_compiled_gather_writes_into_the_guide(rng):
    from flexvox_core.motion.longreach import LongReachPlan, long_reach

    code, frames, flow, guide, sel, sparse, mask = _lattice_case(rng, (2, 4), 3, 12, 16)
    plan = LongReachPlan.of(24, reach=6, sigma_t=6, sigma_s=0.3, h=0.1)
    want = long_reach(frames, code, flow, guide, sel, plan, write_samples=True)
    inplace = guide.copy()
    got = long_reach(frames, code, flow, inplace, sel, plan, out=inplace, write_samples=True)
    assert got is inplace
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got[mask], sparse[mask])
    with pytest.raises(ValueError, match=r"`out` must be C-contiguous float32 of shape \(24, 12, 16\)"):
        long_reach(frames, code, flow, guide, sel, plan, out=np.empty((3, 12, 16), np.float32))
    with pytest.raises(ValueError, match=r"`guide`, `select` \(S, H, W\) = \(24, 12, 16\)"):
        long_reach(frames, code, flow, guide[:8], sel, plan)
    with pytest.raises(ValueError, match=r"`missing` must be one flag per frame, shape \(3,\); got \(2,\)"):
        long_reach(frames, code, flow, guide, sel, plan, missing=np.zeros(2, bool))
    # A multiplexed capture is demultiplexed before motion-aware: the long reach takes identity codes alone.
    mcode = code.copy()
    mcode[0, 0] = True  # every slot open at one pixel of the tile
    with pytest.raises(ValueError, match=r"`code` is not an identity code"):
        long_reach(frames, mcode, flow, guide, sel, plan)


@pytest.mark.parametrize("tile, missing", [((2, 4), None), ((4, 4), [False, True, False])])
def test_compiled_gather_is_the_remap_gather_to_its_1_32_px_rounding(rng, tile, missing):
    # cv2.remap rounds each read's position to 1/32 px: the results agree to that, not to float32 rounding.
    from flexvox_core.motion.longreach import LongReachPlan, long_reach

    code, frames, flow, guide, sel, sparse, mask = _lattice_case(rng, tile, 3, 14, 18, missing, speed=0.3)
    K = code.shape[2]
    plan = LongReachPlan.of(3 * K, reach=K, sigma_t=K, sigma_s=0.3, h=0.1)
    old = long_reach_nc(sparse, mask, flow, guide, sel, reach=plan.reach, sigma_t=plan.sigma_t,
                        sigma_s=plan.sigma_s, h=plan.h)
    new = long_reach(frames, code, flow, guide, sel, plan, missing=None if missing is None else np.array(missing))
    assert np.abs(new - old).max() < 0.02
    assert np.abs(new - old).mean() < 1e-3
    zero = np.zeros_like(flow)  # integer positions: no rounding, the same sums
    old = long_reach_nc(sparse, mask, zero, guide, sel, reach=plan.reach, sigma_t=plan.sigma_t,
                        sigma_s=plan.sigma_s, h=plan.h)
    new = long_reach(frames, code, zero, guide, sel, plan, missing=None if missing is None else np.array(missing))
    np.testing.assert_allclose(new, old, atol=2e-6, rtol=0)


def test_corner_table_names_the_pixels_that_hold_each_slot():
    from flexvox_core.codes import order_from_code
    from flexvox_core.motion.longreach_kernel import CORNERS, corner_table

    order = order_from_code(design_code((2, 4)).code)
    table = corner_table(order)
    assert table.shape == (2, 4, 8)
    for i in range(2):
        for j in range(4):
            for k in range(8):
                want = sum(1 << b for b, (dy, dx) in enumerate(CORNERS) if order[(i + dy) % 2, (j + dx) % 4] == k)
                assert table[i, j, k] == want
            assert sorted(int(v).bit_count() for v in table[i, j]) == [0] * 4 + [1] * 4  # one pixel per slot


@pytest.mark.parametrize("threads", [1, 3])
def test_compiled_gather_bits_do_not_depend_on_the_thread_count(rng, monkeypatch, threads):
    from flexvox_core import threads as threads_module
    from flexvox_core.motion.longreach import LongReachPlan, long_reach

    code, frames, flow, guide, sel, _, _ = _lattice_case(rng, (4, 4), 3, 12, 14)
    plan = LongReachPlan.of(48, reach=12, sigma_t=12, sigma_s=0.3, h=0.1)
    many = long_reach(frames, code, flow, guide, sel, plan, write_samples=True)
    calls = []
    monkeypatch.setattr(threads_module, "workers", lambda: calls.append(threads) or threads)
    one = long_reach(frames, code, flow, guide, sel, plan, write_samples=True)
    assert calls  # the chunks and their threads came from the patched count
    np.testing.assert_array_equal(one, many)
    assert not np.array_equal(many[sel], guide[sel])


@pytest.mark.parametrize("order, missing", [
    ((4, 4), [False, True, False]),
    ((2, 4), None),
    ([[0, 2, 4], [1, 3, 5]], [True, False, False, False]),  # 2×3: residues of 3 in float32 arithmetic
    ([[0, 3, 6], [1, 4, 7], [2, 5, 8]], None),
])
def test_vectorized_row_reads_are_the_scalar_reads_to_float32_rounding(rng, order, missing):
    # The branch-free reads (_row_sums_one: float32 residues, the held pixel as the sample, exp32) against the
    # scalar ones (_row_sums: the corner table, n/d, math.exp) row by row, odd sizes, reads on the cells' edges and
    # beyond the picture, dropped frames. Tolerance: each term is within a few float32 ulp (the exp's 1 ulp, the n/d
    # not taken), so the sums agree to 1e-5 relative (the positions, and so the cells read, are the same).
    from flexvox_core.codes import order_from_code
    from flexvox_core.motion.longreach_kernel import _lattice, _row_sums, _row_sums_one, corner_table

    code, frames, flow, guide, _, _, _ = _lattice_case(rng, order, len(missing or [0, 0, 0]), 13, 19, missing)
    frames = np.ascontiguousarray(frames)
    S, H, W = guide.shape
    flow[2] = np.round(flow[2] * 4) / 4  # quarter pixels: reads on the cells' edges
    flow[3, :, :8] = 30.0  # beyond the picture
    flow[4, :2] = np.nan  # read as still
    order_ = order_from_code(code)
    present = np.ones(frames.shape[0], bool) if missing is None else ~np.array(missing)
    lat = _lattice(corner_table(order_), present, S, H, W)
    assert lat[10]  # the vectorized reads apply
    time_w = np.exp(-np.arange(9.0) ** 2 / 2 / 6**2).astype(np.float32)
    scale = np.float32(-1 / (2 * 0.1**2))
    xs = np.arange(W, dtype=np.int64)
    scratch = np.empty((6, W + 8), np.float32)
    compared = 0
    for t in range(S):
        for y in range(H):
            count = int(rng.integers(1, W + 1))
            xs[:count] = np.sort(rng.choice(W, count, replace=False))
            want = np.zeros((2, W), np.float32)
            got = np.zeros((2, W), np.float32)
            _row_sums(frames, lat, flow[t], guide, t, y, xs, count, time_w, scale, want[0], want[1], scratch)
            _row_sums_one(frames, lat, flow[t], guide, t, y, xs, count, time_w, scale, got[0], got[1], scratch)
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
            compared += int((want[1] > 0).sum())
    assert compared > S * H * W / 4  # most rows' voxels found samples


def test_a_tile_one_pixel_wide_takes_the_scalar_reads():
    from flexvox_core.codes import order_from_code
    from flexvox_core.motion.longreach_kernel import _lattice, corner_table

    order = order_from_code(code_from_order([[0, 2, 1, 3]]))  # two pixels of a cell hold each slot
    assert not _lattice(corner_table(order), np.ones(2, bool), 8, 5, 7)[10]
    order = order_from_code(design_code((4, 4)).code)
    assert _lattice(corner_table(order), np.ones(2, bool), 32, 5, 7)[10]
    assert not _lattice(corner_table(order), np.ones(2, bool), 32, 4096, 4097)[10]  # 2**24 pixels or more


@pytest.mark.parametrize("tile, F, H, W, missing", [
    ((4, 4), 3, 15, 13, None),
    ((2, 4), 5, 11, 19, [False, True, False, False, True]),
    ([[0, 2, 1, 3]], 6, 9, 10, [False, False, True, False, False, False]),  # the scalar reads
])
def test_a_flow_held_small_gives_the_bits_of_its_full_size_planes(rng, tile, F, H, W, missing):
    # The long reach reads a ScaledFlow at its voxels from the small planes (ScaledFlow.scaled): the same bits as
    # the full-size planes the flow makes.
    from flexvox_core.flow.estimate import ScaledFlow
    from flexvox_core.motion.longreach import LongReachPlan, long_reach

    code, frames, _, guide, sel, _, _ = _lattice_case(rng, tile, F, H, W, missing)
    K = code.shape[2]
    small = rng.normal(0, 0.4, (F * K, (H + 2) // 3, (W + 2) // 3, 2)).astype(np.float32)
    small[0, 0, 0] = np.nan  # read as still, either way
    held = ScaledFlow(small, np.ones(small.shape[:3], np.float32), (H, W))
    assert held.scaled(1) is not None
    plan = LongReachPlan.of(F * K, reach=K, sigma_t=K * 0.75, sigma_s=0.3, h=0.1)
    miss = None if missing is None else np.array(missing)
    got = long_reach(frames, code, held, guide, sel, plan, missing=miss, write_samples=True)
    want = long_reach(frames, code, held.band(0, F * K), guide, sel, plan, missing=miss, write_samples=True)
    np.testing.assert_array_equal(got, want)
    assert (np.abs(got - guide)[sel] > 1e-3).mean() > 0.5  # the gather did something
