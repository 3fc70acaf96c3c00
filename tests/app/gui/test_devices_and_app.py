"""Device panel, main window, and ``flexvox app`` started and quit."""

import argparse

import pytest

from flexvox_app.cli.errors import CliError
from flexvox_app.gui.main_window import WORKSPACES
from flexvox_app.gui.models.holder import Holder
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.device_panel import DevicePanel
from rig_drivers.errors import DevicePermissionError
from rig_drivers.interfaces import DeviceState
from rig_drivers.profile import MOCK_SPEC, ProfileRig
from rig_drivers.simulated import SimulatedProjector

from .conftest import small_rig


class LockedProjector(SimulatedProjector):
    """A projector whose USB device the user may not open (no udev rule)."""

    def _do_open(self):
        raise DevicePermissionError("permission denied on USB 0451:6401: add the udev rule (see README)")


def test_device_panel_connects_and_disconnects(qtbot):
    service = RigService(small_rig())
    panel = DevicePanel(service)
    qtbot.addWidget(panel)
    cam = service.rig.camera
    assert "closed" in panel.state_text("camera") and "(simulated)" in panel.rows["camera"]["name"].text()
    panel.rows["camera"]["button"].click()
    assert cam.state is DeviceState.ENABLED and "enabled" in panel.state_text("camera")
    assert panel.rows["camera"]["button"].text() == "Disconnect"
    panel.rows["camera"]["button"].click()
    assert cam.state is DeviceState.CLOSED and "closed" in panel.state_text("camera")
    service.close()


def test_device_panel_says_the_last_error_in_words(qtbot):
    sim = small_rig()
    rig = ProfileRig(LockedProjector(name="LightCrafter 4500"), sim.camera, None, MOCK_SPEC)
    service = RigService(rig)
    panel = DevicePanel(service)
    qtbot.addWidget(panel)
    assert not service.connect("projector")
    err = panel.rows["projector"]["error"]
    assert err.isVisibleTo(panel) and "connect failed: permission denied" in err.text() and "udev" in err.text()
    assert "closed" in panel.state_text("projector")
    assert panel.state_text("sync") == "—" and not panel.rows["sync"]["button"].isEnabled()
    assert "TRIG_OUT_2" in panel.rows["sync"]["name"].text()
    assert service.connect("camera") and not panel.rows["camera"]["error"].isVisibleTo(panel)
    service.close()


def test_led_currents_of_a_lightcrafter_from_the_device_panel(qtbot):
    from tests.rig_drivers.display_rig import display_rig

    rig = display_rig()
    fake = rig.projector._transport
    service = RigService(rig)
    panel = DevicePanel(service)
    qtbot.addWidget(panel)
    assert panel.led_box.isVisibleTo(panel) and panel.led_spins["red"].suffix() == " /255"
    panel.led_spins["green"].setValue(200)
    assert not panel.apply_led_currents()  # not connected yet: said in words
    assert "connect the projector first" in panel.rows["projector"]["error"].text()
    panel.rows["projector"]["button"].click()
    assert rig.projector.state is DeviceState.ENABLED
    assert [s.value() for s in panel.led_spins.values()] == list(fake.led_currents)  # read back at connect
    for colour, value in zip(("red", "green", "blue"), (30, 220, 128), strict=True):
        panel.led_spins[colour].setValue(value)
    panel.led_apply.click()
    assert fake.led_currents == bytes([30, 220, 128]) and not panel.rows["projector"]["error"].isVisibleTo(panel)
    service.close()
    simulated = DevicePanel(RigService(small_rig()))
    qtbot.addWidget(simulated)
    assert not simulated.led_box.isVisibleTo(simulated)  # the simulated projector has no LEDs to set
    simulated.service.close()


