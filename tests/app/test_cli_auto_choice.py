"""``flexvox reconstruct --time auto`` / ``--block auto``: the knob chosen by the estimated PSNR."""

import re

import numpy as np
import pytest

import flexvox_core.accuracy as accuracy
import flexvox_core.methods as methods_pkg
from flexvox_app.cli.main import main
from flexvox_core.accuracy import refusal
from flexvox_core.capture_reader import open_capture
from flexvox_core.choice import TIMES
from flexvox_core.methods import Method


@pytest.fixture
def recording(tmp_path, capsys):
    path = tmp_path / "rec.zarr"
    assert main(["simulate", "balls", "--size", "24x32", "--frames", "3", "-o", str(path)]) == 0
    capsys.readouterr()
    return path


def test_time_auto_prints_the_choice_every_candidates_estimate_and_the_cost_and_writes_the_chosen(
        recording, tmp_path, capsys, monkeypatch):
    calls = []
    real = methods_pkg.run
    monkeypatch.setattr(methods_pkg, "run", lambda *a, **kw: calls.append(a[2]) or real(*a, **kw))
    out_path = tmp_path / "o.npy"
    assert main(["reconstruct", str(recording), "--method", "diffusion", "--time", "auto", "--estimate",
                 "-o", str(out_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    chosen = re.match(r"chose time (\S+) for diffusion by the estimated PSNR \((\d+\.\d\d) dB\)", out[0])
    assert chosen, out
    for line, t in zip(out[1:1 + len(TIMES)], TIMES, strict=True):
        assert re.fullmatch(rf"  diffusion nc \(0\.15,0\.15,1\) n={t:g}: estimated PSNR \d+\.\d\d dB \(± .*\) in "
                            r"\d+\.\d\d s", line), line
    assert re.fullmatch(r"choosing cost \d+\.\d\d s: 5 candidates x \(a reconstruction and its estimate's probe\), "
                        r"10 reconstructions in all", out[1 + len(TIMES)])
    assert out[2 + len(TIMES)].startswith(f"diffusion nc (0.15,0.15,1) n={chosen[1]}: ")
    assert "PSNR vs ground truth" in out[2 + len(TIMES)]
    assert out[3 + len(TIMES)].startswith(f"estimated PSNR {chosen[2]} dB (± ")  # the chosen one's, not made again
    assert len(calls) == 10  # the chosen reconstruction is the one made while choosing
    written = np.load(out_path)
    expected = open_capture(recording).run(Method("diffusion", time=float(chosen[1]))).video
    assert np.array_equal(written, expected)


def test_auto_for_a_method_the_estimate_refuses_names_the_method_and_why(recording, tmp_path, capsys, monkeypatch):
    why = refusal(Method("motion-aware"))
    if why is None:  # offered by the estimate: refused here by its own table, as it would be
        why = "made up here"
        monkeypatch.setitem(accuracy.REFUSED, "motion-aware", why)
    assert main(["reconstruct", str(recording), "--method", "motion-aware", "--time", "auto",
                 "-o", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err
    assert f"--time auto: cannot choose motion-aware's time by the estimated accuracy: {why}" in err
    monkeypatch.setitem(accuracy.REFUSED, "rebin", "its interval is made up here")
    assert main(["reconstruct", str(recording), "--method", "rebin", "--block", "auto",
                 "-o", str(tmp_path / "o.npy")]) == 2
    err = capsys.readouterr().err
    assert "--block auto: cannot choose rebin's block by the estimated accuracy: its interval is made up here" in err
    assert not (tmp_path / "o.npy").exists()


def test_auto_is_one_knob_of_the_method_and_of_reconstruct_only(recording, tmp_path, capsys):
    out = str(tmp_path / "o.npy")
    assert main(["reconstruct", str(recording), "--method", "diffusion", "--time", "auto", "--block", "auto",
                 "-o", out]) == 2
    assert "only one knob can be auto; got --block auto and --time auto" in capsys.readouterr().err
    assert main(["reconstruct", str(recording), "--method", "gap-tv", "--time", "auto", "-o", out]) == 2
    assert "--time goes with --method diffusion or motion-aware, not gap-tv" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["reconstruct", str(recording), "--method", "diffusion", "--tensor", "auto", "-o", out])
    assert "--tensor must be three numbers separated by commas; got 'auto'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["export", str(recording), "--what", "reconstruction", "--time", "auto", "-o", out])
    assert "--time must be a number; got 'auto'" in capsys.readouterr().err


def test_help_says_what_auto_does(capsys):
    with pytest.raises(SystemExit):
        main(["reconstruct", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--time X|auto" in text and "--block a,b,c|auto" in text
    assert ("auto (diffusion and motion-aware): try each candidate (n = 1.5, 2, 3, 4, 6 for diffusion; n = 1.5, 3, "
            "5, 8, 12 for motion-aware), estimate each") in text
    assert ("--time auto (diffusion, motion-aware) and --block auto (rebin) choose the knob by the PSNR estimated"
            in text)
