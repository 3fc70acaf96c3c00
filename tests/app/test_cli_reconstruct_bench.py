import json

import numpy as np
import pytest
import tifffile
import zarr

from flexvox_app.cli.main import main
from flexvox_core.metrics import psnr
from flexvox_core.recording import open_recording

pytestmark = pytest.mark.recording(frames=3, size=(24, 32), tile=(4, 4), name="r.zarr")


@pytest.mark.parametrize("suffix", [".npy", ".tif", ".mp4", ".zarr", ".NPY", ".TIF", ".ZARR"])
def test_reconstruct_writes_every_format(recording, tmp_path, capsys, suffix):
    out = tmp_path / f"out{suffix}"
    assert main(["reconstruct", str(recording), "--method", "diffusion", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "PSNR vs ground truth" in text and out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["r.zarr", out.name])  # no temporary left behind
    suffix = suffix.lower()
    if suffix == ".npy":
        video = np.load(out)
    elif suffix == ".tif":
        video = tifffile.imread(out)
    elif suffix == ".zarr":
        video = zarr.open_group(str(out), mode="r")["video"][:]
    else:
        return
    assert video.shape == (48, 24, 32) and video.dtype == np.float32
    assert 0 <= video.min() and video.max() <= 1
    assert psnr(open_recording(recording).ground_truth[:], video) > 15


def test_the_voxel_rate_keeps_two_figures_below_ten_million_a_second():
    from flexvox_app.cli.reconstruct import voxel_rate

    # a small recording's 36864 voxels in 1.3 s had read "(0 M voxels/s)"
    assert voxel_rate(36864, 1.3) == "0.028 M voxels/s"
    assert voxel_rate(7_370_000, 1.0) == "7.4 M voxels/s"
    assert voxel_rate(73_700_000, 1.0) == "74 M voxels/s"
    assert voxel_rate(10, 0.0) == "10000 M voxels/s"  # a run too fast for the clock: 1 ns


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--method", "rebin", "--block", "3,1,5"], "division 3x1x5 does not divide a 4x4 tile"),
        (["--method", "rebin", "--block", "2,2"], "--block must be three whole numbers a,b,c (rows, columns, slots "
                                                  "of the division), e.g. 2,2,4; got '2,2'"),
        (["--tensor", "1,1"], "--tensor must be three numbers"),
        (["--time", "-1"], "--time must be a finite number > 0; got -1"),  # the flag, not `time`
        (["--time", "0"], "--time must be a finite number > 0; got 0"),
        (["--method", "motion-aware", "--refine", "-1"], "--refine must be a number from 0"),  # not `refine_time`
        # a near-miss method name: refused with the name meant, in the command line's words
        (["--method", "motion_aware"], "--method must be one of rebin, diffusion, gap-tv, motion-aware; got "
                                       "'motion_aware': write it motion-aware"),
        (["--method", "nc"], "got 'nc': nc is a solver of the diffusion method: --method diffusion --solver nc (its "
                             "default)"),
        (["--method", "gaptv"], "got 'gaptv': did you mean gap-tv?"),
    ],
)
def test_reconstruct_bad_options(recording, tmp_path, capsys, argv, message):
    try:
        code = main(["reconstruct", str(recording), "-o", str(tmp_path / "o.npy"), *argv])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_reconstruct_refuses_bad_outputs_and_recordings(recording, tmp_path, capsys):
    assert main(["reconstruct", str(recording), "-o", str(tmp_path / "o.gif")]) == 2
    assert "the output must end in" in capsys.readouterr().err
    assert main(["reconstruct", str(tmp_path / "none.zarr"), "-o", str(tmp_path / "o.npy")]) == 2
    assert "no such recording" in capsys.readouterr().err


