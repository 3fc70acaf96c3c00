"""``write_video`` refuses what is not a video in [0, 1]; ``read_video`` reads back what it wrote; a reconstructed
video given to ``open_recording`` is named for what it is."""

import numpy as np
import pytest

import flexvox_core as fv
from flexvox_core.recording import RecordingError


@pytest.mark.parametrize("suffix", [".npy", ".tif", ".zarr"])
def test_read_video_reads_back_what_write_video_wrote(tmp_path, rng, suffix):
    video = rng.random((5, 12, 16)).astype(np.float32)
    back = fv.read_video(fv.write_video(tmp_path / f"v{suffix}", video, time_step=0.01))
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, video)


def test_read_video_reads_an_mp4_as_its_8_bit_values(tmp_path):
    video = np.tile(np.linspace(0, 1, 16, dtype=np.float32), (4, 16, 1))
    back = fv.read_video(fv.write_video(tmp_path / "v.mp4", video))
    assert back.shape == video.shape and back.dtype == np.float32
    assert np.abs(back - video).mean() < 0.05  # lossy, 8-bit


def test_read_video_names_what_it_cannot_read(tmp_path):
    with pytest.raises(ValueError, match=r"cannot read .*v.avi as a video: a video ends in .npy, .tif"):
        fv.read_video(tmp_path / "v.avi")
    with pytest.raises(ValueError, match=r"v.npy: no such video"):
        fv.read_video(tmp_path / "v.npy")


def test_write_video_refuses_nan_and_values_outside_0_1(tmp_path):
    video = np.full((3, 8, 8), 0.5, np.float32)
    video[1, 2, 3] = np.nan
    with pytest.raises(ValueError, match=r"`video` frame 1 holds NaN or infinite values; a video holds finite values "
                                         r"in \[0, 1\]"):
        fv.write_video(tmp_path / "v.npy", video)
    with pytest.raises(ValueError, match=r"`video` values must lie in \[0, 1\]; got 0 to 255 \(8-bit values in a "
                                         r"float array\? divide by 255\)"):
        fv.write_video(tmp_path / "v.tif", np.linspace(0, 255, 3 * 64).reshape(3, 8, 8))
    with pytest.raises(ValueError, match=r"`video` values must lie in \[0, 1\]; got -0.5 to 0.5 \(np.clip"):
        fv.write_video(tmp_path / "v.zarr", np.linspace(-0.5, 0.5, 3 * 64).reshape(3, 8, 8))
    assert not any(tmp_path.iterdir())  # nothing written


def test_write_video_reads_an_integer_video_by_its_dtype(tmp_path):
    video = np.arange(3 * 8 * 8).reshape(3, 8, 8).astype(np.uint8)
    back = fv.read_video(fv.write_video(tmp_path / "v.npy", video))
    np.testing.assert_allclose(back, video / 255, atol=1e-7)


def test_open_recording_on_a_reconstructed_video_says_what_it_is(tmp_path):
    path = fv.write_video(tmp_path / "motion.zarr", np.zeros((2, 4, 4), np.float32))
    with pytest.raises(RecordingError, match=r"motion.zarr: a reconstructed video \(an OME-Zarr image that "
                                             r"fv.write_video.*not a recording of camera frames: read it with "
                                             r"fv.read_video\(path\), or lazily with fv.open_video_store\(path\)"):
        fv.open_recording(path)


def test_open_recording_on_a_video_file_names_read_video(tmp_path):
    path = fv.write_video(tmp_path / "v.tif", np.zeros((2, 4, 4), np.float32))
    with pytest.raises(RecordingError, match=r"v.tif: not a readable Zarr store \(it is a video file; a recording is "
                                             r"a .zarr folder: fv.read_video\(path\) reads a video\)"):
        fv.open_recording(path)


def test_open_recording_on_an_array_inside_a_recording_names_the_recording(tmp_path):
    code = fv.design_code((2, 2)).code
    rec = fv.write_simulation(tmp_path / "r.zarr", fv.simulate_video(fv.render_scene("balls", 4, 8, 8), code))
    with pytest.raises(RecordingError, match=r"r.zarr/frames: not a readable Zarr store \(it is the `frames` array "
                                             r"inside the store .*r.zarr: open .*r.zarr\)"):
        fv.open_recording(rec / "frames")


@pytest.mark.parametrize("attrs, match", [
    ({"gain": np.float32(2)},
     r"attrs\['gain'\] is a float32 \(a numpy value: give value.item\(\) or value.tolist\(\)\)"),
    ({"m": {"block": [np.int64(2)]}}, r"attrs\['m'\]\['block'\]\[0\] is a int64"),
    ({"f": object()}, r"attrs\['f'\] is a object$"),
    ({1: "a"}, r"`attrs` keys must be text; got 1 in attrs"),
    (["a"], r"`attrs` must be a dict of JSON values; got list"),
])
def test_write_video_refuses_attrs_that_are_not_json_before_it_writes(tmp_path, attrs, match):
    # a numpy scalar had failed inside the .zarr write with json's "Object of type float32 is not JSON serializable"
    for suffix in (".zarr", ".tif"):
        with pytest.raises(TypeError, match=match):
            fv.write_video(tmp_path / f"v{suffix}", np.zeros((2, 4, 4), np.float32), attrs=attrs)
        assert not (tmp_path / f"v{suffix}").exists()
    fv.write_video(tmp_path / "ok.zarr", np.zeros((2, 4, 4), np.float32), attrs={"a": [1, 2.5, None, True, "x"]})
    assert fv.open_video_store(tmp_path / "ok.zarr").attrs["a"] == [1, 2.5, None, True, "x"]
