"""``flexvox reconstruct --estimate`` and ``flexvox bench REC``: the accuracy estimate on the command line."""

import json
import re

import pytest

from flexvox_app.cli.main import main


@pytest.fixture
def recording(tmp_path, capsys):
    path = tmp_path / "rec.zarr"
    assert main(["simulate", "balls", "--size", "24x32", "--frames", "3", "-o", str(path)]) == 0
    capsys.readouterr()
    return path


def test_reconstruct_prints_the_estimate_beside_the_true_psnr(recording, tmp_path, capsys):
    assert main(["reconstruct", str(recording), "--method", "diffusion", "--estimate",
                 "-o", str(tmp_path / "o.npy")]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^estimated PSNR \d+\.\d\d dB \(± \d+\.\d\d dB, 95% interval", out, re.M), out
    assert "PSNR vs ground truth" in out
    # beside the estimate, the truth it estimates: the PSNR of the clip's MSE (not the frames' mean)
    clip = re.search(r"\(of the clip's MSE, as estimated: (\d+\.\d\d) dB\)", out)
    assert clip, out
    import numpy as np

    from flexvox_core.metrics import clip_psnr
    from flexvox_core.recording import open_recording

    video = np.load(tmp_path / "o.npy")
    assert float(clip.group(1)) == pytest.approx(clip_psnr(open_recording(recording).ground_truth[:], video),
                                                 abs=0.006)


def test_reconstruct_says_why_a_method_has_no_estimate(recording, tmp_path, capsys):
    assert main(["reconstruct", str(recording), "--method", "gap-tv", "--iterations", "5", "--estimate",
                 "-o", str(tmp_path / "o.npy")]) == 0
    assert "estimated PSNR: none (cannot estimate the accuracy of gap-tv" in capsys.readouterr().out


def test_bench_on_a_recording_writes_the_estimates_and_the_truth(recording, tmp_path, capsys):
    out_dir = tmp_path / "b"
    assert main(["bench", str(recording), "--quick", "-o", str(out_dir)]) == 0
    out = capsys.readouterr().out
    assert "| method | estimated PSNR (dB) |" in out
    assert "no estimate: cannot estimate the accuracy of motion-aware" in out
    rows = json.loads((out_dir / "results.json").read_text())["rows"]
    short, *diffusion = [r for r in rows if r["family"] == "diffusion"]  # n = 0.5, 1.5, 4
    assert short["estimate"] is None and "copies" in short["why"] and short["truth"] is not None
    assert len(diffusion) == 2 and all(r["estimate"] is not None and r["truth"] is not None for r in diffusion)
    assert all(r["truth"] <= r["truth_frames_mean"] for r in diffusion)  # the clip's PSNR, the frames' mean beside
    assert all(r["low"] <= r["estimate"] <= r["high"] for r in diffusion)
    assert [r["why"] for r in rows if r["family"] == "motion-aware"][0].startswith("cannot estimate")
    assert (out_dir / "pareto.png").stat().st_size > 0 and (out_dir / "results.csv").exists()
