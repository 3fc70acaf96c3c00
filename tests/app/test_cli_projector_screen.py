"""``--projector-screen`` and ``--list-screens`` of ``flexvox calibrate`` and ``flexvox capture`` (offscreen Qt).

A real rig here is a profile whose devices are swapped for the fake DLPC350 transport and a camera that
sees only what the projector window shows, so a calibration that finds the homography found it through
the window, with the patterns sent from the worker thread while the Qt event loop ran.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rig_drivers.profile as profile
from flexvox_app.cli.main import main
from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from tests.rig_drivers.display_rig import ScreenCamera

PROFILE = """
name = "bench rig"
[projector]
kind = "dlpc350"
[camera]
kind = "genicam"
cti = "producer.cti"
[sync]
kind = "projector-trigger"
"""


@pytest.fixture
def rig_toml(tmp_path):
    path = tmp_path / "my-rig.toml"
    path.write_text(PROFILE)
    return path


class _WindowScreen:
    def __init__(self, display):
        self.display = display

    @property
    def current(self):
        window = self.display.window
        return None if window is None else window.frames


@pytest.fixture
def fake_devices(monkeypatch):
    """open_rig builds the fake DLPC350 (with the display sink it is given) and a camera watching that display."""
    made = {}

    def projector(spec, display=None):
        lcr = DLPC350(FakeDLPC350Transport(), poll_interval_s=0, display=display)
        lcr.size = (48, 64)
        made.update(projector=lcr, display=display)
        return lcr

    monkeypatch.setattr(profile, "_projector", projector)
    monkeypatch.setattr(profile, "_camera",
                        lambda spec: ScreenCamera(made["projector"], _WindowScreen(made["display"])))
    return made


def _one_line_error(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err


@pytest.mark.parametrize("command", ["calibrate", "capture"])
def test_a_bad_screen_index_exits_2_with_one_line(capsys, rig_toml, command, fake_devices, tmp_path):
    _one_line_error(capsys, [command, "--rig", str(rig_toml), "--projector-screen", "7", "-o", str(tmp_path / "x")],
                    f"flexvox {command}: error: --projector-screen must be 0..0 on this desktop; got 7 (screens: 0: ")
    assert fake_devices == {}  # refused before any device was built


@pytest.mark.parametrize("command", ["calibrate", "capture"])
def test_screen_options_are_checked(capsys, rig_toml, command, tmp_path):
    out = ["-o", str(tmp_path / "x")]
    with pytest.raises(SystemExit) as info:
        main([command, "--projector-screen", "-1", *out])
    assert info.value.code == 2
    assert "--projector-screen must be a screen index, a whole number >= 0" in capsys.readouterr().err
    _one_line_error(capsys, [command, "--rig", "mock", "--projector-screen", "0", *out],
                    "--projector-screen is for a projector driven through its video input (a DLPC350); the "
                    "simulated rig (--rig mock) needs none")
    _one_line_error(capsys, [command, "--rig", str(rig_toml), *out],
                    "the DLP LightCrafter 4500 takes its patterns on its video input: give --projector-screen N")


def test_list_screens(capsys):
    from PySide6.QtGui import QGuiApplication

    assert main(["calibrate", "--list-screens"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(QGuiApplication.screens()) and lines[0].startswith("0: ")
    assert main(["capture", "--list-screens"]) == 0  # no -o needed to list
    assert capsys.readouterr().out.splitlines() == lines


def test_no_display_is_a_clear_error(rig_toml):
    env = {k: v for k, v in os.environ.items() if k not in ("QT_QPA_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")}
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-m", "flexvox_app.cli.main", "calibrate", "--rig", str(rig_toml),
                          "--projector-screen", "0"], capture_output=True, text=True, env=env, cwd=root, timeout=60)
    assert out.returncode == 2
    assert out.stderr == ("flexvox calibrate: error: no display: --projector-screen needs a desktop session with the "
                          "projector connected as a screen; no display to open the window on (DISPLAY is not set); "
                          "run it in a desktop session, under a virtual screen (`xvfb-run flexvox app`), or with "
                          "QT_QPA_PLATFORM=offscreen (nothing is shown)\n")


def test_no_screens_is_a_clear_error(capsys, monkeypatch, rig_toml):
    monkeypatch.setattr("PySide6.QtGui.QGuiApplication.screens", staticmethod(lambda: []))
    _one_line_error(capsys, ["calibrate", "--rig", str(rig_toml), "--projector-screen", "0"],
                    "no screens: Qt's platform 'offscreen' reports none; connect the projector's HDMI input as a "
                    "screen")


def test_calibrate_on_a_real_rig_shows_its_patterns_on_the_chosen_screen(capsys, rig_toml, fake_devices):
    code = main(["calibrate", "--rig", str(rig_toml), "--projector-screen", "0", "--tile", "2x2", "--json"])
    out, err = capsys.readouterr()
    assert out.strip(), (code, err)  # a refusal prints no report: say why
    report = json.loads(out)
    assert code == (0 if report["success"] else 1)
    assert report["steps"]["homography"]["status"] == "ok" and report["rms_px"] < 0.3 and report["coverage"] > 0.99
    assert report["shutter_slot_accuracy"] > 0.99
    display = fake_devices["display"]
    assert display.frames_shown >= 40  # every pattern went through the window on screen 0
    assert display.window is None  # closed at the end
    assert fake_devices["projector"].state.value == "closed"
    assert np.isfinite(report["seconds"])