@pytest.mark.slow_sim  # 3 min on a busy 2-core machine (every method across a gap); tests/flexvox_core cover the bridge
def test_reconstruct_bridges_dropped_frames_and_says_which(tmp_path, capsys):
    import zarr

    from flexvox_core.gaps import find_gaps
    from flexvox_core.recording import open_recording

    path = tmp_path / "d.zarr"
    main(["simulate", "static", "--size", "16x16", "--frames", "8", "--effects", "dropped_frames.probability=0.3",
          "-o", str(path)])
    dropped = open_recording(path).per_frame("dropped")
    assert dropped.any() and not dropped.all()
    capsys.readouterr()
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "o.zarr")]) == 0
    out = capsys.readouterr().out
    K = 16
    described = ", ".join(g.describe(K) for g in find_gaps(dropped))
    assert f"interpolated {int(dropped.sum()) * K} sub-frames across dropped frames: {described}" in out
    store = zarr.open_group(str(tmp_path / "o.zarr"), mode="r")
    np.testing.assert_array_equal(store["interpolated"][:], np.repeat(dropped, K))
    assert np.isfinite(store["video"][:]).all()
    assert main(["batch", str(path), "-o", str(tmp_path / "b.zarr"), "--chunk", "2"]) == 0
    assert described in capsys.readouterr().out
    np.testing.assert_array_equal(zarr.open_group(str(tmp_path / "b.zarr"))["video"][:], store["video"][:])
    # export keeps the same record: the line, the flags and the method
    assert main(["export", str(path), "--what", "reconstruction", "-o", str(tmp_path / "e.zarr")]) == 0
    assert described in capsys.readouterr().out
    exported = zarr.open_group(str(tmp_path / "e.zarr"), mode="r")
    np.testing.assert_array_equal(exported["interpolated"][:], np.repeat(dropped, K))
    assert exported.attrs["flexvox"]["interpolated_subframes"] == int(dropped.sum()) * K
    assert exported.attrs["flexvox"]["method"] == store.attrs["flexvox"]["method"]
    np.testing.assert_array_equal(exported["video"][:], store["video"][:])


def test_reconstruct_refuses_a_gap_longer_than_the_method_bridges(tmp_path, capsys):
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.simulator import simulate_video

    result = simulate_video(np.full((10 * 16, 8, 8), 0.5, np.float32), design_code((4, 4)).code)
    result.frames[2:7] = 0
    result.dropped[2:7] = True
    path = write_simulation(tmp_path / "d.zarr", result)
    assert main(["reconstruct", str(path), "--method", "diffusion", "-o", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err
    assert "frames 2-6 (5 frames; sub-frames 32-111) were dropped in a row; diffusion bridges gaps of at most 4" in err
    assert "At its defaults motion-aware bridges 8" in err
    assert not (tmp_path / "o.npy").exists()
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "o.npy")]) == 0  # the default, motion-aware
    assert "interpolated 80 sub-frames" in capsys.readouterr().out


def test_reconstruct_multiplexed_recording(tmp_path, capsys):
    path = tmp_path / "m.zarr"
    (tmp_path / "m.toml").write_text('[source]\nbuiltin = "static"\nheight = 15\nwidth = 20\nframes = 2\n'
                                     '[code]\ntile = "3x5"\nmultiplexed = true\n')
    assert main(["simulate", str(tmp_path / "m.toml"), "-o", str(path)]) == 0
    assert main(["reconstruct", str(path), "-o", str(tmp_path / "o.npy")]) == 0
    assert np.load(tmp_path / "o.npy").shape == (30, 15, 20)


