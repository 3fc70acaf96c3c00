"""The one reader from a recording to reconstruction input."""


import numpy as np
import pytest

from flexvox_core.capture_reader import CaptureReader, NotReconstructableError, open_capture, read_capture
from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct import as_identity_capture
from flexvox_core.recording import RecordingError, open_recording, write_simulation
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.simulator import normalise_frames, simulate_video


@pytest.fixture
def counts_path(tmp_path, rng):
    v = rng.random((7 * 8, 10, 12)).astype(np.float32)
    eff = parse_effects({"photon_noise": {}, "adc": {"bits": 12, "gain": 0.5, "black_level": 32}})
    return write_simulation(tmp_path / "c.zarr", simulate_video(v, design_code((2, 4)).code, effects=eff, seed=3))


@pytest.fixture
def mux_path(tmp_path, rng):
    mc = multiplexed_code((1, 3))
    result = simulate_video(rng.random((5 * 3, 9, 12)).astype(np.float32), mc.code, seed=4)
    result.multiplexed, result.placement = True, mc.placement
    return write_simulation(tmp_path / "m.zarr", result)


def test_counts_are_normalised_and_windows_are_slices_of_the_whole(counts_path):
    rec = open_recording(counts_path)
    frames, code = read_capture(counts_path)
    assert frames.dtype == np.float32 and frames.shape == (7, 10, 12)
    np.testing.assert_array_equal(frames, normalise_frames(rec.frames[:], rec.attrs["storage"]))
    np.testing.assert_array_equal(code, rec.code)
    reader = open_capture(rec)
    np.testing.assert_array_equal(reader.read(2, 5), frames[2:5])
    assert reader.read(3, 3).shape == (0, 10, 12)
    assert reader.sample_range(2) == (float(frames.min()), float(frames.max()))
    np.testing.assert_array_equal(reader.preparation(reader.raw[4:7]), frames[4:7])


def test_multiplexed_recordings_are_demultiplexed(mux_path):
    rec = open_recording(mux_path)
    reader = CaptureReader(rec)
    mc = multiplexed_code((1, 3), placement=rec.attrs["placement_order"])
    expected, code = as_identity_capture(rec.normalised_frames(), mc)
    np.testing.assert_array_equal(reader.read(), expected)
    np.testing.assert_array_equal(reader.code, code)
    assert not np.array_equal(reader.code, rec.code)  # the placement's identity code, not the S-matrix code
    # Chunk by chunk (the batch's way) equals the whole.
    parts = [reader.preparation(reader.raw[a:b]) for a, b in ((0, 2), (2, 4), (4, 5))]
    np.testing.assert_array_equal(np.concatenate(parts), expected)


def test_dropped_frames_are_read_as_missing_and_left_out_of_the_sample_range(tmp_path, rng):
    v = rng.uniform(0.2, 0.8, (12 * 4, 8, 8)).astype(np.float32)
    eff = parse_effects({"dropped_frames": {"probability": 0.5}})
    path = write_simulation(tmp_path / "d.zarr", simulate_video(v, design_code((2, 2)).code, effects=eff, seed=1))
    dropped = open_recording(path).per_frame("dropped")
    assert dropped.any() and not dropped.all()
    reader = open_capture(path)
    np.testing.assert_array_equal(reader.missing, dropped)
    frames = reader.read()
    assert (frames[dropped] == 0).all()
    lo, hi = reader.sample_range(2)
    assert lo == float(frames[~dropped].min()) > 0 and hi == float(frames[~dropped].max())
    assert sum(g.frames for g in reader.gaps()) == int(dropped.sum())


def test_a_recording_whose_frames_were_all_dropped_is_refused(tmp_path, rng):
    v = rng.random((3 * 4, 8, 8)).astype(np.float32)
    eff = parse_effects({"dropped_frames": {"probability": 1.0}})
    path = write_simulation(tmp_path / "d.zarr", simulate_video(v, design_code((2, 2)).code, effects=eff, seed=1))
    with pytest.raises(NotReconstructableError, match=r"d.zarr: all 3 frames were dropped; there is nothing"):
        read_capture(path)
    assert issubclass(NotReconstructableError, RecordingError) and issubclass(NotReconstructableError, ValueError)


def test_refusals(counts_path, tmp_path):
    with pytest.raises(RecordingError, match=r"none.zarr: no such recording"):
        open_capture(tmp_path / "none.zarr")
    reader = open_capture(counts_path)
    with pytest.raises(ValueError, match=r"the window \[start, stop\) must lie in the recording's 7 frames "
                                         r"\(0 <= start <= stop <= 7\); got \[5, 9\)"):
        reader.read(5, 9)
    with pytest.raises(ValueError, match=r"`start` must be a whole number; got 1.5"):
        reader.read(1.5, 3)
    with pytest.raises(ValueError, match=r"`chunk_frames` must be a whole number >= 1; got 0"):
        reader.sample_range(0)


def test_the_sample_range_is_taken_on_the_input_the_method_gets(mux_path):
    # A method that reconstructs multiplexed frames from their forward model gets them as captured: the
    # range it scales by (and the batch hands every chunk) is theirs, not the demultiplexed capture's.
    from flexvox_core.methods import Method

    reader = open_capture(mux_path)
    method = Method("diffusion")
    assert reader.takes_multiplexed(method)
    frames, _ = reader.input(method)
    assert reader.sample_range(2, method) == (float(frames.min()), float(frames.max()))
    demux = reader.read()
    assert reader.sample_range(2) == (float(demux.min()), float(demux.max()))


def test_the_deprecated_takes_raw_warns_and_answers_as_takes_multiplexed(mux_path):
    reader = open_capture(mux_path)
    with pytest.warns(DeprecationWarning, match=r"CaptureReader\.takes_raw is deprecated .* "
                                                r"CaptureReader\.takes_multiplexed\(method\)"):
        assert reader.takes_raw(Method("gap-tv")) is reader.takes_multiplexed(Method("gap-tv")) is True
    assert not reader.takes_multiplexed(Method("rebin"))


def test_frames_in_a_recording_s_place_are_refused_naming_what_to_give(counts_path, tmp_path):
    # pathlib had raised "expected str, bytes or os.PathLike object, not ndarray" (not VerifiedRows)
    from flexvox_core.batch import reconstruct_batch

    rec = open_recording(counts_path)
    frames, _ = read_capture(counts_path)
    for call in (read_capture, open_capture, open_recording,
                 lambda r: reconstruct_batch(r, tmp_path / "b.zarr", "diffusion")):
        with pytest.raises(TypeError, match=r"`recording` must be a recording's path or a Recording; got a "
                                            r"recording's frames \(rec.frames\): give the recording itself"):
            call(rec.frames)
        with pytest.raises(TypeError, match=r"`recording` must be a recording's path or a Recording; got ndarray: "
                                            r"frames in memory go to fv.reconstruct_video\(frames, code, method\)"):
            call(frames)
        with pytest.raises(TypeError, match=r"got NoneType None$"):
            call(None)
    assert not (tmp_path / "b.zarr").exists()