def test_main_window_has_the_three_workspaces_and_closes_cleanly(qtbot, settings, runner, recording):
    from flexvox_app.gui.application import build_window

    window = build_window(small_rig(), settings=settings, runner=runner, recording=recording)
    qtbot.addWidget(window)
    window.show()
    assert [window.tabs.tabText(i) for i in range(window.tabs.count())] == list(WORKSPACES)
    assert window.tabs.currentWidget() is window.review
    qtbot.waitUntil(lambda: window.review.session is not None, timeout=10_000)
    window.service.connect("camera")
    window.show_workspace("Capture")
    window.close()
    assert window.service.rig.camera.state is DeviceState.CLOSED
    assert settings.get_int("window/tab", -1) == 1 and settings.get_bytes("window/geometry") is not None
    assert settings.get_str("review/last_recording") == str(recording)


def test_a_recording_made_in_capture_opens_in_review(qtbot, settings, runner, tmp_path):
    from flexvox_app.gui.application import build_window

    window = build_window(small_rig(), settings=settings, runner=runner)
    qtbot.addWidget(window)
    window.show_workspace("Calibrate")
    assert window.calibrate.held_here() is None  # the simulated rig calibrates its own target
    assert window.calibrate.holder is Holder.IDLE and window.capture.holder is Holder.IDLE
    capture = window.capture
    capture.code.rate.setValue(60.0)
    capture.clear_calibration()  # “Record uncalibrated”
    capture.record_panel.path_edit.setText(str(tmp_path / "made-here.zarr"))
    capture.record_panel.frames_box.setValue(6)
    with qtbot.waitSignal(capture.recording_finished, timeout=20_000):
        assert capture.record()
        assert window._held_by_capture() == "a recording is running in the Capture workspace"
        assert window.calibrate.held_elsewhere() == "a recording is running in the Capture workspace"
        assert window.capture.holder is Holder.RECORDING and window.calibrate.holder is Holder.IDLE
        assert window.service.holder is Holder.IDLE  # the service holds the Calibrate workspace's users only
    capture.record_panel.review_button.click()
    assert window.tabs.currentWidget() is window.review
    qtbot.waitUntil(lambda: window.review.session is not None, timeout=10_000)
    assert window.review.session.n_frames == 6
    window.close()


APP_SCRIPT = """
import argparse, sys
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from flexvox_app.cli import app as cli_app
from flexvox_app.gui.application import ensure_application
from flexvox_app.gui.main_window import MainWindow

qapp = ensure_application()
parser = argparse.ArgumentParser()
cli_app.register(parser.add_subparsers())
args = parser.parse_args(["app", sys.argv[1], "--rig", "mock"])

def close_when_ready():
    windows = [w for w in QApplication.topLevelWidgets() if isinstance(w, MainWindow) and w.isVisible()]
    if windows and windows[0].review.session is not None:
        print("title:", windows[0].windowTitle())
        print("summary:", windows[0].review.summary_label.text())
        windows[0].close()
        qapp.quit()
    else:
        QTimer.singleShot(50, close_when_ready)

QTimer.singleShot(50, close_when_ready)
status = args.func(args)
print("status:", status)
"""


