import json

import numpy as np
import pytest

from flexvox_app.cli.main import main
from flexvox_core.forward import capture
from flexvox_core.recording import open_recording


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_simulate_npy_matches_the_forward_model(capsys, tmp_path, rng):
    gt = rng.random((48, 100, 130)).astype(np.float32)
    np.save(tmp_path / "gt.npy", gt)
    code, out, err = run_cli(capsys, "simulate", str(tmp_path / "gt.npy"), "--tile", "4x4",
                             "-o", str(tmp_path / "rec.zarr"))
    assert code == 0, err
    rec = open_recording(tmp_path / "rec.zarr")
    assert rec.frames.shape == (3, 100, 130)
    assert np.max(np.abs(rec.frames[:] - capture(gt, rec.code))) <= 1e-6
    assert np.array_equal(rec.ground_truth[:], gt)
    assert "none (ideal forward model)" in out


def test_simulate_builtin_with_effect_overrides(capsys, tmp_path):
    code, out, err = run_cli(capsys, "simulate", "balls", "--size", "24x32", "--frames", "2", "--tile", "2x4",
                             "--effects", "photon_noise,read_noise.sigma=2", "-o", str(tmp_path / "b.zarr"))
    assert code == 0, err
    rec = open_recording(tmp_path / "b.zarr")
    assert rec.attrs["effects"] == {"photon_noise": {}, "read_noise": {"sigma": 2.0}}
    assert rec.n_frames == 2


def test_simulate_warns_when_trimming(capsys, tmp_path, rng):
    np.save(tmp_path / "v.npy", rng.random((20, 8, 8)).astype(np.float32))
    code, out, _ = run_cli(capsys, "simulate", str(tmp_path / "v.npy"), "--tile", "2x2", "-o", str(tmp_path / "v.zarr"))
    assert code == 0 and "warning:" not in out  # 20 is a whole number of K = 4 frames
    np.save(tmp_path / "w.npy", rng.random((19, 8, 8)).astype(np.float32))
    code, out, _ = run_cli(capsys, "simulate", str(tmp_path / "w.npy"), "--tile", "2x2", "-o", str(tmp_path / "w.zarr"))
    assert code == 0 and "19 sub-frames is not a multiple of K = 4" in out
    # In a real process (where logging reaches stderr) it is said once, not logged as well
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, "-m", "flexvox_app.cli.main", "simulate", str(tmp_path / "w.npy"),
                           "--tile", "2x2",
                           "-o", str(tmp_path / "w2.zarr")], cwd=root, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and (proc.stdout + proc.stderr).count("19 sub-frames is not a multiple") == 1


