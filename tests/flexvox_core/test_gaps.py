"""Dropped camera frames: gaps found, bridged from both sides, refused beyond a method's reach."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.gaps import (
    Gap,
    GapTooLongError,
    as_missing,
    bridge,
    bridge_flow,
    check_reach,
    fill_frames,
    find_gaps,
    interpolated_subframes,
)
from flexvox_core.methods import Method, names, run
from flexvox_core.metrics import psnr
from flexvox_core.simulate.scenes import render_scene

CODE = design_code((2, 2)).code  # K = 4
CODE16 = design_code((4, 4)).code


def _missing(F, drops):
    m = np.zeros(F, bool)
    m[list(drops)] = True
    return m


def test_gaps_are_the_runs_of_missing_frames():
    m = _missing(10, [0, 3, 4, 9])
    assert find_gaps(m) == [Gap(0, 1), Gap(3, 5), Gap(9, 10)]
    assert find_gaps(np.zeros(4, bool)) == []
    assert Gap(12, 17).describe(16) == "frames 12-16 (5 frames; sub-frames 192-271)"
    assert Gap(3, 4).describe() == "frame 3 (1 frame)"
    np.testing.assert_array_equal(interpolated_subframes(_missing(3, [1]), 2), [0, 0, 1, 1, 0, 0])


def test_missing_is_checked():
    assert as_missing(None, 4) is None and as_missing(np.zeros(4, bool), 4) is None
    with pytest.raises(ValueError, match=r"`missing` must be 4 booleans, one per camera frame; got bool \(3,\)"):
        as_missing(np.zeros(3, bool), 4)
    with pytest.raises(ValueError, match=r"all 2 camera frames are missing \(dropped\): there is nothing"):
        as_missing(np.ones(2, bool), 2)
    # fewer integers than frames: dropped frames' indices, most likely; said how to give them as flags
    with pytest.raises(ValueError, match=r"`missing` must be 4 booleans, one per camera frame; got int64 \(1,\): "
                                         r"for dropped frames' indices \[2\] give np.isin\(np.arange\(4\), \[2\]\)$"):
        as_missing(np.array([2], np.int64), 4)
    with pytest.raises(ValueError, match=r"got int64 \(2,\)$"):  # an index past the last frame: no such hint
        as_missing(np.array([1, 9], np.int64), 4)


def test_missing_as_frame_indices_is_refused_not_read_as_booleans():
    # [0, 2, 0, 1]: the indices of dropped frames, not one flag per frame; read as booleans it would
    # drop frames 1 and 3 and keep frames 0 and 2 without a word.
    assert as_missing(np.array([0, 1, 0, 0]), 4).tolist() == [False, True, False, False]
    with pytest.raises(ValueError, match=r"`missing` must be 4 booleans \(or 0/1\), one per camera frame; got "
                                         r"the values 0 to 2: for dropped frames' indices \[0, 1, 2\] give "
                                         r"np.isin\(np.arange\(4\), \[0, 1, 2\]\)"):
        as_missing(np.array([0, 2, 0, 1]), 4)
    with pytest.raises(ValueError, match=r"got the values -1 to 0$"):
        as_missing(np.array([0, -1, 0, 0]), 4)


def test_a_gap_longer_than_the_reach_is_refused_naming_it():
    check_reach(_missing(12, [4, 5]), 2, "rebin", 16)
    with pytest.raises(GapTooLongError, match=r"frames 4-6 \(3 frames; sub-frames 64-111\) were dropped in a row; "
                                              r"rebin bridges gaps of at most 2 frame\(s\)"):
        check_reach(_missing(12, [4, 5, 6]), 2, "rebin", 16)


def test_dropped_frames_are_filled_pixel_by_pixel_from_their_neighbours():
    f = np.stack([np.full((2, 2), v, np.float32) for v in (0.0, 9, 9, 3.0, 5.0)])
    out = fill_frames(f, _missing(5, [1, 2, 4]))
    np.testing.assert_allclose(out[:, 0, 0], [0, 1, 2, 3, 3])  # a line between frames 0 and 3; frame 4 holds 3
    assert f[1, 0, 0] == 9  # the input is not changed


def test_the_bridge_blends_both_sides_in_time():
    K = 2
    video = np.zeros((5 * K, 1, 1), np.float32)
    video[:, 0, 0] = [1, 1, 7, 7, 7, 7, 5, 5, 9, 9]  # frames 1 and 2 missing: sub-frames 2..5
    flags = bridge(video, _missing(5, [1, 2]), K)
    np.testing.assert_allclose(video[:, 0, 0], [1, 1, 1.8, 2.6, 3.4, 4.2, 5, 5, 9, 9], rtol=1e-6)
    np.testing.assert_array_equal(flags, [0, 0, 1, 1, 1, 1, 0, 0, 0, 0])
    ends = np.arange(6, dtype=np.float32).reshape(6, 1, 1)
    bridge(ends, _missing(3, [0, 2]), 2)  # one side each: held
    np.testing.assert_array_equal(ends[:, 0, 0], [2, 2, 2, 3, 3, 3])


def test_with_a_flow_the_bridge_moves_each_side_along_it():
    # A bright column moving one pixel per sub-frame; sub-frames 4..7 dropped.
    K, S, W = 4, 12, 24
    video = np.zeros((S, 3, W), np.float32)
    for t in range(S):
        video[t, :, 2 + t] = 1
    truth = video.copy()
    video[4:8] = 0
    flow = np.zeros((S, 3, W, 2), np.float32)
    flow[..., 0] = 1
    flow[4:8] = 99  # whatever was measured inside the gap is replaced
    bridge(video, _missing(3, [1]), K, flow=flow)
    np.testing.assert_allclose(video[4:8], truth[4:8], atol=1e-6)
    np.testing.assert_array_equal(flow[4:8, ..., 0], 1)
    linear = truth.copy()
    linear[4:8] = 0
    bridge(linear, _missing(3, [1]), K)
    assert np.abs(linear[4:8] - truth[4:8]).max() > 0.5  # without the flow the column fades across


def test_the_flow_across_a_gap_is_a_line_between_its_sides():
    flow = np.zeros((12, 1, 1, 2), np.float32)
    flow[:, 0, 0, 0] = np.arange(12)
    flow[3:9, 0, 0, 0] = -5
    bridge_flow(flow, _missing(3, [1]), 4, margin=1)  # span 3..8, sides 2 and 9
    np.testing.assert_allclose(flow[:, 0, 0, 0], np.arange(12))


@pytest.mark.parametrize("name", names())
@pytest.mark.parametrize("drops", [[3], [3, 4], [1, 2, 3, 4, 5]])
def test_every_method_bridges_a_constant_scene_exactly(name, drops):
    F = 8
    video = np.full((F * 4, 12, 16), 0.4, np.float32)
    frames = capture(video, CODE)
    missing = _missing(F, drops)
    frames[missing] = 0  # a dropped frame is a zero row
    method = Method(name)
    if len(drops) > method.max_gap(4):
        with pytest.raises(GapTooLongError, match=r"frames 1-5 \(5 frames"):
            run(frames, CODE, method, missing=missing)
        return
    out = run(frames, CODE, method, missing=missing, chunk_frames=3)
    assert np.isfinite(out.video).all()
    np.testing.assert_allclose(out.video, 0.4, atol=2e-4)  # GAP-TV: 1e-4 after 40 iterations, gap or not
    np.testing.assert_array_equal(out.interpolated, interpolated_subframes(missing, 4))


@pytest.mark.parametrize("name", ["diffusion", "motion-aware", "rebin", "gap-tv"])
def test_chunks_give_the_same_result_across_a_gap(name):
    truth = render_scene("balls", 10 * 4, 24, 32)
    frames = capture(truth, CODE)
    missing = _missing(10, [4, 5])
    frames[missing] = 0
    whole = run(frames, CODE, Method(name), missing=missing, chunk_frames=None).video
    parts = run(frames, CODE, Method(name), missing=missing, chunk_frames=3).video
    np.testing.assert_allclose(parts, whole, atol=2e-5)


@pytest.mark.parametrize("name", ["diffusion", "motion-aware"])
def test_a_zero_row_does_not_leak_into_the_frames_beside_it(name):
    # Reconstructed as missing, the frame next to a gap is nearly as good as without the drop;
    # taken for samples, the zero row darkens it.
    truth = render_scene("balls", 12 * 16, 48, 64)
    frames = capture(truth, CODE16)
    missing = _missing(12, [5])
    dropped = frames.copy()
    dropped[missing] = 0
    near = slice(4 * 16, 5 * 16)
    good = run(dropped, CODE16, Method(name), missing=missing).video
    naive = run(dropped, CODE16, Method(name)).video
    clean = run(frames, CODE16, Method(name)).video
    assert psnr(truth[near], good[near]) > psnr(truth[near], naive[near]) + 1.0
    assert psnr(truth[near], good[near]) > psnr(truth[near], clean[near]) - 1.5


@settings(max_examples=15, deadline=None)
@given(drops=st.lists(st.integers(0, 7), min_size=1, max_size=3, unique=True), seed=st.integers(0, 2**16))
def test_outputs_stay_finite_and_in_the_samples_range(drops, seed):
    rng = np.random.default_rng(seed)
    video = rng.uniform(0.2, 0.7, (8 * 4, 8, 12)).astype(np.float32)
    frames = capture(video, CODE)
    missing = _missing(8, drops)
    if missing.all():
        return
    frames[missing] = 0
    for name in ("diffusion", "motion-aware"):
        method = Method(name)
        if max(g.frames for g in find_gaps(missing)) > method.max_gap(4):
            continue
        out = run(frames, CODE, method, missing=missing).video
        present = frames[~missing]
        assert np.isfinite(out).all()
        assert out.min() >= present.min() - 1e-5 and out.max() <= present.max() + 1e-5


def test_bridge_refuses_a_missing_that_is_not_one_boolean_per_frame_and_a_flow_of_other_length_in_words():
    from flexvox_core.gaps import bridge

    video = np.zeros((8, 4, 4), np.float32)
    with pytest.raises(ValueError, match=r"`missing` must be booleans, one per camera frame; got <U7 \(\)"):
        bridge(video, "frame 1", 4)
    with pytest.raises(ValueError, match=r"`flow` must have the video's 8 sub-frames; got shape \(3, 4, 4, 2\)"):
        bridge(video, np.array([False, True]), 4, flow=np.zeros((3, 4, 4, 2), np.float32))
