"""The operator's path through the window on the simulated rig, by its buttons:
calibrate → use for capture → record → open in Review → reconstruct.

The simulated rig is the one ``flexvox app`` opens (a projector twice as fine as the camera behind a hidden
homography, a trigger offset that is not a whole slot), with a strobe in front of it so the recording says
which slot every pixel sampled. Its clock is virtual, so nothing waits for real time.
"""

import numpy as np
import pytest
from PySide6.QtCore import Qt

from app.gui.application import build_window
from flexvox_core.recording import open_recording
from flexvox_core.slot_check import slot_accuracy
from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock

FRAMES = 17  # the strobe visits every slot of K = 16 in 17 frames


@pytest.fixture
def window(qtbot, settings, runner):
    rig = open_rig("mock", scene="strobe", subframes=FRAMES * 16, seed=0, clock=VirtualClock())
    w = build_window(rig, settings=settings, runner=runner)
    qtbot.addWidget(w)
    w.capture.live_panel.preview_check.setChecked(False)
    yield w
    w.close()


def click(qtbot, button):
    assert button.isEnabled(), button.text()
    qtbot.mouseClick(button, Qt.MouseButton.LeftButton)


def record(qtbot, capture, path):
    capture.record_panel.path_edit.setText(str(path))
    capture.record_panel.frames_box.setValue(FRAMES)
    assert capture.record_panel.truth_check.isChecked()
    with qtbot.waitSignal(capture.recording_finished, timeout=30_000) as finished:
        click(qtbot, capture.record_panel.record_button)
    assert finished.args[0].ok, finished.args[0].message
    rec = open_recording(path)
    return rec, slot_accuracy(rec.normalised_frames(), rec.ground_truth(), rec.code)


def test_calibrate_use_for_capture_record_and_review(qtbot, window, tmp_path):
    window.show_workspace("Calibrate")
    calibrate = window.calibrate
    click(qtbot, calibrate.run_button)
    qtbot.waitUntil(lambda: not calibrate.running, timeout=60_000)
    assert calibrate.outcome.success, calibrate.step_label.text()
    click(qtbot, calibrate.save_panel.use_button)
    capture = window.capture
    assert window.tabs.currentWidget() is capture and capture.calibration is not None
    sync = calibrate.outcome.sync
    label = capture.calibration_panel.label.text()
    assert f"recordings use phase <b>{sync.effective_phase_slots}</b>" in label and "(set by the camera)" in label

    rec, slots = record(qtbot, capture, tmp_path / "calibrated.zarr")
    assert rec.attrs["calibration"]["phase_slots"] == sync.effective_phase_slots
    assert rec.attrs["calibration"]["trigger_delay_us"] == pytest.approx(sync.recommended_camera_delay_us)
    assert rec.attrs["rig"]["trigger_delay_set_by"] == "camera"
    assert slots.decidable_fraction > 0.95 and slots.accuracy == 1.0, slots.describe()

    click(qtbot, capture.record_panel.review_button)
    review = window.review
    assert window.tabs.currentWidget() is review
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    assert review.session.n_frames == FRAMES and review.session.frames is not None
    n = len(review.results)
    with qtbot.waitSignal(review.result_added, timeout=60_000):
        click(qtbot, review.reconstruct_button)
    assert len(review.results) == n + 1
    video = review.results[-1].video
    assert video.shape == (FRAMES * 16, 120, 160) and np.isfinite(video).all()


def test_without_the_calibration_the_recording_visibly_fails(qtbot, window, tmp_path):
    capture = window.capture
    window.show_workspace("Capture")
    assert "uncalibrated" in capture.calibration_panel.label.text()
    _, slots = record(qtbot, capture, tmp_path / "uncalibrated.zarr")
    assert slots.accuracy < 0.5, slots.describe()


def test_the_cli_and_the_workspace_record_the_same_phase_from_one_calibration_file(qtbot, window, tmp_path):
    from app.cli.main import main

    cal = tmp_path / "cal.json"
    assert main(["calibrate", "--rig", "mock", "--seed", "0", "-o", str(cal)]) == 0
    assert main(["capture", "--rig", "mock", "--seed", "0", "--scene", "strobe", "--frames", str(FRAMES),
                 "--clock", "virtual", "--ground-truth", "--calibration", str(cal),
                 "-o", str(tmp_path / "cli.zarr")]) == 0
    by_cli = open_recording(tmp_path / "cli.zarr")
    capture = window.capture
    window.show_workspace("Capture")
    assert capture.load_calibration(cal), capture.calibration_error
    by_gui, slots = record(qtbot, capture, tmp_path / "gui.zarr")
    for key in ("phase_slots", "trigger_delay_us"):
        assert by_gui.attrs["calibration"][key] == by_cli.attrs["calibration"][key]
    assert by_gui.attrs["calibration"]["trigger_delay_us"] > 0
    assert by_gui.attrs["rig"]["trigger_delay_set_by"] == by_cli.attrs["rig"]["trigger_delay_set_by"] == "camera"
    assert slots.accuracy == 1.0
    cli_slots = slot_accuracy(by_cli.normalised_frames(), by_cli.ground_truth(), by_cli.code)
    assert cli_slots.accuracy == 1.0
