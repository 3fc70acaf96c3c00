"""The start that shows itself: the start-up window is painted before the slow part starts, lists each step as it
runs, and keeps painting while the rig opens (it opens off the GUI thread)."""

import os
import subprocess
import sys

SCRIPT = r"""
import sys, time
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from flexvox_app.gui.application import StartupWindow, launch
from flexvox_app.gui.widgets.settings import settings_at

seen = {"pyqtgraph before the window": "pyqtgraph" in sys.modules}
ticks = []

def startup():
    return next(w for w in QApplication.topLevelWidgets() if isinstance(w, StartupWindow))

def open_the_rig():
    w = startup()
    seen["exposed"] = w.windowHandle().isExposed()
    seen["text while the rig opens"] = w.label.text()
    seen["workspaces not loaded yet"] = "flexvox_app.gui.main_window" not in sys.modules
    QTimer.singleShot(0, w, lambda: ticks.append(time.perf_counter()))  # run by the GUI thread's event loop
    n = len(ticks)
    end = time.perf_counter() + 5
    while len(ticks) == n and time.perf_counter() < end:
        time.sleep(0.01)
    seen["the window kept running while the rig opened"] = len(ticks) > n
    from rig_drivers.profile import open_rig
    return open_rig("mock", scene="balls", camera_size=(48, 64), subframes=64)

def close_when_shown():
    windows = [w for w in QApplication.topLevelWidgets() if type(w).__name__ == "MainWindow" and w.isVisible()]
    if windows:
        seen["steps done"] = [step for step, _ in startup().done]
        windows[0].close()
    else:
        QTimer.singleShot(20, close_when_shown)

QTimer.singleShot(0, close_when_shown)
status = launch(open_the_rig, settings=settings_at(sys.argv[1]))
for k, v in seen.items():
    print(f"{k}: {v}")
print("status", status)
"""


def test_the_start_up_window_paints_at_once_lists_each_step_and_keeps_running_while_the_rig_opens(tmp_path):
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "s.ini")], capture_output=True, text=True,
                         env=env, timeout=180)
    assert out.returncode == 0, out.stderr[-3000:]
    lines = dict(line.split(": ", 1) for line in out.stdout.splitlines() if ": " in line)
    assert lines["pyqtgraph before the window"] == "False"  # the window needs Qt alone
    assert lines["exposed"] == "True"  # mapped and painted before the slow part
    text = lines["text while the rig opens"]
    assert "✓ starting flexvox … " in text and "<b>opening the rig …</b>" in text, text
    assert lines["workspaces not loaded yet"] == "True"
    assert lines["the window kept running while the rig opened"] == "True"
    assert lines["steps done"] == str(["starting flexvox …", "opening the rig …",
                                       "loading the numerics (NumPy, SciPy, Zarr, OpenCV) and designing the code …",
                                       "loading the Calibrate, Capture and Review workspaces …"]), lines["steps done"]
    assert "status 0" in out.stdout


def test_the_qt_start_failure_names_the_libraries_missing_and_their_packages(monkeypatch):
    import subprocess

    import flexvox_app.qt_platform as qp

    assert qp.debian_package("libxcb-icccm.so.4") == "libxcb-icccm4"
    assert qp.debian_package("libxcb-keysyms.so.1") == "libxcb-keysyms1"
    assert qp.debian_package("libfoo2.so.1") == "libfoo2-1"
    monkeypatch.setattr(qp, "missing_xcb_libraries", lambda: ["libxcb-icccm.so.4", "libxcb-keysyms.so.1"])
    monkeypatch.setattr(qp.sys, "platform", "linux")
    monkeypatch.setattr(subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, 134, "", "qt.qpa.plugin: From 6.5.0, xcb-cursor0 or libxcb-cursor0 is needed to load the Qt xcb platform "
                    "plugin.\nCould not load the Qt platform plugin \"xcb\""))
    text = qp.display_problem({"DISPLAY": ":0"})
    assert "lacks libxcb-icccm.so.4, libxcb-keysyms.so.1" in text and "cursor" not in text
    assert "sudo apt install libxcb-icccm4 libxcb-keysyms1" in text and "README" in text
