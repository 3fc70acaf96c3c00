"""``flexvox export`` of a reconstructed video's store, and the command line's words for the core's Python calls."""

import numpy as np
import pytest
import tifffile

from flexvox_app.cli import export, info
from flexvox_app.cli.errors import CliError, OneLineParser, in_cli_words
from flexvox_core.video_io import open_video_store, read_video, write_video


def cli(argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    for module in (info, export):
        module.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


@pytest.fixture
def video_store(tmp_path):
    video = np.random.default_rng(3).random((6, 10, 14)).astype(np.float32)
    interpolated = np.array([0, 0, 1, 1, 0, 0], bool)
    path = write_video(tmp_path / "v.zarr", video, attrs={"method": {"name": "rebin"}}, time_step=0.004,
                       interpolated=interpolated)
    return path, video, interpolated


def test_a_reconstructed_video_exports_as_it_is(video_store, tmp_path, capsys):
    path, video, interpolated = video_store
    assert cli(["export", str(path), "-o", str(tmp_path / "o.tif")]) == 0
    with tifffile.TiffFile(tmp_path / "o.tif") as tif:
        np.testing.assert_array_equal(tif.asarray(), video)
        assert tif.imagej_metadata["finterval"] == pytest.approx(0.004)
    assert cli(["export", str(path), "--what", "reconstruction", "-o", str(tmp_path / "o.npy")]) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "o.npy"), video)
    assert cli(["export", str(path), "-o", str(tmp_path / "o.zarr")]) == 0
    again = open_video_store(tmp_path / "o.zarr")
    np.testing.assert_array_equal(read_video(tmp_path / "o.zarr"), video)
    assert again.time_step == pytest.approx(0.004) and again.attrs["method"] == {"name": "rebin"}
    assert again.attrs["exported_from"] == str(path)
    import zarr

    np.testing.assert_array_equal(zarr.open_group(str(tmp_path / "o.zarr"), mode="r")["interpolated"][:],
                                  interpolated)
    assert "wrote reconstruction (6 x 10x14 float32)" in capsys.readouterr().out


def test_a_reconstructed_video_refuses_what_does_not_apply(video_store, tmp_path):
    path, _, _ = video_store
    with pytest.raises(CliError, match=r"v.zarr is a reconstructed video: it holds no ground truth, only its video; "
                                       r"export it without --what"):
        cli(["export", str(path), "--what", "ground-truth", "-o", str(tmp_path / "o.npy")])
    with pytest.raises(CliError, match=r"--method does not apply: .*v.zarr is a reconstructed video, exported as it "
                                       r"is; to reconstruct again with other options, give the recording"):
        cli(["export", str(path), "--method", "rebin", "-o", str(tmp_path / "o.npy")])
    with pytest.raises(CliError, match=r"--device does not apply"):
        cli(["export", str(path), "--device", "cpu", "-o", str(tmp_path / "o.npy")])
    with pytest.raises(CliError, match=r"an output never replaces its input"):
        cli(["export", str(path), "-o", str(path), "--overwrite"])
    assert not (tmp_path / "o.npy").exists()


def test_the_command_line_names_its_own_ways_not_python_calls(video_store, tmp_path):
    path, _, _ = video_store
    with pytest.raises(CliError, match=r"not a recording of camera frames: flexvox export writes it to TIFF, MP4, "
                                       r"PNG or .npy; napari and Fiji open it") as info_error:
        cli(["info", str(path)])
    np.save(tmp_path / "frames.npy", np.zeros((2, 4, 4), np.float32))
    with pytest.raises(CliError, match=r"it is a video file; a recording is a .zarr folder, as flexvox simulate and "
                                       r"flexvox capture write it") as file_error:
        cli(["export", str(tmp_path / "frames.npy"), "-o", str(tmp_path / "o.mp4")])
    assert "fv." not in str(info_error.value) and "fv." not in str(file_error.value)
    said = in_cli_words("x: a reconstructed video: read it with fv.read_video(path), or lazily with "
                        "fv.open_video_store(path)")
    assert said == "x: a reconstructed video: flexvox export writes it to TIFF, MP4, PNG or .npy"
    assert str(CliError("a recording is a .zarr folder: fv.read_video(path) reads a video")) == (
        "a recording is a .zarr folder, as flexvox simulate and flexvox capture write it")
