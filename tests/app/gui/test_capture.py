"""The Capture workspace on the simulated rig: code choice, timing check, live view start/stop."""

import html
import itertools

import numpy as np
import pytest
from PySide6.QtCore import Qt

from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.questions import answering
from rig_drivers.interfaces import DeviceState, RunState

from .conftest import small_rig
from .widget_helpers import truth_window


@pytest.fixture
def capture(qtbot, settings):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings)
    qtbot.addWidget(ws)
    ws.code.rate.setValue(60.0)  # K = 16 at 60 Hz: 1041 µs patterns, frames every 16.7 ms
    ws.clear_calibration()  # “Record uncalibrated”: these recordings need no calibration
    clicks = itertools.count(0.0, 1.0)
    ws.live_panel.clock = lambda: next(clicks)  # a second between two clicks: none is the half of a double click
    yield ws
    ws.shutdown()
    service.close()


def test_live_view_starts_delivers_frames_and_stops(qtbot, capture):
    ws = capture
    axis = ws.live_panel.hist.getAxis("left")  # an empty histogram: no negative counts, no "pixels (×0.001)"
    assert "×" not in axis.labelString() and ws.live_panel.hist.getViewBox().viewRange()[1][0] >= 0
    rig = ws.service.rig
    ws.live_panel.live_button.click()
    assert ws.live and ws.live_panel.live_button.text() == "Stop live view"
    assert rig.projector.run_state is RunState.RUNNING and rig.camera.acquiring
    qtbot.waitUntil(lambda: ws.live_panel.stats.received >= 5, timeout=10_000)
    qtbot.waitUntil(lambda: ws.live_panel.image_panel.has_image(), timeout=5000)
    assert ws.live_panel.image_panel.image.image.shape == (48, 64)
    label = ws.live_panel.live_label.text()
    assert ws.live_panel.stats.fps > 0 and "fps" in label and "dropped" in label
    x, y = ws.live_panel.hist_curve.getData()
    assert y.sum() == 48 * 64  # every pixel in the histogram
    assert ws.live_panel.image_panel.title.text().startswith("camera: frame")
    ws.live_panel.live_button.click()
    assert not ws.live and not rig.camera.acquiring and rig.projector.run_state is RunState.STOPPED
    assert ws.live_panel.live_label.text().startswith("stopped")
    assert rig.camera.state is DeviceState.ENABLED  # stopping the view keeps the devices connected


def test_saturation_overlay_marks_saturated_pixels(qtbot, capture):
    from rig_drivers.interfaces import Frame

    img = np.zeros((48, 64), np.float32)
    img[:4, :8] = 1.0
    capture.live_panel._on_frame(Frame(img, frame_id=0, timestamp_s=0.0))
    capture.live_panel._redraw()
    overlay = capture.live_panel.image_panel.overlay.image
    assert overlay.shape == (48, 64, 4) and (overlay[..., 0] == 255).sum() == 32
    label = capture.live_panel.live_label.text()
    assert "0.0% saturated" not in label and "1.0% saturated" in label
    capture.live_panel.saturation_check.setChecked(False)
    capture.live_panel._on_frame(Frame(img, frame_id=1, timestamp_s=0.1))
    capture.live_panel._redraw()
    assert capture.live_panel.image_panel.overlay.image is None


def test_timing_check_refuses_what_the_projector_cannot_do(capture):
    ws = capture
    ws.code.rate.setValue(15.0)
    assert "✓ the projector accepts this timing" in ws.code.timing_label.text()
    assert "drifts one slot every 26 s" in ws.code.timing_label.text()
    assert ws.live_panel.live_button.isEnabled()
    ws.code.projector_exposure.setValue(4000)  # period 4166 µs: neither equal nor 230 µs shorter
    assert "at most period - 230 µs = 3936 µs" in ws.code.timing_label.text()
    assert not ws.live_panel.live_button.isEnabled()
    assert not ws.start_live() and "cannot start" in ws.live_panel.live_label.text()
    ws.code.projector_exposure.setValue(3900)
    assert ws.live_panel.live_button.isEnabled() and "video port needs exposure = period" in ws.code.timing_label.text()
    ws.code.projector_exposure.setValue(0)
    ws.code.rate.setValue(1000.0)
    assert "no shorter than 235 µs" in ws.code.timing_label.text() and not ws.live_panel.live_button.isEnabled()


