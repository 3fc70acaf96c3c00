"""The one chunked runner: the result does not depend on the chunking; the Method value API."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.divisions import Division
from flexvox_core.forward import capture
from flexvox_core.methods import Method, default_block, overlap_frames
from flexvox_core.motion.options import SLOW_REACH
from flexvox_core.video_api import reconstruct_video

CODE = design_code((2, 4)).code


@pytest.fixture
def case(rng):
    truth = rng.random((8 * 9, 10, 12)).astype(np.float32)
    return truth, capture(truth, CODE)


@pytest.mark.parametrize(
    "method",
    [
        Method("rebin"),
        Method("rebin", interpolate=False),
        Method("diffusion"),
        Method("diffusion", tensor=(0.05, 0.05, 1), time=8),
        Method("diffusion", solver="explicit", time=0.5),
        Method("gap-tv", iterations=3),
    ],
    ids=lambda m: m.label(),
)
def test_chunking_does_not_change_the_result(case, method):
    _, frames = case
    whole = reconstruct_video(frames, CODE, method, chunk_frames=None)
    chunked = reconstruct_video(frames, CODE, method, chunk_frames=2)
    assert whole.shape == (72, 10, 12) and whole.dtype == np.float32
    assert np.array_equal(whole, chunked)
    assert whole.min() >= 0 and whole.max() <= 1


def test_progress_is_reported_per_chunk(case):
    _, frames = case
    calls = []
    reconstruct_video(frames, CODE, Method("diffusion"), chunk_frames=4, progress=lambda d, t: calls.append((d, t)))
    assert calls == [(4, 9), (8, 9), (9, 9)]


def test_default_block_is_balanced_and_square_first():
    assert default_block(design_code((4, 4)).code) == Division(2, 2, 4)
    assert default_block(CODE).tr in (2, 4)


def test_overlap_rules():
    assert overlap_frames(Method("gap-tv"), 8) == 0
    assert overlap_frames(Method("diffusion", solver="steady"), 8) is None
    assert overlap_frames(Method("diffusion", tensor=(0, 0, 1), time=8), 8) >= 2


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"name": "magic"}, r"`method` must be one of rebin, diffusion, gap-tv, motion-aware; got .magic."),
        ({"name": "diffusion", "solver": "exact"}, r"`solver` must be one of nc, explicit, steady"),
        ({"name": "diffusion", "tensor": (-1, 1, 1)}, r"tensor"),
        ({"solver": "nc"}, r"`solver` is not an option of motion-aware \(its options: flow, time"),
    ],
)
def test_bad_methods(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Method(**kwargs)


@pytest.mark.parametrize("chunk", [0, 2.5, 2.0, "4", True])
def test_bad_chunk(case, chunk):
    # 2.5 and "4" had raised TypeErrors from range() and from a comparison
    with pytest.raises(ValueError, match=rf"`chunk_frames` must be a whole number >= 1 or None; got {chunk!r}"):
        reconstruct_video(case[1], CODE, Method(), chunk_frames=chunk)


def test_motion_aware_chunking_matches_the_whole(rng):
    from flexvox_core.simulate.scenes import render_scene

    truth = render_scene("balls", 8 * 10, 24, 32)
    frames = capture(truth, CODE)
    m = Method("motion-aware", time=2.0)
    whole = reconstruct_video(frames, CODE, m, chunk_frames=None)
    chunked = reconstruct_video(frames, CODE, m, chunk_frames=4)
    assert np.allclose(whole, chunked, atol=1e-5)


@pytest.mark.parametrize("slow_reach", [None, 4.0])
def test_motion_aware_chunking_matches_the_whole_with_slow_voxels(slow_reach):
    # A slow pan: the slow voxels' long gather runs. Its range weight is scaled by the samples'
    # range, which must be the whole capture's in every chunk; and a reach of 4 periods needs
    # more overlap than the default 3 frames.
    from flexvox_core.simulate.scenes import render_scene

    truth = render_scene("pan", 8 * 10, 24, 32)
    frames = capture(truth, CODE)
    m = Method("motion-aware", time=2.0, slow_reach=slow_reach)
    whole = reconstruct_video(frames, CODE, m, chunk_frames=None)
    chunked = reconstruct_video(frames, CODE, m, chunk_frames=3)
    assert np.array_equal(whole, chunked)


def test_slow_reach_knob():
    m = Method("motion-aware", slow_reach=2)
    assert m.label().endswith("slow-reach 2")
    assert m.options.slow_reach == 2.0 and m.slow_reach == 2
    assert Method("motion-aware").options.slow_reach == SLOW_REACH  # None: the pipeline's default
    assert overlap_frames(Method("motion-aware", refine_time=0.0), 8) == 3
    # The default refinement ((K/16)²: 1 explicit step at K = 8, 2 at K = 16) reads one frame further.
    assert overlap_frames(Method("motion-aware"), 8) == 4 and overlap_frames(Method("motion-aware"), 16) == 4
    assert overlap_frames(Method("motion-aware", slow_reach=4), 8) == 7  # 6, and one for the refinement


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), True, "2"])
def test_bad_slow_reach(bad):
    with pytest.raises(ValueError, match=r"`slow_reach` must be a number from 0 to 1000 \(sampling periods\) or None"):
        Method("motion-aware", slow_reach=bad)


class _Echo:
    """A stand-in spec whose result is chosen by the test: ``make(frames, K)`` -> (video, extras)."""

    def __init__(self, make):
        from flexvox_core.methods.spec import MethodSpec

        class Spec(MethodSpec):
            name = "echo"
            title = "test"
            extras = ("same",)

            def overlap(self, values, K):
                return 0

            def run(self, frames, code, values, *, sample_range=None, extras=False, missing=None):
                from flexvox_core.methods import MethodOutput

                video, extra = make(frames, code.shape[2])
                return MethodOutput(video, extra)

            def label(self, values):
                return "echo"

        self.spec = Spec()
        self.options = {}

    def takes_multiplexed(self):
        return False

    def label(self):
        return "echo"


def test_run_chunk_clips_its_own_result_in_place_and_never_an_input_or_an_extra(rng):
    from flexvox_core.methods.runner import run_chunk

    frames = (rng.random((2, 4, 8)) * 3 - 1).astype(np.float32)  # values outside [0, 1]
    before = frames.copy()
    own = np.repeat(frames, 8, axis=0)  # the method's own memory: clipped where it lies
    got = run_chunk(frames, CODE, _Echo(lambda f, K: (own, {})))
    assert got.video is own or np.shares_memory(got.video, own)
    assert got.video.min() == 0 and got.video.max() == 1
    # A result that is (a view of) the input: the input stays as it was.
    def view(f, K):  # every sub-frame is frame 0 itself: a writeable view of the input
        return np.lib.stride_tricks.as_strided(f, (2 * K, *f.shape[1:]), (0, *f.strides[1:]), writeable=True), {}

    got = run_chunk(frames, CODE, _Echo(view))
    np.testing.assert_array_equal(frames, before)
    np.testing.assert_array_equal(got.video, np.clip(np.broadcast_to(before[0], (16, 4, 8)), 0, 1))
    # A result that is also an extra: the extra keeps its values.
    shared = np.repeat(frames, 8, axis=0)
    got = run_chunk(frames, CODE, _Echo(lambda f, K: (shared, {"same": shared})), extras=True)
    np.testing.assert_array_equal(shared, np.repeat(before, 8, axis=0))
    assert got.video.min() == 0 and got.video.max() == 1


def test_run_chunk_copies_a_chunk_cut_from_its_context(rng):
    # With context around the chunk, the kept sub-frames are a copy: the context is not held while the chunk
    # waits to be stored.
    from flexvox_core.methods.runner import run_chunk

    frames = (rng.random((3, 4, 8)) * 3 - 1).astype(np.float32)
    own = np.repeat(frames, 8, axis=0)
    got = run_chunk(frames, CODE, _Echo(lambda f, K: (own, {})), left=1, count=1)
    assert got.video.shape == (8, 4, 8) and not np.shares_memory(got.video, own)
    np.testing.assert_array_equal(got.video, np.clip(own[8:16], 0, 1))


def test_the_deprecated_methods_reconstruct_warns_and_gives_reconstruct_videos_video(rng):
    from flexvox_core.methods import reconstruct

    frames = rng.random((3, 8, 8), dtype=np.float32)
    with pytest.warns(DeprecationWarning, match=r"flexvox_core\.methods\.reconstruct is deprecated .* "
                                                r"call flexvox_core\.reconstruct_video"):
        video = reconstruct(frames, CODE, "diffusion")
    np.testing.assert_array_equal(video, reconstruct_video(frames, CODE, "diffusion"))


def test_the_deprecated_value_range_keyword_of_run_chunk_warns_and_still_works(rng):
    from flexvox_core.methods import run_chunk

    frames = rng.random((2, 8, 8), dtype=np.float32)
    with pytest.warns(DeprecationWarning, match=r"`value_range` of run_chunk is deprecated .* call it `sample_range`"):
        old = run_chunk(frames, CODE, Method("diffusion"), value_range=(0.0, 1.0)).video
    np.testing.assert_array_equal(old, run_chunk(frames, CODE, Method("diffusion"), sample_range=(0.0, 1.0)).video)
    with pytest.raises(TypeError, match=r"run_chunk got `sample_range` and its deprecated name `value_range`"):
        with pytest.warns(DeprecationWarning):
            run_chunk(frames, CODE, Method("diffusion"), sample_range=(0, 1), value_range=(0, 1))


def test_a_method_whose_run_takes_the_old_value_range_keyword_gets_the_range_with_a_warning(rng):
    from flexvox_core.methods import MethodOutput, MethodSpec, register, run_chunk, unregister

    seen = []

    class OldSpec(MethodSpec):
        name = "old-range"
        needs_sample_range = True

        def overlap(self, options, K):
            return 0

        def run(self, frames, code, options, *, value_range=None, extras=False):
            seen.append(value_range)
            return MethodOutput(np.zeros((frames.shape[0] * code.shape[2], *frames.shape[1:]), np.float32))

        def label(self, values):
            return "old"

    register(OldSpec())
    try:
        frames = rng.random((2, 8, 8), dtype=np.float32)
        with pytest.warns(DeprecationWarning, match=r"the `value_range` keyword of OldSpec\.run is deprecated"):
            run_chunk(frames, CODE, Method("old-range"), sample_range=(0.0, 2.0))
    finally:
        unregister("old-range")
    assert seen == [(0.0, 2.0)]
