"""The trajectory gather read from the frames and the code (:func:`flexvox_core.motion.mcnc.trajectory_gather` and
its kernel :func:`flexvox_core.motion.mcnc_kernel.lattice_sums`) against a plain numpy reference and against the
sample-volume gather (:func:`flexvox_core.motion.mcnc.motion_compensated_nc`)."""

import math

import cv2
import numba
import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume
from flexvox_core.motion.mcnc import default_reach, motion_compensated_nc, reaches, trajectory_gather
from flexvox_core.motion.mcnc_kernel import own_reach
from flexvox_core.motion.noise_aware import wide_sigma
from flexvox_core.simulate.scenes import render_scene

from .longreach_reference import bilinear_zero

TILES = [(2, 4), (4, 4)]


def _volumes(frames, code, missing):
    """The sample volume and its mask, a dropped frame's sub-frames without samples."""
    sparse = sparse_volume(frames, code).astype(np.float64)
    mask = sample_mask(sparse.shape, code)
    K = code.shape[2]
    if missing is not None:
        for f in np.flatnonzero(missing):
            sparse[f * K:(f + 1) * K] = 0
            mask[f * K:(f + 1) * K] = False
    return sparse, mask.astype(np.float64)


def reference_sums(sparse, mask, flow, t, time, c1, reach):
    """The unblurred (numerator, weight) planes of sub-frame ``t`` from the sample volume, every pixel, float64:
    w_d = e^(d²) over d up to each voxel's own reach (e as the kernel computes it, float32)."""
    S, H, W = sparse.shape
    u = np.nan_to_num(flow[t, ..., 0], nan=0, posinf=0, neginf=0).astype(np.float32)
    v = np.nan_to_num(flow[t, ..., 1], nan=0, posinf=0, neginf=0).astype(np.float32)
    bad = ~(np.isfinite(flow[t, ..., 0]) & np.isfinite(flow[t, ..., 1]))
    u[bad], v[bad] = 0, 0
    e = np.exp(-(1 + u * u + v * v) * np.float32(1 / (4 * time * c1))).astype(np.float32)
    r = reaches(e, reach)
    y, x = np.mgrid[:H, :W].astype(np.float64)
    num, den = sparse[t].copy(), mask[t].copy()
    e64, u64, v64 = e.astype(np.float64), u.astype(np.float64), v.astype(np.float64)
    for d in range(1, reach + 1):
        w = np.where(r >= d, e64 ** (d * d), 0)
        for sd in (d, -d):
            if 0 <= t + sd < S:
                py, px = y + sd * v64, x + sd * u64
                num += w * bilinear_zero(sparse[t + sd], py, px)
                den += w * bilinear_zero(mask[t + sd], py, px)
    return num, den


@pytest.mark.parametrize("tile", TILES)
@pytest.mark.parametrize("dropped", [False, True])
def test_lattice_sums_are_the_numpy_reference(rng, tile, dropped):
    from flexvox_core.motion.mcnc_kernel import lattice_sums, reach_thresholds, slot_tables

    code = design_code(tile).code
    K = code.shape[2]
    F, H, W = 3, 11, 13  # odd sizes: partial tiles at the right and bottom
    frames = rng.uniform(0.1, 0.9, (F, H, W)).astype(np.float32)
    missing = np.array([False, True, False]) if dropped else None
    S = F * K
    flow = rng.normal(0, 1.2, (S, H, W, 2)).astype(np.float32)
    flow[:, :3] = 0  # a still band: its own samples
    flow[::5, 7, 2] = np.nan  # no flow measured: still
    time, c1, reach = 2.0, 0.95, default_reach(2.0, 0.95, K, S)
    sparse, mask = _volumes(frames, code, missing)
    present = np.ones(F, bool) if missing is None else ~missing
    rows, cols = slot_tables(code, H, W)
    box = (slice(2, 10), slice(1, 12))
    for t in (0, K - 1, K + 3, S - 1):
        near = rng.random((8, 11)) > 0.3
        num, den = np.full((2, 8, 11), 7, np.float32)
        lattice_sums(frames, present, rows, cols, flow[t], near, box[0].start, box[1].start, t, S,
                     np.float32(1 / (4 * time * c1)), reach, num, den, reach_thresholds(reach))
        want_n, want_d = reference_sums(sparse, mask, flow, t, time, c1, reach)
        np.testing.assert_allclose(num, np.where(near, want_n[box], 0), atol=2e-5)
        np.testing.assert_allclose(den, np.where(near, want_d[box], 0), atol=2e-5)
        assert den[near].max() > 0  # samples were read