def test_flexvox_app_starts_and_quits(recording, tmp_path):
    """``flexvox app REC`` through the CLI module, in its own process (it runs and quits the event loop):
    the window opens the recording, closes, and the exit status is 0. Settings go to a temp folder."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", XDG_CONFIG_HOME=str(tmp_path), HOME=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", APP_SCRIPT, str(recording)], capture_output=True, text=True,
                         env=env, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "title: flexvox — simulated rig" in out.stdout and "6 frames of 48×32" in out.stdout
    assert "status: 0" in out.stdout
    assert list(tmp_path.rglob("flexvox.conf")), "settings were not saved where QSettings was pointed"


def test_flexvox_app_refuses_bad_arguments(tmp_path):
    from flexvox_app.cli import app as cli_app

    parser = argparse.ArgumentParser()
    cli_app.register(parser.add_subparsers())
    with pytest.raises(CliError, match="no such recording"):
        cli_app.run(parser.parse_args(["app", str(tmp_path / "none.zarr")]))
    with pytest.raises(CliError, match="none.toml"):
        cli_app.run(parser.parse_args(["app", "--rig", str(tmp_path / "none.toml")]))


def test_a_job_that_ends_after_shutdown_does_not_call_back(qtbot, runner):
    """A closing window shuts its runner down; a result still queued must not reach its deleted widgets."""
    import threading

    release = threading.Event()
    seen = []
    handle = runner.submit("slow", lambda token, progress: release.wait(5) or "late",
                           on_finished=seen.append, on_done=lambda: seen.append("done"))
    quick = runner.submit("quick", lambda token, progress: "now", on_finished=seen.append)
    qtbot.waitUntil(lambda: not quick.running, timeout=5000)
    assert seen == ["now"]
    release.set()
    assert runner.shutdown(5000)
    qtbot.waitUntil(lambda: not handle.running, timeout=5000)  # its signals were delivered ...
    assert handle.outcome == "finished" and seen == ["now"]  # ... and its callbacks dropped


def test_closing_the_window_while_review_plays_starts_no_preview_after_the_runner_shut_down(qtbot, settings, runner,
                                                                                           recording):
    """Closing during playback stops playback, and that must not schedule a preview after the runner has shut down.

    A job running at the close (the preview, the machine-speed timing) stops at its next cancel check; the first
    motion-aware run of a process loads its compiled kernels before its first check, which on a loaded machine
    takes longer than the window waits for (5 s). So the test waits for those jobs to end, with room, and checks
    that no job started after the close, rather than that they ended within the window's wait."""
    from flexvox_app.gui.application import build_window

    window = build_window(small_rig(), settings=settings, runner=runner, recording=recording)
    qtbot.addWidget(window)
    window.show()
    review = window.review
    qtbot.waitUntil(lambda: review.session is not None, timeout=60_000)
    assert review.preview_check.isChecked()
    review.play_button.click()
    assert review.playing
    qtbot.waitUntil(lambda: review.subframe > 0, timeout=60_000)  # it plays
    window.close()
    assert not review.playing and not review.preview_timer.isActive() and not review.timer.isActive()
    preview_at_close = review.preview_job
    if preview_at_close is not None and preview_at_close.running:
        assert preview_at_close.token.cancelled  # a preview still running was asked to stop
    assert review.request_preview() is None  # a late caller gets nothing scheduled
    refused = runner.submit("late", lambda token, progress: "ran")
    assert refused.outcome == "cancelled" and not refused.running
    assert runner.pool.waitForDone(120_000)  # the jobs running at the close end ...
    qtbot.waitUntil(lambda: runner.active == 0, timeout=60_000)  # ... and their last queued signals were delivered
    assert review.preview_job is preview_at_close  # no preview was started after the close


def test_a_status_line_keeps_its_height_and_cuts_a_long_text_with_the_whole_on_hover(qtbot):
    from flexvox_app.gui.widgets.rich_text import RED, coloured
    from flexvox_app.gui.widgets.status_line import StatusLine

    line = StatusLine("short", lines=2)
    qtbot.addWidget(line)
    line.resize(300, line.height())
    line.show()
    height = line.height()
    assert not line.elided and line.shown_text() == "short" and line.toolTip() == ""
    long = coloured("cannot record: " + "a long reason, " * 30, RED)
    line.setText(long)
    assert line.height() == height and line.elided and line.text() == long and line.toolTip() == long
    shown = line.shown_text()
    assert shown.endswith("…") and RED in shown  # cut to its lines, its colour kept
    assert line.heightForWidth(line.width()) <= height  # what it shows fits
    # Red only on the refusal: what comes before it keeps its own colour and bold.
    mixed = "<b>calibrated</b>: phase 6, 441 µs trigger delay · " + coloured("not loaded: " + "a reason, " * 30, RED)
    line.setText(mixed)
    shown = line.shown_text()
    assert line.elided and shown.startswith("<b>calibrated</b>: phase 6, 441 µs trigger delay · <span style='color:")
    assert RED.lower() in shown.lower() and shown.count("<span") == 1 and "not loaded: a reason" in shown
    with pytest.raises(ValueError, match="`lines` must be at least 1; got 0"):
        StatusLine(lines=0)


