"""Streaming motion-aware: one frame behind, the same values as its window's offline run, close to the
whole clip's, dropped frames bridged, bad input refused by name."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.flow.memo import FlowMemo
from flexvox_core.forward import capture
from flexvox_core.gaps import GapTooLongError
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.motion.pipeline import MotionOptions, gated_flow, run_window
from flexvox_core.motion.streaming import StreamingMotionAware
from flexvox_core.simulate.scenes import render_scene

CODE = design_code((4, 4)).code  # K = 16
K = 16


@pytest.fixture(scope="module")
def balls():
    truth = render_scene("balls", 5 * K, 48, 64)
    return truth, capture(truth, CODE)


def _stream(frames, **kw):
    stream = StreamingMotionAware(CODE, **kw)
    out = []
    for i, frame in enumerate(frames):
        got = stream.push(frame)
        # One frame behind: frame i - 1 comes back when frame i arrives (nothing after the first).
        assert [o.index for o in got] == ([] if i == 0 else [i - 1])
        out += got
    out += stream.finish()
    return stream, out


def test_each_frame_equals_its_windows_offline_run(balls):
    _, frames = balls
    stream, out = _stream(frames)
    assert [o.index for o in out] == list(range(len(frames)))
    assert [o.window for o in out] == [(0, 2), (0, 3), (1, 4), (2, 5), (3, 5)]
    for o in out:
        a, b = o.window
        ref = motion_aware(frames[a:b], CODE, sample_range=(0, 1)).video[(o.index - a) * K:(o.index - a + 1) * K]
        # Only the work whose result is cut was left out: the same values up to float rounding.
        np.testing.assert_allclose(o.video, ref, rtol=0, atol=1e-5)
        assert o.video.dtype == np.float32 and not o.interpolated
    assert stream.memo.hits > 0  # pairs met in an earlier window were not computed again


@pytest.mark.parametrize("scene", ["balls", "drummer"])
def test_whole_clip_within_0_3_db_of_offline(scene):
    truth = render_scene(scene, 6 * K, 48, 64)
    frames = capture(truth, CODE)
    _, out = _stream(frames)
    video = np.concatenate([o.video for o in out])
    offline = motion_aware(frames, CODE, sample_range=(0, 1)).video
    assert video.shape == offline.shape
    assert abs(psnr(truth, video) - psnr(truth, offline)) < 0.3


def test_dropped_frame_is_bridged_and_marked(balls):
    truth, frames = balls
    stream = StreamingMotionAware(CODE)
    out = []
    for i, frame in enumerate(frames):
        out += stream.push(None if i == 2 else frame)
    out += stream.finish()
    assert [o.index for o in out] == list(range(len(frames)))
    assert [o.interpolated for o in out] == [False, False, True, False, False]
    # The windows reach past the gap to a captured frame on each side.
    assert out[1].window == (0, 4) and out[2].window == (1, 4) and out[3].window == (1, 5)
    video = np.concatenate([o.video for o in out])
    assert np.isfinite(video).all() and video.min() >= 0 and video.max() <= 1
    # The bridged frame is a fair guess, not black.
    assert psnr(truth[2 * K:3 * K], video[2 * K:3 * K]) > 15


def test_a_gap_longer_than_the_reach_is_refused():
    stream = StreamingMotionAware(CODE, refine_time=0.0)  # overlap 3: gaps of up to 6 frames
    assert stream.max_gap == 6
    stream.push(np.zeros((16, 16), np.float32))
    for _ in range(6):
        stream.push(None)
    with pytest.raises(GapTooLongError, match=r"frames 1-7 were dropped in a row; .* at most 6 frame"):
        stream.push(None)


def test_a_stream_stops_after_a_gap_too_long():
    stream = StreamingMotionAware(CODE, refine_time=0.0)
    stream.push(np.zeros((16, 16), np.float32))
    for _ in range(6):
        stream.push(None)
    with pytest.raises(GapTooLongError):
        stream.push(None)
    # Going on would count the next frame as the dropped one: the stream refuses, saying why.
    with pytest.raises(RuntimeError, match=r"the stream stopped \(frames 1-7 were dropped in a row; .*\); start a new"):
        stream.push(np.zeros((16, 16), np.float32))


def test_back_zero_reaches_back_only_across_a_dropped_frame(balls):
    _, frames = balls
    stream = StreamingMotionAware(CODE, back=0)
    out = []
    for i, frame in enumerate(frames):
        out += stream.push(None if i == 2 else frame)
    out += stream.finish()
    assert [o.window for o in out] == [(0, 2), (1, 4), (1, 4), (3, 5), (4, 5)]


def test_back_zero_skip_to_the_newest_keeps_what_a_dropped_frame_reaches_back_to(balls):
    # A preview that fell behind skips to the newest frame; when the camera then drops it, its window reaches
    # back past it to the last captured frame, which the skip must not have forgotten.
    _, frames = balls
    stream = StreamingMotionAware(CODE, back=0)
    stream.push(frames[0])
    stream.skip_to(1)
    assert stream.push(None) == []
    out = stream.push(frames[2])
    assert [(o.index, o.window, o.interpolated) for o in out] == [(1, (0, 3), True)]
    assert np.isfinite(out[0].video).all()


@pytest.mark.parametrize("case", ["a second pass", "a dropped frame"])
def test_a_kept_range_is_the_whole_windows_run_with_a_second_pass_or_a_dropped_frame(balls, case):
    # Then everything is gathered and refined, and cut at the end: the same values as the whole run's.
    _, frames = balls
    f = np.asarray(frames[1:4], np.float32).copy()
    options = MotionOptions(passes=2) if case == "a second pass" else MotionOptions()
    missing = None if case == "a second pass" else np.array([False, True, False])
    if missing is not None:
        f[missing] = 0
    whole = run_window(f, CODE, options, (0.0, 1.0), missing=missing).video[K:2 * K]
    kept = run_window(f, CODE, options, (0.0, 1.0), missing=missing, keep=(K, 2 * K)).video
    np.testing.assert_allclose(kept, whole, rtol=0, atol=1e-5)


def test_a_stream_of_dropped_frames_only_is_refused():
    stream = StreamingMotionAware(CODE)
    stream.push(None)
    with pytest.raises(GapTooLongError, match="every frame of the stream was dropped"):
        stream.finish()


def test_skip_to_gives_up_older_frames(balls):
    _, frames = balls
    stream = StreamingMotionAware(CODE, ahead=1)
    stream.push(frames[0])
    assert stream.ready() == 0
    stream.skip_to(3)  # a preview that fell behind: the newest wins
    assert stream.emitted == 1  # cannot skip past what was pushed
    for frame in frames[1:4]:
        stream.push(frame)
    assert stream.emitted == 3
    stream.skip_to(3)
    assert [o.index for o in stream.push(frames[4])] == [3]


@pytest.mark.parametrize(("kw", "message"), [
    ({"back": -1}, r"`back` must be a whole number >= 0 \(frames\); got -1"),
    ({"ahead": 0}, r"`ahead` must be a whole number >= 1 \(frames\); got 0"),
    ({"sample_range": (1, 0)}, r"`sample_range` must be two finite numbers lo < hi; got \(1, 0\)"),
    ({"time": -1.0}, r"`time` must be a finite number > 0; got -1.0"),
    ({"flow_scale": 2.0}, r"`flow_scale` must be in \(0, 1\] or None; got 2.0"),
    ({"flow": "dsi"}, r"`flow` must be one of dis, deepflow, farneback, tvl1; got 'dsi'"),
    ({"gate": (0.2, 0.1)}, r"`gate` must be two thresholds 0 <= low < high \(px per sub-frame\); got \(0.2, 0.1\)"),
    ({"time": "5"}, r"`time` must be a finite number > 0; got '5'"),
    ({"still_speed": -1}, r"`still_speed` must be a number >= 0 \(px per sub-frame\) or None; got -1"),
    ({"time": 1e308}, r"time 1e\+308 with tensor \(0.05, 0.05, 0.95\) asks for a blur of σ = .*; at most 10000"),
    ({"refine_time": 1e308}, r"`refine_time` must be a number from 0 to 10526 or None \(\(K/16\)²\); got 1e\+308"),
    ({"refine_time": 1e6}, r"`refine_time` must be a number from 0 to 10526 or None \(\(K/16\)²\); got 1000000.0"),
    ({"slow_reach": 1e308},
     r"`slow_reach` must be a number from 0 to 1000 \(sampling periods\) or None; got 1e\+308"),
])
def test_bad_options_are_refused_by_name(kw, message):
    with pytest.raises(ValueError, match=message):
        StreamingMotionAware(CODE, **kw)


def test_bad_frames_are_refused_by_name():
    stream = StreamingMotionAware(CODE)
    with pytest.raises(ValueError, match=r"a frame must be an image \(H, W\); got shape \(2, 16, 16\)"):
        stream.push(np.zeros((2, 16, 16), np.float32))
    stream.push(np.zeros((16, 16), np.float32))
    with pytest.raises(ValueError, match=r"frame 1 is 16x20; the stream's frames are 16x16"):
        stream.push(np.zeros((16, 20), np.float32))
    with pytest.raises(ValueError, match=r"frame 1 has values in \[2, 2\], outside the stream's sample_range \[0, 1\]"):
        stream.push(np.full((16, 16), 2.0, np.float32))
    with pytest.raises(ValueError, match=r"frame 1 holds NaN"):
        stream.push(np.full((16, 16), np.nan, np.float32))
    assert stream.pushed == 1  # nothing refused was taken in
    stream.finish()
    with pytest.raises(RuntimeError, match="the stream is finished"):
        stream.push(np.zeros((16, 16), np.float32))


def test_options_overlap_is_the_methods():
    # One rule for the context a result depends on: the stream's gap reach and the batch's overlap.
    assert MotionOptions().overlap(16) == 4 and MotionOptions(refine_time=0.0).overlap(8) == 3
    assert MotionOptions(slow_reach=4.0).overlap(8) == 7


def test_flow_memo_never_changes_the_flow(balls):
    truth, _ = balls
    memo = FlowMemo()
    plain = gated_flow(truth, K, backend="dis")
    first = gated_flow(truth, K, backend="dis", memo=memo)
    assert memo.hits == 0 and len(memo) > 0
    again = gated_flow(truth, K, backend="dis", memo=memo)
    assert memo.hits == memo.misses  # every pair found the second time
    np.testing.assert_array_equal(plain.flow, first.flow)
    np.testing.assert_array_equal(plain.flow, again.flow)
    other = gated_flow(truth, K, backend="farneback", memo=memo)  # another backend never reads dis's pairs
    assert not np.array_equal(other.flow, plain.flow)


def test_flow_memo_forgets_the_oldest_pairs():
    memo = FlowMemo(max_pairs=2)
    img = np.zeros((4, 4), np.uint8)
    keys = [memo.key("dis", img + i, img, False) for i in range(3)]
    for k in keys:
        memo.put(k, np.zeros((4, 4, 2)), np.ones((4, 4)))
    assert len(memo) == 2 and memo.get(keys[0]) is None and memo.get(keys[2]) is not None
    flow, _ = memo.get(keys[1])
    assert not flow.flags.writeable
    with pytest.raises(ValueError, match=r"`max_pairs` must be a whole number >= 1; got 0"):
        FlowMemo(max_pairs=0)


def test_a_noisy_frame_is_clipped_by_default_and_refused_outside_a_given_range(caplog):
    """Sensor noise takes a normalised frame a little past [0, 1]: the default stream clips it into [0, 1] (logged
    once, counted); a stream given its ``sample_range`` refuses it."""
    rng = np.random.default_rng(0)
    frame = np.clip(rng.random((16, 16)), 0, 1).astype(np.float32) + rng.normal(0, 0.02, (16, 16)).astype(np.float32)
    assert frame.min() < 0 and frame.max() > 1
    stream = StreamingMotionAware(CODE)
    with caplog.at_level("INFO", logger="flexvox_core.motion.streaming"):
        stream.push(frame)
        stream.push(frame)
    assert stream.clipped == 2 and stream.pushed == 2
    assert sum("clipped into [0, 1]" in r.getMessage() for r in caplog.records) == 1
    assert stream._frames[0].min() == 0 and stream._frames[0].max() == 1
    strict = StreamingMotionAware(CODE, sample_range=(0, 1))
    with pytest.raises(ValueError, match=r"frame 0 has values in \[-0\.0\d+, 1\.0\d+\], outside the stream's "
                                         r"sample_range \[0, 1\]"):
        strict.push(frame)


def test_motion_aware_returns_values_in_0_1_on_a_noisy_capture():
    """The samples' range bounds the pipeline's video; the public function's lies in [0, 1] (the pipeline's own
    values inside it unchanged)."""
    from flexvox_core.motion.options import MotionOptions
    from flexvox_core.motion.pipeline import run_clip

    frames = capture(render_scene("balls", 3 * K, 12, 16, seed=0), CODE)
    frames = (frames - frames.min()) / np.ptp(frames) * 1.1 - 0.05  # the scene's range a little past [0, 1]
    frames = (frames + np.random.default_rng(1).normal(0, 0.02, frames.shape)).astype(np.float32)
    inner = run_clip(frames, CODE, MotionOptions()).video
    assert inner.min() < 0 and inner.max() > 1
    video = motion_aware(frames, CODE).video
    assert video.min() == 0 and video.max() == 1
    np.testing.assert_array_equal(video, np.clip(inner, 0, 1))


def test_the_deprecated_value_range_names_warn_and_still_work(rng):
    from flexvox_core.motion.options import check_sample_range, sample_bounds

    frames = rng.random((3, 8, 8), dtype=np.float32)
    with pytest.warns(DeprecationWarning, match=r"`value_range` of motion_aware is deprecated .* `sample_range`"):
        old = motion_aware(frames, CODE, value_range=(0, 1)).video
    np.testing.assert_array_equal(old, motion_aware(frames, CODE, sample_range=(0, 1)).video)
    with pytest.warns(DeprecationWarning, match=r"`value_range` of StreamingMotionAware is deprecated"):
        stream = StreamingMotionAware(CODE, value_range=(0, 2))
    with pytest.warns(DeprecationWarning, match=r"StreamingMotionAware\.value_range is deprecated .* "
                                                r"StreamingMotionAware\.sample_range"):
        assert stream.value_range == stream.sample_range == (0.0, 2.0)
    with pytest.warns(DeprecationWarning, match=r"motion\.options\.sample_bounds is deprecated .* check_sample_range"):
        assert sample_bounds(frames, None, (0, 1)) == check_sample_range(frames, None, (0, 1)) == (0.0, 1.0)