def _odd_case(rng, order, dropped: bool, *, flow_sigma: float):
    """An 11×13 capture of 3 frames through the code of ``order`` (the middle frame dropped when ``dropped``), a
    flow of fractional, integer (rows 0–1) and unmeasured (NaN) vectors, and the kernel's tables: (frames, present,
    flow, rows, cols, reach, inv)."""
    from flexvox_core.codes import code_from_order
    from flexvox_core.motion.mcnc_kernel import slot_tables

    code = code_from_order(np.asarray(order))
    K = code.shape[2]
    F, H, W = 3, 11, 13
    frames = rng.uniform(0.1, 0.9, (F, H, W)).astype(np.float32)
    present = np.array([True, not dropped, True])
    S = F * K
    flow = rng.normal(0, flow_sigma, (S, H, W, 2)).astype(np.float32)
    flow[:, :2] = np.round(flow[:, :2])
    flow[::3, 4, 2] = np.nan
    rows, cols = slot_tables(code, H, W)
    return frames, present, flow, rows, cols, default_reach(2.0, 0.95, K, S), np.float32(1 / (4 * 2.0 * 0.95))


@pytest.mark.parametrize("order", [design_code((4, 4)).order, [[2, 0, 3, 1]], [[1], [2], [0]]],
                         ids=["4x4", "1x4", "3x1"])
@pytest.mark.parametrize("dropped", [False, True])
def test_lattice_sums_reach_on_the_table_is_own_reachs_bit_for_bit(rng, order, dropped):
    """Each voxel's reach counted on :func:`reach_thresholds` gives the kernel's bits with :func:`own_reach` (an
    empty table), on odd sizes, with fractional, integer and unmeasured flows and a dropped frame."""
    from flexvox_core.motion.mcnc_kernel import lattice_sums, reach_thresholds

    frames, present, flow, rows, cols, reach, inv = _odd_case(rng, order, dropped, flow_sigma=1.5)
    S, H, W = flow.shape[:3]
    table, none = reach_thresholds(reach), np.zeros(0, np.float32)
    read = 0.0
    for t in range(S):
        near = rng.random((H - 1, W - 2)) > 0.2
        want = np.full((2, H - 1, W - 2), 7, np.float32)
        got = np.full((2, H - 1, W - 2), 5, np.float32)
        lattice_sums(frames, present, rows, cols, flow[t], near, 1, 2, t, S, inv, reach, want[0], want[1], none)
        lattice_sums(frames, present, rows, cols, flow[t], near, 1, 2, t, S, inv, reach, got[0], got[1], table)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
        read += float(got[1].sum())
    assert read > 0


@numba.njit(cache=False)
def _reach_mismatches(lo_bits, hi_bits, reach, thresholds):  # pragma: no cover - compiled
    """How many float32 numbers with bit patterns in [lo_bits, hi_bits) own_reach and the thresholds disagree on."""
    buf = np.zeros(1, np.float32)
    bits = buf.view(np.uint32)
    bad = 0
    for b in range(lo_bits, hi_bits):
        bits[0] = b
        e = buf[0]
        r = 0
        while e >= thresholds[r + 1]:
            r += 1
        bad += r != own_reach(e, reach)
    return bad


@pytest.mark.parametrize("reach", [16, 5])
def test_reach_thresholds_count_own_reach_on_every_float32(reach):
    """Every float32 from CUTOFF / 2 to 1: the reach counted on the thresholds is own_reach's (the kernel's bits
    rest on it)."""
    from flexvox_core.motion.gather_weights import CUTOFF
    from flexvox_core.motion.mcnc_kernel import reach_thresholds

    th = reach_thresholds(reach)
    lo = int(np.array(CUTOFF / 2, np.float32).view(np.uint32))
    hi = int(np.array(1.0, np.float32).view(np.uint32)) + 1
    assert _reach_mismatches(lo, hi, reach, th) == 0
    assert own_reach(np.float32(th[3]), reach) == 3 and own_reach(np.nextafter(th[3], np.float32(0)), reach) == 2


