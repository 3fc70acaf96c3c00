"""Camera frames exported in [0, 1] (.mp4, .zarr, PNG): a multiplexed code's frames divided by its open slots, what
is clipped said; an .mp4 refused at a size OpenCV's writer cannot keep, before any reconstruction."""

import numpy as np
import pytest

from flexvox_app.cli import export, reconstruct, simulate
from flexvox_app.cli.errors import CliError, OneLineParser
from flexvox_core.video_io import read_video, write_video


def cli(argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    for module in (export, simulate, reconstruct):
        module.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


def scene_file(tmp_path, *, size=(30, 30), multiplexed=False, effects=""):
    path = tmp_path / "scene.toml"
    path.write_text(f'seed = 0\n[source]\nbuiltin = "balls"\nheight = {size[0]}\nwidth = {size[1]}\nframes = 3\n'
                    f'[code]\ntile = "3x5"\nmultiplexed = {str(multiplexed).lower()}\n{effects}')
    return path


def test_multiplexed_frames_are_divided_by_their_open_slots_not_clipped_white(tmp_path, capsys):
    rec = tmp_path / "mx.zarr"
    cli(["simulate", str(scene_file(tmp_path, multiplexed=True)), "-o", str(rec)])
    cli(["export", str(rec), "-o", str(tmp_path / "f.npy")])
    cli(["export", str(rec), "-o", str(tmp_path / "f.zarr")])
    raw = np.load(tmp_path / "f.npy")
    unit = read_video(tmp_path / "f.zarr")
    assert raw.max() > 1  # each frame sums 8 of the 15 slots
    np.testing.assert_allclose(unit, raw / 8, rtol=1e-6)  # (K + 1) / 2 = 8 open slots a pixel
    assert (unit == 1).mean() < 0.01
    assert "outside [0, 1]" not in capsys.readouterr().err


def test_frames_clipped_by_the_unit_range_are_said_with_their_share(tmp_path, capsys):
    rec = tmp_path / "amb.zarr"
    cli(["simulate", str(scene_file(tmp_path)), "-o", str(rec), "--effects", "ambient"])
    cli(["export", str(rec), "-o", str(tmp_path / "f.npy")])
    raw = np.load(tmp_path / "f.npy")
    raw_over = np.mean((raw < 0) | (raw > 1))
    assert raw_over > 0  # the ambient light lifts some values above 1
    capsys.readouterr()
    cli(["export", str(rec), "-o", str(tmp_path / "f.zarr")])
    err = capsys.readouterr().err
    assert f"warning: {raw_over:.2%} of the values lay outside [0, 1]" in err and "f.zarr" in err
    assert ".tif and .npy keep them" in err


@pytest.mark.parametrize(("size", "rule"), [
    ((5, 4), r"even and of at least 16 px"),
    ((31, 32), r"even \(OpenCV.s writer would drop the odd row or column\)"),
    ((8, 20), r"of at least 16 px"),
])
def test_write_video_refuses_an_mp4_its_writer_would_crop_or_crash_on(tmp_path, size, rule):
    out = tmp_path / "v.mp4"
    with pytest.raises(ValueError, match=rf"cannot write .*v\.mp4: an \.mp4 .* needs a height and width {rule}; "
                                         rf"the frames are {size[0]}x{size[1]}: write \.tif, \.npy or \.zarr"):
        write_video(out, np.full((3, *size), 0.5, np.float32))
    assert list(tmp_path.iterdir()) == []  # nothing written, no temporary left


def test_an_mp4_of_an_even_size_keeps_its_shape(tmp_path):
    write_video(tmp_path / "v.mp4", np.full((3, 16, 18), 0.5, np.float32))
    assert read_video(tmp_path / "v.mp4").shape == (3, 16, 18)


def test_the_cli_refuses_an_odd_mp4_before_reconstructing(tmp_path, monkeypatch):
    rec = tmp_path / "odd.zarr"
    cli(["simulate", str(scene_file(tmp_path, size=(31, 30))), "-o", str(rec)])

    def never(*a, **k):
        raise AssertionError("the reconstruction ran before the output's size was checked")

    monkeypatch.setattr("flexvox_core.capture_reader.CaptureReader.run", never)
    for command in (["reconstruct", str(rec)], ["export", str(rec), "--what", "reconstruction"]):
        with pytest.raises(CliError, match=r"out\.mp4: an \.mp4 .* needs a height and width even .* 31x30"):
            cli([*command, "-o", str(tmp_path / "out.mp4")])
    assert not (tmp_path / "out.mp4").exists()