STARTUP_SCRIPT = """
import sys, time
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from flexvox_app.gui.application import StartupWindow, launch
from flexvox_app.gui.widgets.settings import settings_at

seen = {}

def open_the_rig():
    # what the operator sees while the rig opens: the start-up window, before any workspace was imported
    seen["startup shown"] = any(isinstance(w, StartupWindow) and w.isVisible() for w in QApplication.topLevelWidgets())
    seen["workspaces not loaded yet"] = "flexvox_app.gui.main_window" not in sys.modules
    from rig_drivers.profile import open_rig
    return open_rig("mock", scene="balls", camera_size=(48, 64), subframes=64)

def close_when_shown():  # runs from the first events on: it must not import the workspaces itself
    windows = [w for w in QApplication.topLevelWidgets() if type(w).__name__ == "MainWindow" and w.isVisible()]
    if windows:
        seen["startup gone"] = not any(isinstance(w, StartupWindow) and w.isVisible()
                                       for w in QApplication.topLevelWidgets())
        windows[0].close()
    else:
        QTimer.singleShot(20, close_when_shown)

QTimer.singleShot(0, close_when_shown)
status = launch(open_the_rig, settings=settings_at(sys.argv[1]))
print(seen, "status", status)
"""


def test_the_first_window_shows_at_once_and_the_rest_loads_behind_it(tmp_path):
    """Point 11: the start-up window shows before the rig opens and the workspaces load, and goes when they are in."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    out = subprocess.run([sys.executable, "-c", STARTUP_SCRIPT, str(tmp_path / "s.ini")], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert ("{'startup shown': True, 'workspaces not loaded yet': True, 'startup gone': True} status 0"
            in out.stdout), out.stdout + out.stderr[-2000:]


def test_the_docs_say_what_the_application_does():
    """Point 12: the README's Debian list has the libraries Qt's xcb platform needs; docs/application.md quotes the
    refinement default as the form shows it and says what a TIFF export carries (the writer's ImageJ metadata)."""
    from pathlib import Path

    from flexvox_core.methods.motion_aware_method import REFINE_SHOWN
    from flexvox_core.video_io import imagej_metadata

    root = Path(__file__).resolve().parents[3]
    readme = (root / "README.md").read_text()
    apt = readme[readme.index("sudo apt install libgl1"):].split("`")[0]
    assert {"libxcb-cursor0", "libxcb-icccm4", "libxcb-keysyms1"} <= set(apt.split())
    app_doc = " ".join((root / "docs" / "application.md").read_text().split())
    assert f'"default ({REFINE_SHOWN})"' in app_doc and "TIFF, NPY and MP4 files carry no attributes" not in app_doc
    meta = imagej_metadata(1 / 240, {"method": "m"})
    assert {"finterval", "Info"} <= set(meta) and "ImageJ Info" in app_doc and "`finterval`" in app_doc


def test_the_close_question_s_text_follows_the_recording_while_it_is_open(qtbot):
    from flexvox_app.gui.widgets.questions import question_box

    frames = [3]
    box = question_box(None, "Quit flexvox?", "3 frames", accept="Quit", update=lambda: f"{frames[0]} frames")
    qtbot.addWidget(box)
    frames[0] = 40  # the recording went on while the operator read
    qtbot.waitUntil(lambda: box.text() == "40 frames", timeout=3000)
    assert box.yes.text() == "Quit" and box.defaultButton() is not box.yes
