"""docs/python.md's code blocks run, in order, in one namespace, in a scratch folder (the guide cannot rot)."""

import time

import matplotlib
import pytest

from tests.docs.guide_blocks import ROOT, python_blocks, skipped

GUIDE = ROOT / "docs" / "python.md"


def test_the_guide_marks_what_a_cpu_machine_cannot_run():
    blocks = python_blocks(GUIDE)
    marked = [src.splitlines()[0] for _, src in blocks if skipped(src)]
    assert sorted(marked) == ["# needs a GPU", "# needs a cluster", "# needs a display", "# needs hardware"]
    assert len(blocks) - len(marked) >= 10


def test_every_other_block_runs_in_order(tmp_path, monkeypatch, capsys):
    matplotlib.use("Agg")  # the plot is saved to a file; no window
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__guide__"}
    t0 = time.perf_counter()
    for line, source in python_blocks(GUIDE):
        if skipped(source):
            continue
        try:
            exec(compile(source, f"{GUIDE}:{line}", "exec"), namespace)  # noqa: S102 - the guide's own code
        except Exception as exc:
            pytest.fail(f"docs/python.md block at line {line} failed: {type(exc).__name__}: {exc}")
    seconds = time.perf_counter() - t0
    out = capsys.readouterr().out
    # What the blocks promise, checked on what they made.
    assert (tmp_path / "psnr.png").stat().st_size > 1000
    for store in ("motion.zarr", "sim.zarr", "capture.zarr", "calibrated.zarr", "batch.zarr", "cal.json"):
        assert (tmp_path / store).exists(), store
    assert "2x2x4 [TR 4, SR 1/4]" in out and "PSNR of the calibrated capture" in out
    ns = namespace
    assert ns["result"].ok and ns["cal"].calibrated and ns["rec"].calibration["calibrated"]
    assert 0.0 <= ns["motion"].min() and ns["motion"].max() <= 1.0
    assert ns["fv"].psnr(ns["video"], ns["motion"]) > 15
    print(f"guide blocks: {seconds:.1f} s")
