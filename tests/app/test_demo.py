import pytest

from flexvox_app.cli.main import main


@pytest.mark.slow_sim  # a minute or two on a busy 2-core machine; make docs-check runs `flexvox demo --quick` too
def test_quick_demo_writes_the_report(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "motion-aware" in text and "GAP-TV" in text and "report:" in text
    assert "Calibrated the simulated rig" in text and "phase" in text
    assert "through the capture service" in text and "0 dropped" in text
    # the operator's path: calibrate, check the shutter with a strobe, record through the calibration
    assert "100.0% right with the calibration, 0.0% with the raw phase" in text
    assert "Shutter check" in (out / "index.html").read_text()
    page = (out / "index.html").read_text()
    for name in ("fig1_sampling", "fig3_rebinning", "fig4_continuum", "fig5_flow", "fig7_panel"):
        assert (out / "figures" / f"{name}.png").stat().st_size > 5_000
        assert f"figures/{name}.png" in page
    for name in ("ground_truth", "captured", "high_sr", "high_tr", "motion_aware"):
        assert (out / "videos" / f"{name}.mp4").stat().st_size > 1_000
    assert (out / "bench" / "pareto.png").exists() and "What accuracy costs in time" in page
    assert (out / "recording.zarr").is_dir()
    assert "homography error over the frame" in page and "shutter slot accuracy" in page
    assert main(["demo", "--quick", "--out", str(out)]) == 2  # refused at once: an earlier report is there
    assert "already holds a demo report; use --overwrite" in capsys.readouterr().err
    assert (out / "index.html").read_text() == page


def test_demo_rejects_unknown_scene(tmp_path, capsys):
    assert main(["demo", "--quick", "--scene", "nope", "--out", str(tmp_path)]) == 2
    assert "unknown scene 'nope'" in capsys.readouterr().err


def test_an_interrupted_demo_leaves_nothing_half_written(tmp_path, capsys, monkeypatch):
    import flexvox_app.demo.run as demo_run

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(demo_run, "_capture", interrupted)  # Ctrl-C during the capture: figures half done
    out = tmp_path / "d"
    assert main(["demo", "--quick", "--out", str(out)]) == 130
    assert "interrupted; no output was replaced" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no d/, no hidden partial report, no lock file


def test_a_report_folder_is_replaced_only_with_overwrite_and_only_when_it_holds_a_report(tmp_path, capsys):
    half = tmp_path / "d"
    (half / "figures").mkdir(parents=True)  # what an interrupted run of an older flexvox left
    assert main(["demo", "--quick", "--out", str(half)]) == 2
    assert "already holds part of a demo report; use --overwrite" in capsys.readouterr().err
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    assert main(["demo", "--quick", "--out", str(mine), "--overwrite"]) == 2
    assert "holds other things than a demo report (notes.txt); --out another folder" in capsys.readouterr().err
    assert (mine / "notes.txt").read_text() == "keep me"