def test_code_choice_lists_tr_sr_and_multiplexed_codes(capture):
    ws = capture
    ws.set_tile((2, 4))
    text = ws.code.resolutions_label.text()
    assert "1x1x8" in text and "2x4x1" in text and "identity code, K = 8" in ws.code.code_label.text()
    # Point 11: no S-matrix at K = 8: the choice is off, and says why
    multiplexed = ws.code.multiplexed
    assert not multiplexed.isEnabled() and multiplexed.text() == "multiplexed (S-matrix): none for K = 8"
    assert multiplexed.toolTip().startswith("not for this tile: no S-matrix exists for K = 8")
    ws.set_tile((3, 5))
    assert multiplexed.isEnabled() and multiplexed.text() == "multiplexed (S-matrix)"
    multiplexed.setChecked(True)
    assert "S-matrix multiplexed, K = 15" in ws.code.code_label.text() and "3x5x1" in ws.code.resolutions_label.text()
    ws.set_tile((4, 4))  # the choice made at K = 15 does not follow to a tile without one
    assert ws.code.identity.isChecked() and not ws.plan().multiplexed and not multiplexed.isEnabled()
    assert "identity code, K = 16" in ws.code.code_label.text() and "refused" not in ws.live_panel.live_label.text()


def test_a_camera_that_stops_delivering_ends_the_live_view_with_the_reason(qtbot, capture):
    ws = capture
    assert ws.start_live()
    qtbot.waitUntil(lambda: ws.live_panel.stats.received >= 1, timeout=10_000)
    ws.service.rig.projector.stop()  # the trigger source goes away behind the live view's back
    qtbot.waitUntil(lambda: not ws.live, timeout=10_000)
    label = ws.live_panel.live_label.text()
    assert "live view stopped" in label and "no frame within" in label
    assert "no frame within" in ws.service.status("camera").last_error


def test_capture_settings_persist(qtbot, settings):
    service = RigService(small_rig())
    first = CaptureWorkspace(service, settings)
    qtbot.addWidget(first)
    first.set_tile((2, 4))
    first.code.rate.setValue(30.0)
    settings.sync()
    second = CaptureWorkspace(service, settings)
    qtbot.addWidget(second)
    assert second.code.tile() == (2, 4) and second.code.rate.value() == 30.0
    service.close()


def test_a_design_file_is_the_code_recordings_use(qtbot, settings, tmp_path):
    import json

    from flexvox_core.design import design_code
    from flexvox_core.recording import open_recording

    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings)
    qtbot.addWidget(ws)
    ws.live_panel.preview_check.setChecked(False)
    ws.clear_calibration()  # “Record uncalibrated”: these recordings need no calibration
    code = design_code((2, 4))
    path = tmp_path / "code.json"
    path.write_text(json.dumps(code.as_dict()))
    bad = tmp_path / "bad.json"
    bad.write_text('{"code": [[[1, 1], [0, 0]]]}')
    assert not ws.code.load_code_file(bad)
    assert "refused: " in ws.code.code_label.text() and "not an identity code" in ws.code.code_label.text()
    assert ws.code.load_code_file(path)
    plan = ws.plan()
    assert plan.K == 8 and plan.code_file == path and np.array_equal(plan.code, code.code)
    assert "identity code from code.json, K = 8" in ws.code.code_label.text()
    assert not ws.code.tile_box.isEnabled() and ws.code.tile_code_button.isEnabled()
    ws.code.rate.setValue(60.0)
    ws.record_panel.path_edit.setText(str(tmp_path / "r.zarr"))
    ws.record_panel.frames_box.setValue(3)
    with qtbot.waitSignal(ws.recording_finished, timeout=20_000) as finished:
        assert ws.record()
    assert finished.args[0].ok
    assert open_recording(tmp_path / "r.zarr").attrs["order"] == code.order.tolist()
    ws.code.use_tile_code()
    assert ws.plan().code_file is None and ws.code.tile_box.isEnabled()
    ws.shutdown()
    service.close()


