"""The ``flexvox`` console script: the command, then a quick exit that loses nothing."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import zarr

import flexvox_app.cli.main as cli_main

ROOT = Path(__file__).resolve().parents[2]


def test_the_console_script_collects_then_freezes_only_after_the_command(monkeypatch):
    calls = []
    monkeypatch.setattr(cli_main, "main", lambda: calls.append("main") or 3)
    # Only the console script's own view of the collector is replaced: the GUI's collector timer, which may fire
    # while pytest-qt processes events at teardown, keeps the real gc.collect (it failed there on 3.13 in CI).
    fake = SimpleNamespace(collect=lambda: calls.append("collect"), freeze=lambda: calls.append("freeze"))
    monkeypatch.setattr(cli_main, "gc", fake)
    assert cli_main.console() == 3
    assert calls == ["main", "collect", "freeze"]


def test_main_itself_leaves_the_collector_alone(capsys):
    before = gc.get_freeze_count()
    assert cli_main.main(["scenes"]) == 0
    assert gc.get_freeze_count() == before
    assert "balls" in capsys.readouterr().out


def test_version_prints_the_installed_version_and_exits_zero(capsys):
    from flexvox_core import __version__

    parser = cli_main.build_parser()
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--version"])
    assert stop.value.code in (0, None)
    assert capsys.readouterr().out == f"flexvox {__version__}\n"
    assert "--version" in parser.format_help() and "show program's version number and exit" in parser.format_help()


def test_the_installed_script_is_the_console_entry():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["flexvox"] == "flexvox_app.cli.main:console"


def test_a_reconstruction_through_the_console_entry_is_complete(tmp_path):
    """Simulate and reconstruct in real processes (``python -m flexvox_app.cli.main``: the console entry): every line
    is printed and the output is whole; and what the quick exit must keep, it keeps."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    rec, out = tmp_path / "r.zarr", tmp_path / "o.zarr"

    def run(*args):
        return subprocess.run([sys.executable, "-m", "flexvox_app.cli.main", *map(str, args)], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=300)

    assert run("simulate", "balls", "--size", "24x32", "--frames", "3", "-o", rec).returncode == 0
    proc = run("reconstruct", rec, "--method", "diffusion", "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == f"wrote {out}"
    assert "PSNR vs ground truth" in proc.stdout
    video = zarr.open_group(str(out), mode="r")["video"][:]
    assert video.shape == (48, 24, 32) and np.isfinite(video).all()
    # In a real process: the collector is frozen at exit, atexit handlers still run, and an object the command
    # left in a reference cycle is still finalized (its __del__ writes a file).
    code = ("import atexit, gc, sys\nimport flexvox_app.cli.main as m\n"
            "class Canary:\n"
            f"    def __del__(self): open({str(tmp_path / 'finalized')!r}, 'w').write('yes')\n"
            "def command():\n"
            "    c = Canary(); c.me = c\n"  # a cycle: only a collection frees it
            "    return 0\n"
            "m.main = command\n"
            f"atexit.register(lambda: open({str(tmp_path / 'atexit')!r}, 'w').write(str(gc.get_freeze_count())))\n"
            "sys.exit(m.console())")
    assert subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True).returncode == 0
    assert int((tmp_path / "atexit").read_text()) > 0
    assert (tmp_path / "finalized").read_text() == "yes"
