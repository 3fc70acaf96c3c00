"""The projector output window: exactly the packed frame, pixel for pixel; the screen list; Esc closes."""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication

from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.projector.window import ProjectorWindow, screen_label
from flexvox_app.gui.widgets.questions import answering
from rig_drivers.dlpc350.bitplanes import pack_bitplanes, unpack_bitplanes

from .conftest import small_rig
from .widget_helpers import grab


def _random_frames(K: int, shape=(57, 91), seed: int = 0) -> np.ndarray:
    masks = np.random.default_rng(seed).random((K, *shape)) < 0.5
    return pack_bitplanes(masks)


@pytest.fixture
def window(qtbot):
    def make(frames, **kw):
        w = ProjectorWindow(frames, **kw)
        qtbot.addWidget(w)
        w.open()
        qtbot.waitExposed(w)
        return w

    return make


def test_the_window_shows_exactly_the_packed_frame_unscaled(window):
    frames = _random_frames(24)  # every bit-plane used: any blending or scaling changes some bit
    w = window(frames)
    shot = grab(w)
    screen = QGuiApplication.primaryScreen().geometry()
    assert (shot.shape[1], shot.shape[0]) == (screen.width(), screen.height())  # full-screen
    H, W = frames.shape[1:3]
    np.testing.assert_array_equal(shot[:H, :W], frames[0])
    assert not shot[H:].any() and not shot[:, W:].any()  # black around the pattern, nothing stretched
    np.testing.assert_array_equal(unpack_bitplanes(shot[None, :H, :W], 24), unpack_bitplanes(frames, 24))
    assert w.windowFlags() & Qt.WindowType.FramelessWindowHint and w.isFullScreen()
    assert w.size_warning().startswith(f"the screen is {screen.width()}×{screen.height()} pixels, the patterns 91×57")


@pytest.mark.parametrize("scale", ["2", "1.25"])
def test_the_pattern_stays_one_image_pixel_per_device_pixel_on_a_scaled_screen(scale):
    """On a high-DPI (or 125 %) desktop the frame is drawn in device pixels, not stretched to logical ones."""
    script = textwrap.dedent("""
        import numpy as np
        from PySide6.QtGui import QImage
        from PySide6.QtWidgets import QApplication
        from flexvox_app.gui.projector.window import ProjectorWindow
        from rig_drivers.dlpc350.bitplanes import pack_bitplanes

        app = QApplication([])
        frames = pack_bitplanes(np.random.default_rng(0).random((24, 57, 91)) < 0.5)
        w = ProjectorWindow(frames)
        w.open()
        app.processEvents()
        pm = w.grab()
        img = pm.toImage().convertToFormat(QImage.Format.Format_RGB888)
        h, wd = img.height(), img.width()
        buf = np.frombuffer(img.constBits(), np.uint8, count=img.bytesPerLine() * h)
        buf = buf.reshape(h, img.bytesPerLine())[:, : 3 * wd].reshape(h, wd, 3)
        exact = (buf[:57, :91] == frames[0]).all() and not buf[57:].any() and not buf[:, 91:].any()
        print(pm.devicePixelRatio(), bool(exact))
        w.close()
    """)
    root = Path(__file__).resolve().parents[3]
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "QT_SCALE_FACTOR": scale,
           "PYTHONPATH": str(root) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=root,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [str(float(scale)), "True"]


def test_more_than_24_masks_cycle_through_the_packed_frames(qtbot, window):
    frames = _random_frames(30, seed=1)
    assert frames.shape[0] == 2
    w = window(frames, cycle_ms=40)
    assert w.timer.isActive()
    w.timer.stop()  # step by hand: the timer's pace is not under test
    w.show_frame(1)
    np.testing.assert_array_equal(grab(w)[:57, :91], frames[1])
    w.next_frame()
    assert w.index == 0
    np.testing.assert_array_equal(grab(w)[:57, :91], frames[0])


def test_escape_closes_the_window(qtbot, window):
    w = window(_random_frames(8))
    with qtbot.waitSignal(w.closed, timeout=2000):
        qtbot.keyClick(w, Qt.Key.Key_Escape)
    assert not w.isVisible() and not w.timer.isActive()


def test_frames_that_are_not_rgb_are_refused():
    with pytest.raises(ValueError, match=r"`frames` must have shape \(F, H, W, 3\) uint8 with F >= 1; got \(4, 5\)"):
        ProjectorWindow(np.zeros((4, 5), np.uint8))


@pytest.fixture
def capture(qtbot, settings, runner):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    ws.code.rate.setValue(60.0)
    yield ws
    ws.shutdown()
    service.close()


def test_capture_lists_the_screens_with_their_geometry(capture):
    screens = QGuiApplication.screens()
    assert capture.projector.screen_box.count() == len(screens) >= 1
    for i, screen in enumerate(screens):
        g = screen.geometry()
        text = capture.projector.screen_box.itemText(i)
        assert text == screen_label(screen)
        assert f"{g.width()}×{g.height()} at ({g.x()}, {g.y()})" in text
    assert capture.projector.chosen_screen() in screens


def test_capture_shows_the_plans_patterns_full_screen_and_esc_closes(qtbot, capture):
    ws = capture
    ws.set_tile((2, 4))
    assert len(QGuiApplication.screens()) == 1  # offscreen: the only screen, so it asks first (point 11)
    with answering(False) as asked:
        ws.projector.button.click()
    assert [q.title for q in asked] == ["Cover the only screen?"] and "until you press Esc" in asked[0].text
    assert ws.projector.window is None and not ws.projector.button.isChecked()
    assert ws.projector.label.text() == "not shown: it is the only screen"
    with answering(True):
        ws.projector.button.click()
    qtbot.waitUntil(lambda: ws.projector.window is not None, timeout=10_000)
    win = ws.projector.window
    qtbot.waitExposed(win)
    # what a recording loads into the projector (96x128: the simulated projector is twice as fine)
    expected = ws.plan().patterns((48, 64), (96, 128), ws.capture_calibration()).packed
    assert expected.shape == (1, 96, 128, 3)
    np.testing.assert_array_equal(grab(win)[:96, :128], expected[0])
    assert win.screen() is ws.projector.chosen_screen()
    assert re.search(r"showing on .*: 128×96 pixels, 1 frame: K = 8 masks in its bit-planes; Esc closes",
                     ws.projector.label.text())
    assert ws.projector.button.isChecked() and ws.projector.button.text() == "Close projector window"
    qtbot.keyClick(win, Qt.Key.Key_Escape)
    qtbot.waitUntil(lambda: ws.projector.window is None, timeout=2000)
    assert not ws.projector.button.isChecked() and ws.projector.label.text() == "closed (Esc)"


def test_a_screen_gone_while_the_patterns_were_packed_is_said_not_shown(qtbot, capture):
    """The packing job ends after the screen went away (unplugged): no window, a line that says so."""
    ws = capture
    ws.projector._set_button(True)  # as open() leaves it while the job runs
    frames = np.zeros((1, 96, 128, 3), np.uint8)
    ws.projector._show(frames, "HDMI-unplugged", 8)
    assert ws.projector.window is None and not ws.projector.button.isChecked()
    assert "not shown: the screen HDMI-unplugged is gone" in ws.projector.label.text()