@pytest.mark.slow_sim  # 2 min on a busy 2-core machine; make docs-check runs `flexvox bench --quick` too
def test_bench_quick_writes_table_csv_json_and_plot(tmp_path, capsys):
    assert main(["bench", "--quick", "--no-sci", "-o", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "| method | PSNR (dB) |" in out and "gap-tv" in out and "rebin" in out
    payload = json.loads((tmp_path / "b" / "results.json").read_text())
    assert payload["pareto"] and all(np.isfinite(r["psnr"]) for r in payload["summary"])
    assert (tmp_path / "b" / "pareto.png").stat().st_size > 10_000
    assert (tmp_path / "b" / "results.csv").read_text().startswith("case,K,family,method,psnr")
    before = (tmp_path / "b" / "results.csv").read_bytes()
    assert main(["bench", "--quick", "--no-sci", "-o", str(tmp_path / "b")]) == 2  # never over an earlier run
    assert "already holds results.csv, results.json, pareto.png from an earlier run; use --overwrite" in \
        capsys.readouterr().err
    assert (tmp_path / "b" / "results.csv").read_bytes() == before


def test_bench_on_a_recording_that_cannot_be_opened_leaves_no_results_folder(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("not a recording")
    for rec in (tmp_path / "none.zarr", tmp_path / "notes.txt"):
        assert main(["bench", str(rec), "-o", str(tmp_path / "b")]) == 2
        assert str(rec) in capsys.readouterr().err
        assert not (tmp_path / "b").exists()  # it had been made before the recording was opened


def test_reconstruct_motion_aware_with_figures(recording, tmp_path, capsys):
    out = tmp_path / "ma.npy"
    assert main(["reconstruct", str(recording), "--method", "motion-aware", "--flow", "farneback", "-o", str(out),
                 "--figures", str(tmp_path / "figs")]) == 0
    text = capsys.readouterr().out
    assert "motion-aware farneback" in text and "wrote 4 figures" in text
    assert np.load(out).shape == (48, 24, 32)
    for name in ("flow_color.png", "flow_quiver.png", "resolution_map.png", "panel.png"):
        assert (tmp_path / "figs" / name).stat().st_size > 500


def test_figures_need_motion_aware(recording, tmp_path, capsys):
    assert main(["reconstruct", str(recording), "--method", "diffusion", "-o", str(tmp_path / "o.npy"),
                 "--figures", str(tmp_path / "f")]) == 2
    assert "--figures goes with --method motion-aware" in capsys.readouterr().err


def test_reconstruct_motion_aware_slow_reach(recording, tmp_path, capsys):
    out = tmp_path / "ma.npy"
    assert main(["reconstruct", str(recording), "--method", "motion-aware", "--flow", "farneback",
                 "--slow-reach", "0", "-o", str(out)]) == 0
    assert "motion-aware farneback n=5 slow-reach 0" in capsys.readouterr().out
    assert np.load(out).shape == (48, 24, 32)


@pytest.mark.parametrize("args, message", [
    (["--method", "diffusion", "--slow-reach", "1"], "--slow-reach goes with --method motion-aware"),
    (["--method", "motion-aware", "--slow-reach", "-1"], "--slow-reach must be a number from 0 to 1000"),
])
def test_bad_slow_reach(recording, tmp_path, capsys, args, message):
    assert main(["reconstruct", str(recording), *args, "-o", str(tmp_path / "o.npy")]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--method", "rebin", "--time", "2"],
     "--time goes with --method diffusion or motion-aware, not rebin"),
    (["--method", "diffusion", "--iterations", "5", "--refine", "1"],
     "--iterations goes with --method gap-tv; --refine goes with --method motion-aware, not diffusion"),
    (["--method", "gap-tv", "--no-interpolate"], "--no-interpolate goes with --method rebin, not gap-tv"),
])
def test_an_option_of_another_method_is_refused_naming_its_methods(recording, tmp_path, capsys, args, message):
    assert main(["reconstruct", str(recording), *args, "-o", str(tmp_path / "o.npy")]) == 2
    assert message in capsys.readouterr().err


def test_a_registered_method_is_on_the_command_line_with_its_options(recording, tmp_path, capsys):
    from flexvox_core.capture_reader import read_capture
    from flexvox_core.methods import Method
    from flexvox_core.video_api import reconstruct_video
    from tests.flexvox_core.methods.tiny_method import frame_mean_registered

    with frame_mean_registered():
        assert main(["reconstruct", str(recording), "--method", "frame-mean", "--radius", "2", "--chunk", "1",
                     "-o", str(tmp_path / "t.npy")]) == 0
        assert "frame-mean r=2" in capsys.readouterr().out
        frames, code = read_capture(recording)
        expected = reconstruct_video(frames, code, Method("frame-mean", radius=2), chunk_frames=None)
    np.testing.assert_array_equal(np.load(tmp_path / "t.npy"), expected)
    with pytest.raises(SystemExit):  # gone with its registration
        main(["reconstruct", str(recording), "--radius", "2", "-o", str(tmp_path / "u.npy")])
    assert "unrecognized arguments: --radius 2" in capsys.readouterr().err


def test_the_refinement_help_says_its_default_in_words(capsys):
    with pytest.raises(SystemExit):
        main(["reconstruct", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default (K/16)²: 1 at K = 16, 0.25 at K = 8; 0 for none)" in text
    assert "0 for none) (default" not in text  # not a second, K-blind default after it


def test_a_damaged_ground_truth_costs_only_the_psnr(recording, tmp_path, capsys):
    """The truth is read a few sub-frames at a time after the video is written: a missing chunk gives a
    warning and no PSNR, and the reconstruction is still written."""
    chunks = sorted(p for p in (recording / "ground_truth").rglob("*") if p.is_file() and p.name != "zarr.json")
    chunks[-1].unlink()
    out = tmp_path / "out.npy"
    assert main(["reconstruct", str(recording), "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "warning: no PSNR" in captured.err and "PSNR vs ground truth" not in captured.out
    assert np.load(out).shape == (48, 24, 32)


def test_a_ground_truth_with_nan_costs_only_the_psnr(recording, tmp_path, capsys, monkeypatch):
    # A truth that reads but holds a NaN: a warning naming the sub-frames, the video written, "wrote" printed.
    from flexvox_core.recording import GroundTruthRows

    real = GroundTruthRows.__getitem__

    def with_nan(self, key):
        rows = real(self, key).copy()
        start = key.indices(self.n)[0] if isinstance(key, slice) else 0
        if isinstance(key, slice) and start <= 20 < start + len(rows):
            rows[20 - start, 0, 0] = np.nan
        return rows

    monkeypatch.setattr(GroundTruthRows, "__getitem__", with_nan)
    out = tmp_path / "out.npy"
    assert main(["reconstruct", str(recording), "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "warning: no PSNR: sub-frames 16..31: `ref` frame 4 holds NaN" in captured.err
    assert f"wrote {out}" in captured.out and np.load(out).shape == (48, 24, 32)


def test_a_failed_write_stops_the_psnr_at_its_next_block(recording, tmp_path, capsys, monkeypatch):
    # The PSNR runs beside the write; when the write fails the truth is read no further (3 blocks of 16 here).
    import threading

    import flexvox_core.video_io
    from flexvox_core.recording import GroundTruthRows

    real = GroundTruthRows.__getitem__
    reads, written = [], threading.Event()

    def counted(self, key):
        reads.append(key.indices(self.n)[0] if isinstance(key, slice) else key)
        written.wait(10)  # the first block is read while the write fails
        return real(self, key)

    def failing_write(*args, **kwargs):
        try:
            raise OSError(28, "No space left on device")
        finally:
            threading.Timer(0.05, written.set).start()

    monkeypatch.setattr(GroundTruthRows, "__getitem__", counted)
    monkeypatch.setattr(flexvox_core.video_io, "write_video", failing_write)  # `reconstruct` imports it as it runs
    out = tmp_path / "out.npy"
    assert main(["reconstruct", str(recording), "-o", str(out)]) != 0
    assert "cannot write" in capsys.readouterr().err
    assert len(reads) <= 1 and not out.exists()


@pytest.mark.parametrize(("per_frame", "words"), [
    ([20.0, 22.0], "21.00 dB"),
    ([np.inf, 20.0, 22.0], "exact on 1 of 3 sub-frames, 21.00 dB over the rest"),
    ([np.inf, np.inf], "exact on all 2 sub-frames"),
])
def test_the_psnr_line_counts_exact_sub_frames_apart_instead_of_saying_inf(per_frame, words):
    from flexvox_app.cli.reconstruct import psnr_words

    assert psnr_words(np.array(per_frame)) == words
