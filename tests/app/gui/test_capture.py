"""The Capture workspace on the simulated rig: code choice, timing check, live view start/stop."""

import numpy as np
import pytest

from app.gui.capture.workspace import CaptureWorkspace
from app.gui.models.rig_service import RigService
from rig_drivers.interfaces import DeviceState, RunState

from .conftest import small_rig


@pytest.fixture
def capture(qtbot, settings):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings)
    qtbot.addWidget(ws)
    ws.rate.setValue(60.0)  # K = 16 at 60 Hz: 1041 µs patterns, frames every 16.7 ms
    yield ws
    ws.shutdown()
    service.close()


def test_live_view_starts_delivers_frames_and_stops(qtbot, capture):
    ws = capture
    rig = ws.service.rig
    ws.live_button.click()
    assert ws.live and ws.live_button.text() == "Stop live view"
    assert rig.projector.run_state is RunState.RUNNING and rig.camera.acquiring
    qtbot.waitUntil(lambda: ws.stats.received >= 5, timeout=10_000)
    qtbot.waitUntil(lambda: ws.image_panel.has_image(), timeout=5000)
    assert ws.image_panel.image.image.shape == (48, 64)
    assert ws.stats.fps > 0 and "fps" in ws.live_label.text() and "dropped" in ws.live_label.text()
    x, y = ws.hist_curve.getData()
    assert y.sum() == 48 * 64  # every pixel in the histogram
    assert ws.image_panel.title.text().startswith("camera: frame")
    ws.live_button.click()
    assert not ws.live and not rig.camera.acquiring and rig.projector.run_state is RunState.STOPPED
    assert ws.live_label.text().startswith("stopped")
    assert rig.camera.state is DeviceState.ENABLED  # stopping the view keeps the devices connected


def test_saturation_overlay_marks_saturated_pixels(qtbot, capture):
    from rig_drivers.interfaces import Frame

    img = np.zeros((48, 64), np.float32)
    img[:4, :8] = 1.0
    capture._on_frame(Frame(img, frame_id=0, timestamp_s=0.0))
    capture._redraw()
    overlay = capture.image_panel.overlay.image
    assert overlay.shape == (48, 64, 4) and (overlay[..., 0] == 255).sum() == 32
    assert "0.0% saturated" not in capture.live_label.text() and "1.0% saturated" in capture.live_label.text()
    capture.saturation_check.setChecked(False)
    capture._on_frame(Frame(img, frame_id=1, timestamp_s=0.1))
    capture._redraw()
    assert capture.image_panel.overlay.image is None


def test_timing_check_refuses_what_the_projector_cannot_do(capture):
    ws = capture
    ws.rate.setValue(15.0)
    assert "✓ the projector accepts this timing" in ws.timing_label.text()
    assert "drifts one slot every 26 s" in ws.timing_label.text()
    assert ws.live_button.isEnabled()
    ws.projector_exposure.setValue(4000)  # period 4166 µs: neither equal nor 230 µs shorter
    assert "at most period - 230 µs = 3936 µs" in ws.timing_label.text()
    assert not ws.live_button.isEnabled()
    assert not ws.start_live() and "cannot start" in ws.live_label.text()
    ws.projector_exposure.setValue(3900)
    assert ws.live_button.isEnabled() and "video port needs exposure = period" in ws.timing_label.text()
    ws.projector_exposure.setValue(0)
    ws.rate.setValue(1000.0)
    assert "no shorter than 235 µs" in ws.timing_label.text() and not ws.live_button.isEnabled()


def test_code_choice_lists_tr_sr_and_multiplexed_codes(capture):
    ws = capture
    ws.set_tile((2, 4))
    text = ws.resolutions_label.text()
    assert "1x1x8" in text and "2x4x1" in text and "identity code, K = 8" in ws.code_label.text()
    ws.multiplexed.setChecked(True)
    assert "no S-matrix exists for K = 8" in ws.code_label.text()
    ws.set_tile((3, 5))
    assert "S-matrix multiplexed, K = 15" in ws.code_label.text() and "3x5x1" in ws.resolutions_label.text()


def test_a_camera_that_stops_delivering_ends_the_live_view_with_the_reason(qtbot, capture):
    ws = capture
    assert ws.start_live()
    qtbot.waitUntil(lambda: ws.stats.received >= 1, timeout=10_000)
    ws.service.rig.projector.stop()  # the trigger source goes away behind the live view's back
    qtbot.waitUntil(lambda: not ws.live, timeout=10_000)
    assert "live view stopped" in ws.live_label.text() and "no frame within" in ws.live_label.text()
    assert "no frame within" in ws.service.status("camera").last_error


def test_capture_settings_persist(qtbot, settings):
    service = RigService(small_rig())
    first = CaptureWorkspace(service, settings)
    qtbot.addWidget(first)
    first.set_tile((2, 4))
    first.rate.setValue(30.0)
    settings.sync()
    second = CaptureWorkspace(service, settings)
    qtbot.addWidget(second)
    assert second.tile() == (2, 4) and second.rate.value() == 30.0
    service.close()