@pytest.mark.parametrize(
    "argv, message",
    [
        (["simulate", "nosuch", "-o", "x.zarr"], "is neither a scene file"),
        (["simulate", "fan", "--effects", "glitter", "-o", "x.zarr"], "unknown effect 'glitter'; effects:"),
        (["simulate", "fan", "--effects", "read_noise.sigma=-2", "-o", "x.zarr"], "read_noise.sigma must be between 0"),
        (["simulate", "fan", "--effects", "read_noise.sigma=abc", "-o", "x.zarr"], "must be a number; got 'abc'"),
        # the last had been taken without a word
        (["simulate", "fan", "--effects", "read_noise.sigma=2,read_noise.sigma=3", "-o", "x.zarr"],
         "--effects sets read_noise.sigma twice (read_noise.sigma=2 and read_noise.sigma=3): give it once"),
        (["simulate", "fan", "--size", "3x3", "-o", "x.zarr"], "--size must be HxW with H, W >= 8"),
        (["simulate", "missing.npy", "-o", "x.zarr"], "missing.npy: no such file"),
    ],
)
def test_simulate_bad_input(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse-level errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x.zarr").exists()


def test_size_with_a_video_file_is_refused_not_ignored(capsys, tmp_path):
    np.save(tmp_path / "v.npy", np.zeros((8, 16, 16), np.float32))
    code = main(["simulate", str(tmp_path / "v.npy"), "--tile", "2x2", "--size", "32x32",
                 "-o", str(tmp_path / "x.zarr")])
    err = capsys.readouterr().err
    assert code == 2 and "--size sets the size of a built-in scene; " in err and "is a video of its own size" in err
    assert not (tmp_path / "x.zarr").exists()


def test_a_1x1_tile_has_no_neighbour_gap_to_report(capsys):
    code, out, _ = run_cli(capsys, "design", "--tile", "1x1")
    assert code == 0 and "no neighbours (a 1x1 tile)" in out and "None" not in out


def test_scenes_lists_scenes_and_effects(capsys):
    code, out, _ = run_cli(capsys, "scenes", "--json")
    payload = json.loads(out)
    assert set(payload["scenes"]) == {"fan", "balls", "drummer", "pan", "static", "strobe"}
    assert payload["effects"]["read_noise"]["params"]["sigma"]["unit"] == "e- rms"
    code, out, _ = run_cli(capsys, "scenes")
    assert code == 0 and "photon_noise" in out and "electrons_per_unit" in out


def test_white_reads_a_12_bit_camera_s_counts_and_its_absence_is_warned_of(tmp_path, capsys):
    from flexvox_core.simulate.scenes import render_scene

    counts = np.round(render_scene("balls", 16, 16, 16) * 4095).astype(np.uint16)
    np.save(tmp_path / "c.npy", counts)
    assert main(["simulate", str(tmp_path / "c.npy"), "--tile", "4x4", "-o", str(tmp_path / "dim.zarr")]) == 0
    out = capsys.readouterr().out
    assert "warning: " in out and "uint16 counts none above" in out and "--white 4095" in out
    assert main(["simulate", str(tmp_path / "c.npy"), "--tile", "4x4", "--white", "4095",
                 "-o", str(tmp_path / "w.zarr")]) == 0
    assert "warning" not in capsys.readouterr().out
    truth = open_recording(tmp_path / "w.zarr").ground_truth[:]
    np.testing.assert_allclose(truth, counts / 4095, rtol=1e-6)
    assert main(["simulate", "balls", "--white", "4095", "-o", str(tmp_path / "b.zarr")]) == 2
    assert "--white is the count that stands for white in a video file of counts" in capsys.readouterr().err


def test_a_tile_or_a_code_given_over_a_scene_files_own_code_order_is_refused(capsys, tmp_path):
    scene = tmp_path / "seq.toml"
    scene.write_text('seed = 0\n[source]\nbuiltin = "balls"\nheight = 16\nwidth = 16\nframes = 2\n'
                     "[code]\norder = [[0, 1], [2, 3]]\n")
    code, out, _ = run_cli(capsys, "simulate", str(scene), "-o", str(tmp_path / "a.zarr"))
    assert code == 0 and open_recording(tmp_path / "a.zarr").attrs["order"] == [[0, 1], [2, 3]]
    assert run_cli(capsys, "design", "--tile", "2x2", "-o", str(tmp_path / "c.json"))[0] == 0
    # the same tile or another, a designed code or a code file: the file's code would be replaced without a word
    for given, flag in (("--tile 2x2", "--tile"), ("--tile 4x4", "--tile"),
                        (f"--code {tmp_path / 'c.json'}", "--code")):
        code, _, err = run_cli(capsys, "simulate", str(scene), *given.split(), "-o", str(tmp_path / "b.zarr"))
        assert code == 2 and not (tmp_path / "b.zarr").exists()
        assert (f"{given} would replace the code {scene} states in [code] order (a 2x2 tile): drop {flag} to "
                "simulate the scene's code") in err


def test_a_code_file_from_design_is_simulated_as_written(capsys, tmp_path):
    # identity: the file's order is the recording's; multiplexed: its S-matrix code, tile and placement
    for tile, extra in (("4x4", []), ("3x5", ["--multiplexed"])):
        assert run_cli(capsys, "design", "--tile", tile, *extra, "-o", str(tmp_path / f"{tile}.json"))[0] == 0
        written = json.loads((tmp_path / f"{tile}.json").read_text())
        out = tmp_path / f"{tile}.zarr"
        code, _, err = run_cli(capsys, "simulate", "balls", "--code", str(tmp_path / f"{tile}.json"), "--size",
                               "30x30", "--frames", "2", "-o", str(out))
        assert code == 0, err
        attrs = open_recording(out).attrs
        if extra:
            assert attrs["multiplexed"] and attrs["tile"] == [3, 5]
            assert attrs["placement_order"] == written["placement_order"]
        else:
            assert attrs["order"] == written["order"] and not attrs.get("multiplexed")
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "balls", "--code", str(tmp_path / "4x4.json"), "--tile", "2x2", "-o",
              str(tmp_path / "x.zarr")])
    assert exc.value.code == 2 and "argument --tile: not allowed with argument --code" in capsys.readouterr().err
    (tmp_path / "bad.json").write_text('{"order": [[0, 0], [1, 2]]}')
    code, _, err = run_cli(capsys, "simulate", "balls", "--code", str(tmp_path / "bad.json"), "-o",
                           str(tmp_path / "y.zarr"))
    assert code == 2 and str(tmp_path / "bad.json") in err and not (tmp_path / "y.zarr").exists()
