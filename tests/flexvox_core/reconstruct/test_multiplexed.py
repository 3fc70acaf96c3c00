"""Multiplexed captures from their own forward model: GAP with flexvox's priors, the runner and the reader."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.ndimage import gaussian_filter

from flexvox_core.capture_reader import CaptureReader
from flexvox_core.forward import capture
from flexvox_core.methods import Method, run
from flexvox_core.metrics import psnr
from flexvox_core.motion.multiplexed import motion_aware_multiplexed
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct import as_identity_capture
from flexvox_core.reconstruct.diffusion import gaussian
from flexvox_core.reconstruct.multiplexed import gap_gaussian
from flexvox_core.recording import open_recording, write_simulation
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video
from flexvox_core.video_api import reconstruct_video

MC = multiplexed_code((1, 3))


def test_gaussian_is_the_float64_gaussian_filter(rng):
    v = rng.random((9, 12, 14)).astype(np.float32)
    tensor, time = (0.3, 0.2, 1.0), 1.5
    sx, sy, st_ = (np.sqrt(2 * time * c) for c in tensor)
    ref = gaussian_filter(v.astype(np.float64), (st_, sy, sx), mode="reflect", truncate=4.0)
    out = gaussian(v, tensor, time)
    assert out.dtype == np.float32 and not np.shares_memory(out, v)
    np.testing.assert_allclose(out, ref, atol=1e-5)


@settings(max_examples=15, deadline=None)
@given(value=st.floats(0.0, 1.0), tile=st.sampled_from([(1, 3), (1, 7), (3, 5)]), frames=st.integers(1, 3))
def test_a_constant_scene_comes_back_exactly(value, tile, frames):
    code = multiplexed_code(tile).code
    K = code.shape[2]
    video = np.full((frames * K, 7, 10), value, np.float32)
    out = gap_gaussian(capture(video, code), code, iterations=5)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out, value, atol=1e-5)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**16))
def test_random_scenes_give_finite_output_near_the_range(seed):
    video = np.random.default_rng(seed).random((2 * 3, 6, 9)).astype(np.float32)
    out = gap_gaussian(capture(video, MC.code), MC.code, iterations=10)
    assert np.isfinite(out).all()
    assert out.min() > -0.5 and out.max() < 1.5  # unclipped GAP overshoots little; the runner clips to [0, 1]
    clipped = reconstruct_video(capture(video, MC.code), MC.code, Method("diffusion"))
    assert clipped.min() >= 0 and clipped.max() <= 1


def test_float32_matches_the_float64_reference(rng):
    video = rng.random((4 * 3, 8, 9))
    frames = capture(video, MC.code)
    out32 = gap_gaussian(frames, MC.code)
    out64 = gap_gaussian(frames, MC.code, dtype=np.float64)
    assert out32.dtype == np.float32 and out64.dtype == np.float64
    np.testing.assert_allclose(out32, out64, atol=2e-5)


def _balls(tile, frames=3):
    code = multiplexed_code(tile)
    truth = render_scene("balls", frames * code.K, 30, 40)
    return truth, code, capture(truth, code.code)


def test_the_forward_model_beats_per_tile_demultiplexing_on_a_moving_scene():
    truth, mc, frames = _balls((3, 5))
    demux = run(*as_identity_capture(frames, mc), Method("diffusion")).video
    own = run(frames, mc.code, Method("diffusion")).video
    assert psnr(truth, own) > psnr(truth, demux) + 3


def test_motion_aware_multiplexed_reconstructs_a_still_scene_exactly():
    video = np.full((3 * 7, 12, 14), 0.4, np.float32)
    code = multiplexed_code((1, 7)).code
    out = motion_aware_multiplexed(capture(video, code), code, iterations=2)
    np.testing.assert_allclose(out, 0.4, atol=1e-5)


@pytest.mark.parametrize("method", [Method("diffusion"), Method("gap-tv", iterations=3),
                                    Method("motion-aware", time=2.0)], ids=lambda m: m.name)
def test_chunked_equals_whole_for_multiplexed_captures(method):
    _, mc, frames = _balls((1, 3), frames=7)
    whole = reconstruct_video(frames, mc.code, method, chunk_frames=None)
    chunked = reconstruct_video(frames, mc.code, method, chunk_frames=2)
    assert whole.shape == (21, 30, 40)
    np.testing.assert_array_equal(whole, chunked)


def test_dropped_frames_of_a_multiplexed_capture_are_interpolated_by_the_runner():
    _, mc, frames = _balls((1, 3), frames=6)
    missing = np.zeros(6, bool)
    missing[2] = True
    frames[2] = 0
    out = run(frames, mc.code, Method("diffusion"), missing=missing)
    assert np.isfinite(out.video).all() and out.video[6:9].mean() > 0.05
    np.testing.assert_array_equal(out.interpolated, np.repeat(missing, 3))


def test_capabilities():
    assert Method("diffusion").takes_multiplexed() and Method("motion-aware").takes_multiplexed()
    assert Method("gap-tv").takes_multiplexed()
    assert not Method("diffusion", solver="explicit").takes_multiplexed()
    assert not Method("rebin").takes_multiplexed()


@pytest.mark.parametrize("call, match", [
    (lambda f: run(f, MC.code, Method("rebin")), r"rebin .* takes identity-code captures only; demultiplex"),
    (lambda f: gap_gaussian(f, MC.code, iterations=-1), r"`iterations` must be a whole number >= 0; got -1"),
    (lambda f: gap_gaussian(f, MC.code, context=1.5), r"`context` must be a whole number >= 0; got 1.5"),
    (lambda f: motion_aware_multiplexed(f, MC.code, passes=0), r"`passes` must be a whole number >= 1; got 0"),
])
def test_refusals(call, match):
    with pytest.raises(ValueError, match=match):
        call(np.full((2, 4, 6), 0.5, np.float32))


def test_a_pixel_closed_in_every_slot_is_refused():
    code = MC.code.copy()
    code[0, 0] = False
    with pytest.raises(ValueError, match=r"`code` leaves some tile pixel closed in every slot; nothing measures it"):
        gap_gaussian(np.ones((2, 4, 6), np.float32), code)


@pytest.fixture
def mux_path(tmp_path):
    truth = render_scene("balls", 4 * 3, 12, 15)
    result = simulate_video(truth, MC, seed=4)  # the MultiplexedCode itself: marked multiplexed, with its placement
    assert result.multiplexed and np.array_equal(result.placement, MC.placement)
    np.testing.assert_array_equal(result.frames, simulate_video(truth, MC.code, seed=4).frames)
    return write_simulation(tmp_path / "m.zarr", result)


def test_a_simulation_through_the_code_array_alone_is_not_written_as_a_recording(tmp_path):
    result = simulate_video(render_scene("balls", 4 * 3, 12, 15), MC.code)  # its `.code`: not marked multiplexed
    with pytest.raises(ValueError, match=r"opens pixels in more than one slot, and the simulation is not marked "
                                         r"multiplexed.*fv\.simulate_video\(video, fv\.multiplexed_code\(tile\)\), not "
                                         r"its `\.code`; nothing was written"):
        write_simulation(tmp_path / "m.zarr", result)
    assert not (tmp_path / "m.zarr").exists()


def test_the_reader_hands_multiplexed_frames_to_methods_that_take_them(mux_path):
    rec = open_recording(mux_path)
    reader = CaptureReader(rec)
    frames, code = reader.input(Method("diffusion"))
    np.testing.assert_array_equal(frames, rec.normalised_frames())
    np.testing.assert_array_equal(code, MC.code)
    frames, code = reader.input(Method("rebin"), 1, 3)  # the fallback: demultiplexed per tile
    np.testing.assert_array_equal(frames, reader.read(1, 3))
    np.testing.assert_array_equal(code, reader.code)
    np.testing.assert_array_equal(reader.preparation_for(Method("diffusion"))(reader.raw[0:2]),
                                  rec.normalised_frames(0, 2))


def test_batch_equals_the_in_memory_run_on_a_multiplexed_recording(mux_path):
    from flexvox_core.batch import batch_video

    rec = open_recording(mux_path)
    m = Method("diffusion")
    video, _ = batch_video(rec, m, chunk_frames=2)
    expected = reconstruct_video(*CaptureReader(rec).input(m), m)
    np.testing.assert_array_equal(video.compute(scheduler="synchronous"), expected)


def test_the_deprecated_multiplexed_names_warn_and_still_answer():
    from flexvox_core.methods import MethodSpec

    diffusion = Method("diffusion")
    with pytest.warns(DeprecationWarning, match=r"MethodSpec\.accepts_multiplexed is deprecated .* "
                                                r"call takes_multiplexed\(options\)"):
        assert diffusion.spec.accepts_multiplexed(diffusion.spec.build(diffusion.spec.resolve({})))

    class Flagged(MethodSpec):
        def overlap(self, options, K):
            return 0

        def run(self, frames, code, options, **kw):
            raise NotImplementedError

        def label(self, values):
            return "flagged"

    with pytest.warns(DeprecationWarning, match=r"Old\.takes_multiplexed as a class flag \(True\) is deprecated"):
        Old = type("Old", (Flagged,), {"takes_multiplexed": True})
    with pytest.warns(DeprecationWarning, match=r"Older\.accepts_multiplexed is deprecated .* "
                                                r"name the method takes_multiplexed\(self, options\)"):
        Older = type("Older", (Flagged,), {"accepts_multiplexed": lambda self, options: options == "yes"})
    assert Old().takes_multiplexed(None) and not Flagged().takes_multiplexed(None)
    assert Older().takes_multiplexed("yes") and not Older().takes_multiplexed("no")