@pytest.fixture(params=TILES, ids=lambda t: f"{t[0]}x{t[1]}")
def clip(request, rng):
    """(code, frames, flow) of a small moving scene at an odd size, the flow from still to 2 px per sub-frame."""
    code = design_code(request.param).code
    K = code.shape[2]
    truth = render_scene("balls", 3 * K, 15, 17, seed=2)
    frames = capture(truth, code).astype(np.float32)
    flow = rng.normal(0, 1.0, (*truth.shape, 2)).astype(np.float32)
    flow[:, :5] = 0
    return code, frames, flow


@pytest.mark.parametrize("noisy", [False, True])
@pytest.mark.parametrize("dropped", [False, True])
def test_gather_from_the_frames_is_the_sample_volumes(rng, clip, noisy, dropped):
    """Integer flows (OpenCV's remap reads whole pixels exactly): the same video and leave-one-out as the
    sample-volume gather, up to float32 sums in another order."""
    code, frames, flow = clip
    K = code.shape[2]
    S = len(flow)
    flow = np.round(flow)
    missing = np.array([False, True, False]) if dropped else None
    sparse, mask = _volumes(frames, code, missing)
    gathered = rng.random(sparse.shape) > 0.4  # samples among them: their leave-one-out
    base = rng.random(sparse.shape).astype(np.float32)
    fallback = rng.random(sparse.shape).astype(np.float32)
    wide = list(rng.random(sparse.shape).astype(np.float32)) if noisy else None
    reach = default_reach(3.0, 0.95, S // (3 - int(dropped)), S)
    kw = dict(time=3.0, fallback=fallback, still_value=base, wide=wide, wide_sigma=wide_sigma(K), max_reach=reach)
    loo_want = np.full(frames.shape, np.nan, np.float32)
    want = motion_compensated_nc(sparse.astype(np.float32), mask > 0, flow, gathered=gathered, loo=loo_want, **kw)
    loo = np.full(frames.shape, np.nan, np.float32)
    got = trajectory_gather(frames, code, flow, missing=missing, gathered=gathered, loo=loo, **kw)
    np.testing.assert_allclose(got, want, atol=2e-5)
    np.testing.assert_array_equal(np.isnan(loo), np.isnan(loo_want))
    np.testing.assert_allclose(loo[np.isfinite(loo)], loo_want[np.isfinite(loo)], atol=1e-4)
    assert np.isfinite(loo).any() and (got != base).any()


def test_gather_from_the_frames_reads_exact_positions(rng, clip):
    """Fractional flows: within OpenCV's 1/32 px rounding of the sample-volume gather; in place of ``still_value``
    alike."""
    code, frames, flow = clip
    sparse, mask = _volumes(frames, code, None)
    gathered = rng.random(sparse.shape) > 0.3
    base = rng.random(sparse.shape).astype(np.float32)
    high_tr = rng.random(sparse.shape).astype(np.float32)
    want = motion_compensated_nc(sparse.astype(np.float32), mask > 0, flow, time=2.0, fallback=high_tr,
                                 gathered=gathered, still_value=base)
    got = trajectory_gather(frames, code, flow, time=2.0, fallback=high_tr, gathered=gathered, still_value=base,
                            out=base)
    assert got is base
    np.testing.assert_allclose(got, want, atol=3e-3)
    assert np.abs(got - want).mean() < 3e-4
    np.testing.assert_array_equal(got[mask > 0], sparse[mask > 0].astype(np.float32))


def test_gather_from_the_frames_refuses_what_it_cannot_read(rng):
    code = design_code((2, 2)).code
    frames = rng.random((2, 5, 6)).astype(np.float32)
    S = 2 * 4
    vol = np.zeros((S, 5, 6), np.float32)
    kw = dict(fallback=vol, gathered=vol > 0, still_value=vol)
    flow = np.zeros((S, 5, 6, 2), np.float32)
    with pytest.raises(ValueError, match=r"`flow` must have shape \(8, 5, 6, 2\)"):
        trajectory_gather(frames, code, flow[:4], **kw)
    with pytest.raises(ValueError, match="must be an identity code"):
        trajectory_gather(frames, np.ones((2, 2, 4), bool), flow, **kw)
    with pytest.raises(ValueError, match=r"`missing` must be \(2,\) bool"):
        trajectory_gather(frames, code, flow, missing=np.zeros(3, bool), **kw)
    with pytest.raises(ValueError, match=r"`loo` must be \(F, H, W\)"):
        trajectory_gather(frames, code, flow, loo=np.zeros((1, 5, 6), np.float32), **kw)
    with pytest.raises(ValueError, match="must not share memory with `fallback`"):
        trajectory_gather(frames, code, flow, out=vol, **kw)
    assert math.isfinite(float(trajectory_gather(frames, code, flow, **kw).sum()))


def test_a_float16_fallback_is_read_as_float32_of_its_values(rng, clip):
    """Motion-aware holds its high-TR video (the gather's fallback) in float16 from the flow on."""
    code, frames, flow = clip
    S = frames.shape[0] * code.shape[2]
    gathered = rng.random((S, *frames.shape[1:])) > 0.3
    base = rng.random(gathered.shape).astype(np.float32)
    held = (rng.random(gathered.shape) * 0.9 + 0.05).astype(np.float16)
    kw = dict(time=2.0, gathered=gathered, still_value=base, max_reach=1)
    got = trajectory_gather(frames, code, flow, fallback=held, **kw)
    want = trajectory_gather(frames, code, flow, fallback=held.astype(np.float32), **kw)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, want)
    assert np.isin(got, held.astype(np.float32)).any()  # some voxels out of reach took the fallback