def test_a_double_click_on_start_live_view_does_not_stop_it_after_one_frame(qtbot, capture):
    """Point 11: the second click of a double click is ignored; a later click stops the live view."""
    ws = capture
    now = [100.0]
    ws.live_panel.clock = lambda: now[0]
    for _ in range(2):  # a double click: two clicks with no time between them on the clock
        qtbot.mouseClick(ws.live_panel.live_button, Qt.MouseButton.LeftButton)
    assert ws.live and ws.live_panel.live_button.isChecked() and ws.live_panel.live_button.text() == "Stop live view"
    now[0] += 0.3
    ws.live_panel.live_button.click()  # still within the double-click time
    assert ws.live
    now[0] += 1.0
    ws.live_panel.live_button.click()
    assert not ws.live and ws.live_panel.live_button.text() == "Start live view"


def test_ground_truth_says_what_it_costs_and_the_choice_survives_a_restart(qtbot, settings):
    w = truth_window(qtbot, settings)
    panel = w.capture.record_panel
    w.show()
    w.show_workspace("Capture")
    panel.frames_box.setValue(300)
    panel.options.set_expanded(True)  # the cost is said beside its box, among the options
    for _ in range(3):
        qtbot.wait(10)
    review_y = panel.review_button.mapTo(w, panel.review_button.rect().topLeft()).y()
    assert panel.truth_check.isChecked() and panel.truth_cost.isVisible()
    cost = panel.truth_cost.text()  # 4x4 code on a 120x160 camera at 15 Hz: 16 float32 pictures per frame
    assert "ground truth adds 1.2 MB per frame (18 MB per second at 15 Hz, about 32× the frames' size)" in cost, cost
    assert "369 MB for 300 frames" in cost and "finishing takes longer" in cost
    panel.truth_check.setChecked(False)
    assert not panel.truth_cost.isVisible()
    for _ in range(3):
        qtbot.wait(10)
    # "Open in Review" holds still (it jumped 34 px): the cost's room stays when it is hidden
    assert panel.review_button.mapTo(w, panel.review_button.rect().topLeft()).y() == review_y
    with answering(default=True):
        w.close()
    again = truth_window(qtbot, settings)
    assert not again.capture.record_panel.truth_check.isChecked()  # unticked stays unticked
    with answering(default=True):
        again.close()


def test_while_a_recording_finishes_its_ground_truth_the_status_says_what_is_written_and_stop_is_off(
        qtbot, settings, tmp_path):
    from dataclasses import replace

    w = truth_window(qtbot, settings)
    panel = w.capture.record_panel
    panel.path_edit.setText(str(tmp_path / "t.zarr"))
    panel.frames_box.setValue(17)
    with answering(default=True), qtbot.waitSignal(panel.started, timeout=20_000):
        assert panel.record()
    # Stop is on while it records. The virtual clock runs ahead of a loaded GUI thread: the capture may already
    # have its 17 frames and be finishing when `started` is handled, and then Stop is already off.
    assert panel.stop_button.isEnabled() != panel.finishing
    stats = replace(panel.capture.stats(), finishing="writing the scene's ground truth: frame 3 of 17",
                    queue_depth=0)
    panel._on_progress(panel.capture, stats)  # as the capture's progress event says it
    said = html.unescape(panel.recording_label.text())
    assert "finishing t.zarr: writing the scene's ground truth: frame 3 of 17 …" in said, said
    assert not panel.stop_button.isEnabled()
    with qtbot.waitSignal(panel.finished, timeout=30_000) as done:
        pass
    assert done.args[0].ok and settings.get_float("capture/truth_finish_s_per_frame", -1) > 0
    assert "measured on the last such recording" in panel.truth_cost.text()
    with answering(default=True):
        w.close()


def test_a_double_click_on_a_slow_start_does_not_stop_the_live_view(qtbot, settings):
    w = truth_window(qtbot, settings)
    live = w.capture.live_panel
    now = [100.0]
    live.clock = lambda: now[0]
    start = live.start

    def slow_start():  # a loaded machine: starting takes longer than the double-click time
        ok = start()
        now[0] += 2.0
        return ok

    live.start = slow_start
    with answering(default=True):
        live.live_button.click()
        live.live_button.click()  # the second click, handled only after the start returned
    assert live.running and live.live_button.isChecked()
    w.capture.stop_live()
    with answering(default=True):
        w.close()
