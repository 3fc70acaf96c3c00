"""The app's display sink: frames from any thread onto the projector window, pixel-exact, before the call returns;
and the Calibrate workspace injecting it into a real rig's DLPC350."""

import html
import threading

import numpy as np
import pytest
from PySide6.QtCore import Qt

from flexvox_app.gui.calibrate.workspace import CalibrateWorkspace
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.projector.display import ProjectorDisplay, ScreenError, pick_screen
from flexvox_calibration.geometry import homography_error_px
from rig_drivers.dlpc350.bitplanes import pack_bitplanes
from tests.rig_drivers.display_rig import ScreenCamera, display_rig

from .widget_helpers import grab


def _frames(K=24, shape=(57, 91), seed=0):
    return pack_bitplanes(np.random.default_rng(seed).random((K, *shape)) < 0.5)


@pytest.fixture
def display(qtbot):
    d = ProjectorDisplay(timeout_s=5.0)
    yield d
    d.close()


def _call_from_worker(qtbot, display, frames):
    """Call ``display(frames)`` on a plain thread; note, right when it returns, whether the frame was painted."""
    seen = {}

    def work():
        try:
            display(frames)
            window = display.window
            seen["painted"] = window is not None and window.on_screen() and window.frames is not None \
                and np.array_equal(window.frames, frames)
        except Exception as exc:  # reported to the test below
            seen["error"] = exc

    t = threading.Thread(target=work)
    t.start()
    qtbot.waitUntil(lambda: not t.is_alive(), timeout=10_000)
    t.join()
    return seen


def test_a_frame_sent_from_a_worker_thread_is_on_screen_pixel_exactly_before_the_call_returns(qtbot, display):
    first, second = _frames(seed=1), _frames(seed=2)
    assert _call_from_worker(qtbot, display, first) == {"painted": True}
    win = display.window
    assert win.isFullScreen() and win.windowFlags() & Qt.WindowType.FramelessWindowHint
    np.testing.assert_array_equal(grab(win)[:57, :91], first[0])
    assert _call_from_worker(qtbot, display, second) == {"painted": True}
    assert display.window is win and display.frames_shown == 2  # the same window, new frame
    shot = grab(win)
    np.testing.assert_array_equal(shot[:57, :91], second[0])
    assert not shot[57:].any() and not shot[:, 91:].any()


def test_the_gui_thread_shows_at_once(qtbot, display):
    frames = _frames(K=8)
    with qtbot.waitSignal(display.shown, timeout=2000) as shown:
        display(frames)
    assert shown.args == [1] and display.window.on_screen()
    np.testing.assert_array_equal(grab(display.window)[:57, :91], frames[0])


def test_a_gui_thread_that_does_not_answer_times_out(qtbot):
    display = ProjectorDisplay(timeout_s=0.2)
    seen = {}

    def work():
        try:
            display(_frames(K=4))
        except TimeoutError as exc:
            seen["error"] = str(exc)

    t = threading.Thread(target=work)
    t.start()
    t.join(10)  # the GUI thread is blocked here on purpose: nobody serves the request
    assert seen == {"error": "the projector window did not show the frames within 0.2 s (the GUI thread is busy "
                             "or its event loop is not running)"}
    qtbot.wait(50)  # the late request is served now, and ignored
    assert display.window is None
    display.close()


def test_a_window_closed_by_the_operator_refuses_further_frames(qtbot, display):
    display(_frames(K=4))
    qtbot.keyClick(display.window, Qt.Key.Key_Escape)
    assert display.closed_by_user
    seen = _call_from_worker(qtbot, display, _frames(K=4))
    assert isinstance(seen["error"], RuntimeError)
    assert str(seen["error"]) == "the projector output window was closed (Esc): the patterns cannot reach the projector"


def test_bad_frames_and_screen_indexes_are_refused(display):
    with pytest.raises(ValueError, match=r"`frames` must have shape \(F, H, W, 3\) uint8 with F >= 1; got \(4, 5\)"):
        display(np.zeros((4, 5), np.uint8))
    with pytest.raises(ScreenError, match=r"--projector-screen must be 0\.\.0 on this desktop; got 3 \(screens: 0: "):
        pick_screen(3)


class _WindowScreen:
    """What the camera sees: the frames in the Calibrate workspace's projector window."""

    def __init__(self, ws):
        self.ws = ws

    @property
    def current(self):
        d = self.ws.screen.display
        return None if d is None or d.window is None else d.window.frames


def test_calibrate_injects_the_window_into_a_real_dlpc350_and_the_homography_is_found_through_it(
        qtbot, settings, runner):
    rig = display_rig()
    rig.projector.display = None  # the workspace brings its own
    service = RigService(rig)
    ws = CalibrateWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    rig.camera = ScreenCamera(rig.projector, _WindowScreen(ws))
    assert ws.screen.needed and ws.screen.screen_box.count() >= 1
    ws.tile_box.setCurrentIndex(ws.tile_box.findText("2×2", Qt.MatchFlag.MatchStartsWith))  # K = 4: wide bands
    assert ws.tile() == (2, 2)
    shown = []
    with qtbot.waitSignal(ws.calibrated, timeout=30_000) as done:
        assert ws.run_calibration()
        assert rig.projector.display is ws.screen.display
        ws.screen.display.shown.connect(lambda n: shown.append(ws.screen.display.window.on_screen()))
    outcome = done.args[0]
    hom = outcome.homography
    assert hom is not None and hom.success, outcome.report
    assert outcome.report["shutter"]["accuracy"] > 0.99  # each slot shown alone through the window, decoded
    assert homography_error_px(hom.homography, np.eye(3), (48, 64)) < 0.1
    assert len(shown) >= 40 and all(shown)  # every pattern painted in the window before the driver went on
    qtbot.waitUntil(lambda: not ws.running, timeout=5000)
    assert ws.screen.display is None and rig.projector.display is None  # window closed, sink removed
    assert ws.screen.label.text() == "projector window closed"


def test_a_failing_display_is_a_device_error_in_the_calibration(qtbot, settings, runner):
    rig = display_rig()
    service = RigService(rig)
    ws = CalibrateWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    assert ws.screen.attach("test") is None
    ws.screen.display.closed_by_user = True  # as if the operator had pressed Esc
    assert ws.run_calibration()
    qtbot.waitUntil(lambda: not ws.running, timeout=30_000)
    text = html.unescape(ws.step_label.text())
    assert "calibration failed: ProjectorDisplayError: could not show the 1 pattern frame(s) of 64x48 on the " \
           "projector's video input: RuntimeError: the projector output window was closed (Esc)" in text
    ws.screen.release("test")
    assert ws.screen.display is None and rig.projector.display is None
