"""``flexvox info`` and ``flexvox export`` (parsers built with register())."""

import json
import re

import cv2
import numpy as np
import pytest
import tifffile
import zarr

from flexvox_app.cli import batch, export, info
from flexvox_app.cli.errors import CliError, OneLineParser
from flexvox_core.methods import Method
from flexvox_core.recording import JOURNAL, RecordingWriter, open_recording, recording_attrs
from flexvox_core.video_api import reconstruct_video
from tests.killed_writer import kill


def cli(argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    for module in (info, export, batch):
        module.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


pytestmark = pytest.mark.recording(frames=5, size=(16, 24), tile=(2, 2), name="r.zarr")


def test_info_summarises_a_sound_recording(recording, capsys):
    assert cli(["info", str(recording)]) == 0
    text = capsys.readouterr().out
    assert "simulated recording, schema 2" in text and "tile 2x2, K = 4" in text
    assert "checked: metadata and every chunk" in text
    assert "frames: 5 of 16x24 float32 (float), ids 0..4" in text and text.strip().endswith("OK")
    assert cli(["info", str(recording), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["frames"] == 5 and s["ground_truth"] and s["problems"] == [] and not s["interrupted"]


def test_info_exits_1_on_damage_and_2_when_missing(recording, tmp_path, capsys):
    g = zarr.open_group(str(recording), mode="r+")
    g["frame_id"][3] = 7  # a gap with no dropped row
    assert cli(["info", str(recording)]) == 1
    out = capsys.readouterr().out
    assert "problem: 4 frame id(s) missing without a dropped row (first after id 2)" in out
    assert "problem: frame ids do not increase at row 4 (7 then 4)" in out and out.strip().endswith("DAMAGED")
    g["timestamp"].resize((3,))
    assert cli(["info", str(recording)]) == 1
    assert "DAMAGED: " in capsys.readouterr().out
    with pytest.raises(CliError, match=r"none.zarr: no such recording"):
        cli(["info", str(tmp_path / "none.zarr")])


def test_info_checks_every_chunk_unless_quick(recording, capsys):
    (recording / "frames" / "c" / "3" / "0" / "0").unlink()
    (recording / "ground_truth" / "c" / "7" / "0" / "0").unlink()
    assert cli(["info", str(recording), "--quick"]) == 0  # metadata only: it cannot see the chunks
    assert "checked: metadata\n" in capsys.readouterr().out
    assert cli(["info", str(recording)]) == 1
    out = capsys.readouterr().out
    assert "problem: frames row 3: its chunk file is missing" in out
    assert "problem: ground truth row 7: its chunk file is missing" in out and out.strip().endswith("DAMAGED")
    assert cli(["info", str(recording), "--json"]) == 1
    s = json.loads(capsys.readouterr().out)
    assert s["checksums"] and s["problems"] == ["frames row 3: its chunk file is missing",
                                                "ground truth row 7: its chunk file is missing"]


def test_info_reports_and_repairs_an_interrupted_capture(tmp_path, capsys):
    attrs = recording_attrs(np.eye(4, dtype=bool).reshape(2, 2, 4), rate_hz=30.0, kind="captured",
                            storage={"kind": "float"})
    w = RecordingWriter(tmp_path / "i.zarr", height=8, width=8, dtype="float32", attrs=attrs)
    for i in range(3):
        w.append(np.ones((8, 8), np.float32), frame_id=i, timestamp=i / 30)
    assert cli(["info", str(tmp_path / "i.zarr")]) == 0
    assert re.search(r"being written now by process \d+ \(.*\): the frames committed so far are readable",
                     capsys.readouterr().out)  # a capture in progress, not an interrupted one
    with pytest.raises(CliError, match=r"--repair: .*i.zarr is being written by process \d+"):
        cli(["info", "--repair", str(tmp_path / "i.zarr")])  # never finalised under a running writer
    kill(w)
    (tmp_path / ".i.replaced-123-abcdef.zarr").mkdir()  # what a killed overwriting capture leaves beside it
    assert cli(["info", str(tmp_path / "i.zarr")]) == 0
    out = capsys.readouterr().out
    assert "interrupted: the capture did not finish" in out
    assert "note: .i.replaced-123-abcdef.zarr beside it is the recording an overwriting capture moved aside" in out
    assert cli(["info", "--repair", str(tmp_path / "i.zarr")]) == 0
    assert "finalised, 3 frames" in capsys.readouterr().out
    assert not (tmp_path / "i.zarr" / JOURNAL).exists() and not open_recording(tmp_path / "i.zarr").interrupted


def test_info_repair_of_a_recording_that_needs_nothing_says_so_and_changes_nothing(recording, capsys):
    before = {p.relative_to(recording): (p.read_bytes(), p.stat().st_mtime_ns) for p in recording.rglob("*")
              if p.is_file()}
    assert cli(["info", "--repair", str(recording)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{recording}: nothing to repair: a finished recording of 5 frames; nothing was changed\n")
    assert "finalised" not in out and out.strip().endswith("OK")
    after = {p.relative_to(recording): (p.read_bytes(), p.stat().st_mtime_ns) for p in recording.rglob("*")
             if p.is_file()}
    assert after == before


def test_export_frames_to_every_format(recording, tmp_path, capsys):
    rec = open_recording(recording)
    frames = rec.frames[:]
    assert cli(["export", str(recording), "-o", str(tmp_path / "f.tif")]) == 0
    with tifffile.TiffFile(tmp_path / "f.tif") as tif:
        assert tif.is_imagej and tif.imagej_metadata["frames"] == 5
        np.testing.assert_array_equal(tif.asarray(), frames)
    assert cli(["export", str(recording), "-o", str(tmp_path / "f.npy")]) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "f.npy"), frames)
    assert cli(["export", str(recording), "-o", str(tmp_path / "png")]) == 0
    pngs = sorted((tmp_path / "png").glob("frame_*.png"))
    assert len(pngs) == 5
    img = cv2.imread(str(pngs[2]), cv2.IMREAD_UNCHANGED)
    assert img.dtype == np.uint16 and np.abs(img / 65535 - np.clip(frames[2], 0, 1)).max() < 1e-4
    assert cli(["export", str(recording), "-o", str(tmp_path / "f.mp4")]) == 0
    cap = cv2.VideoCapture(str(tmp_path / "f.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 5
    cap.release()
    assert "wrote frames (5 x 16x24 float32)" in capsys.readouterr().out


def test_export_ground_truth_and_reconstruction(recording, tmp_path):
    rec = open_recording(recording)
    assert cli(["export", str(recording), "--what", "ground-truth", "-o", str(tmp_path / "g.tif")]) == 0
    np.testing.assert_array_equal(tifffile.imread(tmp_path / "g.tif"), rec.ground_truth[:])
    assert cli(["export", str(recording), "--what", "reconstruction", "--method", "rebin",
                "-o", str(tmp_path / "r.npy")]) == 0
    expected = reconstruct_video(rec.normalised_frames(), rec.code, Method("rebin"))
    np.testing.assert_allclose(np.load(tmp_path / "r.npy"), expected, atol=1e-6)


def test_export_refuses_bad_requests(recording, tmp_path):
    with pytest.raises(CliError, match=r"the output must end in .tif, .tiff, .npy, .mp4 or .zarr"):
        cli(["export", str(recording), "-o", str(tmp_path / "x.gif")])
    (tmp_path / "x.npy").write_bytes(b"")
    with pytest.raises(CliError, match=r"already exists; use --overwrite to replace it"):
        cli(["export", str(recording), "-o", str(tmp_path / "x.npy")])
    attrs = recording_attrs(np.eye(4, dtype=bool).reshape(2, 2, 4), rate_hz=30.0, kind="captured",
                            storage={"kind": "float"})
    with RecordingWriter(tmp_path / "c.zarr", height=8, width=8, dtype="float32", attrs=attrs) as w:
        w.append(np.ones((8, 8), np.float32), frame_id=0, timestamp=0.0)
    with pytest.raises(CliError, match=r"holds no ground truth"):
        cli(["export", str(tmp_path / "c.zarr"), "--what", "ground-truth", "-o", str(tmp_path / "g.npy")])


def test_batch_cli_equals_reconstruct(recording, tmp_path, capsys):
    assert cli(["batch", str(recording), "-o", str(tmp_path / "b.zarr"), "--chunk", "2"]) == 0
    assert "on local threads (chunks of 4 frames, overlap 4)" in capsys.readouterr().out  # raised to the overlap
    rec = open_recording(recording)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, Method(), chunk_frames=None)
    np.testing.assert_allclose(zarr.open_group(str(tmp_path / "b.zarr"))["video"][:], expected, atol=1e-5)
    with pytest.raises(CliError, match=r"the batch output must be a .zarr store"):
        cli(["batch", str(recording), "-o", str(tmp_path / "b.npy")])


def test_batch_cli_motion_aware_options(recording, tmp_path, capsys):
    assert cli(["batch", str(recording), "-o", str(tmp_path / "m.zarr"), "--method", "motion-aware",
                "--flow", "farneback", "--slow-reach", "0"]) == 0
    rec = open_recording(recording)
    method = Method("motion-aware", flow="farneback", slow_reach=0.0)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, method, chunk_frames=None)
    np.testing.assert_array_equal(zarr.open_group(str(tmp_path / "m.zarr"))["video"][:], expected)
    with pytest.raises(CliError, match=r"--passes, --refine, --slow-reach, --no-local-choice and --no-noise-aware "
                                       r"go with --method motion-aware"):
        cli(["export", str(recording), "--what", "reconstruction", "--method", "diffusion", "--refine", "1",
             "-o", str(tmp_path / "e.npy")])


@pytest.mark.parametrize("command, chunk", [("batch", 32), ("export", 16)])
def test_chunk_help_names_each_default(command, chunk, capsys):
    with pytest.raises(SystemExit):
        cli([command, "--help"])
    assert f"camera frames per chunk (default {chunk})" in " ".join(capsys.readouterr().out.split())


@pytest.mark.recording(frames=2, size=(16, 24), tile=(2, 4), name="few.zarr")
def test_info_slots_from_fewer_frames_than_k_says_what_the_figure_cannot_see(recording, capsys):
    # 2 frames of K = 8: the single-slot fit, whose line says the projector's spilled light reads as wrong slots
    assert cli(["info", str(recording), "--slots", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)["slots"]
    assert s["single_slot_fit"] is True
    assert re.search(r"read from 2 frame\(s\), fewer than K = 8, .*: record 17 frames of the strobe scene$",
                     s["message"])


@pytest.mark.parametrize("key", ["calibration", "rig", "capture"])
def test_info_names_an_attribute_edited_into_something_that_is_no_object(recording, capsys, key):
    root = recording / "zarr.json"
    meta = json.loads(root.read_text())
    meta["attributes"]["flexvox"][key] = "cal.json"
    root.write_text(json.dumps(meta))
    assert cli(["info", str(recording)]) == 1
    out = capsys.readouterr().out
    assert f"problem: the `{key}` attribute must be an object; got 'cal.json' (the attributes were edited or " \
           "damaged)" in out and out.strip().endswith("DAMAGED")