@pytest.mark.parametrize("shape", [(7, 19), (12, 15), (1, 23)])
@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("with_loo", [False, True])
@pytest.mark.parametrize("fallback", ["none", "float16", "float32"])
def test_the_gathers_last_steps_are_numpys_bit_for_bit(rng, shape, wide, with_loo, fallback):
    """mcnc._finish (the leave-one-out and N / D compiled: mcnc_kernel.divide_box) against the numpy steps it
    replaced (finish_reference), on odd boxes with weights about MIN_WEIGHT, samples on a 4 × 4 lattice, the wide
    kernel's mixture and a float16 fallback."""
    from flexvox_core.motion.mcnc import _finish

    from .finish_reference import finish

    h, w = shape
    H, W = h + 3, w + 2
    box = (slice(2, 2 + h), slice(1, 1 + w))
    t, sig_space, wide_sigma = 1, 0.9, 2.0
    planes = rng.random((2, h, w), dtype=np.float32)
    planes[1][:, : (w + 1) // 2] *= np.float32(1e-6)  # weights about MIN_WEIGHT on the left, after the blur too
    planes[0] *= planes[1]
    inside = rng.random((h, w)) < 0.7
    mask = np.zeros((H, W), bool)
    mask[1::4, 2::4] = True
    vals = rng.random((H, W), dtype=np.float32)
    g = [None, rng.random((H, W), dtype=np.float32), None] if wide else None
    fb = None if fallback == "none" else rng.random((3, H, W)).astype(np.float16 if fallback == "float16" else
                                                                       np.float32)
    out = np.full((3, H, W), -5, np.float32)
    loo = np.full((H, W), -7, np.float32) if with_loo else None
    _finish(t, box, inside, planes.copy(), lambda s: (mask, vals), g, wide_sigma, sig_space, fb, loo, out)

    # The reference blurs as _finish does, then takes the numpy steps.
    ref_planes = planes.copy()
    gb = None
    if wide:
        gb = g[t][box]
        broad = np.empty_like(ref_planes)
        for plane, dst in zip(ref_planes, broad, strict=True):
            cv2.GaussianBlur(plane, (0, 0), wide_sigma, dst=dst, borderType=cv2.BORDER_REFLECT)
    for plane in ref_planes:
        cv2.GaussianBlur(plane, (0, 0), sig_space, dst=plane, borderType=cv2.BORDER_REFLECT)
    if wide:
        ref_planes += gb * (broad - ref_planes)
    ref_out = np.full((3, H, W), -5, np.float32)
    ref_loo = np.full((H, W), -7, np.float32) if with_loo else None
    finish(ref_planes, inside, mask[box], vals[box], sig_space, gb, wide_sigma, None if fb is None else fb[t][box],
           None if ref_loo is None else ref_loo[box], ref_out[t][box])
    small = ref_planes[1][inside] <= np.float32(1e-6)
    assert small.any() and not small.all()  # both ways are taken
    np.testing.assert_array_equal(out, ref_out)
    if with_loo:
        np.testing.assert_array_equal(loo, ref_loo)
        assert (loo[box][~(inside & mask[box])] == -7).all()  # written at the box's samples alone


@pytest.mark.parametrize("order", [design_code((4, 4)).order, [[2, 0, 3, 1]], [[1], [2], [0]]],
                         ids=["4x4", "1x4", "3x1"])
@pytest.mark.parametrize("dropped", [False, True])
def test_lattice_sums_read_cells_in_the_picture_as_clamped_bit_for_bit(rng, order, dropped):
    """The kernel (every read clamped, a row's voxels at a time) gives the bits of the kernel a voxel at a time
    that clamped every read (lattice_reference), on odd sizes with trajectories leaving the picture, fractional,
    integer and unmeasured
    flows, multiplexed slots' tables of several tiles and a dropped frame."""
    from flexvox_core.motion.mcnc_kernel import lattice_sums, reach_thresholds

    from .lattice_reference import kernel_by_voxel

    # up to 4 offsets of several px: off the picture
    frames, present, flow, rows, cols, reach, inv = _odd_case(rng, order, dropped, flow_sigma=2.5)
    S, H, W = flow.shape[:3]
    table = reach_thresholds(reach)
    clamped = kernel_by_voxel(clamped=True, exp32=True)
    read = 0.0
    for t in range(S):
        near = rng.random((H, W)) > 0.2
        want = np.full((2, H, W), 7, np.float32)
        got = np.full((2, H, W), 5, np.float32)
        clamped(frames, present, rows, cols, flow[t], near, 0, 0, t, S, inv, reach, want[0], want[1], table)
        lattice_sums(frames, present, rows, cols, flow[t], near, 0, 0, t, S, inv, reach, got[0], got[1], table)
        np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
        read += float(got[1].sum())
    assert read > 0


@pytest.mark.parametrize("order", [design_code((4, 4)).order, [[2, 0, 3, 1]], [[1], [2], [0]]],
                         ids=["4x4", "1x4", "3x1"])
@pytest.mark.parametrize("dropped", [False, True])
@pytest.mark.parametrize("by_table", [True, False])
def test_lattice_sums_rows_are_the_kernel_per_voxel_bit_for_bit(rng, order, dropped, by_table):
    """The kernel a row's voxels at a time gives the bits of the kernel a voxel at a time (lattice_reference; with
    the kernel's exp, and both with numba's), on
    odd boxes inside an odd picture and on the whole picture, with trajectories leaving it, fractional, integer and
    unmeasured flows, multiplexed slots' tables, a dropped frame, the reach on the table and by :func:`own_reach`."""
    from flexvox_core.motion.mcnc_kernel import lattice_sums, reach_thresholds

    from .lattice_reference import kernel_by_voxel, lattice_sums_by_voxel, rows_with_libm_exp

    # the kernel's exp in both, and numba's (the benchmark's variants gather-exp-libm and gather-by-voxel)
    pairs = ((lattice_sums, kernel_by_voxel(exp32=True)), (rows_with_libm_exp(), lattice_sums_by_voxel))
    frames, present, flow, rows, cols, reach, inv = _odd_case(rng, order, dropped, flow_sigma=2.0)
    S, H, W = flow.shape[:3]
    table = reach_thresholds(reach) if by_table else np.zeros(0, np.float32)
    read = 0.0
    for t in range(S):
        for y0, x0, h, w in ((0, 0, H, W), (1, 2, H - 3, W - 5), (4, 0, 1, W), (0, 7, H, 1)):
            near = rng.random((h, w)) > 0.3
            for kernel, by_voxel in pairs:
                want = np.full((2, h, w), 7, np.float32)
                got = np.full((2, h, w), 5, np.float32)
                by_voxel(frames, present, rows, cols, flow[t], near, y0, x0, t, S, inv, reach, want[0], want[1], table)
                kernel(frames, present, rows, cols, flow[t], near, y0, x0, t, S, inv, reach, got[0], got[1], table)
                np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
                read += float(got[1].sum())
    assert read > 0
