"""Calibration in the Capture workspace: load a file or a sync profile, refuse another rig's, take the Calibrate
workspace's result (the simulated rig is one rig: its own calibration is accepted)."""

import html
import re

import numpy as np
import pytest

from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.calibration_model import run_workspace_calibration, target_for
from flexvox_app.gui.models.capture_calibration import capture_identity
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.questions import answering
from flexvox_calibration.capture_setup import CalibrationRefused, file_sha256, from_run, load_for_capture
from flexvox_calibration.files import write_versioned
from flexvox_core.recording import open_recording

from .conftest import H_SHIFT, small_rig
from .conftest import write_calibration as _write
from .widget_helpers import truth_window


@pytest.fixture
def capture(qtbot, settings, runner):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    ws.code.rate.setValue(60.0)  # K = 16 at 60 Hz: 1041 µs patterns
    ws.live_panel.preview_check.setChecked(False)
    yield ws
    ws.shutdown()
    service.close()


def test_a_file_for_this_rig_is_used_by_recordings(qtbot, capture, tmp_path):
    ws = capture
    label = ws.calibration_panel.label
    assert "uncalibrated" in label.text()
    path = _write(tmp_path / "cal.json", capture_identity(ws.service))
    with qtbot.waitSignal(ws.calibration_changed) as changed:
        assert ws.load_calibration(path)
    active = changed.args[0]
    np.testing.assert_allclose(active.homography, H_SHIFT)
    text = label.text()
    assert str(path) in text and "2026-03-14T09:30:00+00:00" in text and "RMS 0.123 px" in text
    assert "phase 3 with a 0 µs camera trigger delay (measured at K = 16, 1041 µs patterns)" in text
    assert "recordings use phase <b>3</b>, no camera trigger delay" in text
    cal = ws.capture_calibration()
    np.testing.assert_allclose(cal.homography, H_SHIFT)
    assert cal.phase_slots == 3 and cal.created == "2026-03-14T09:30:00+00:00"
    assert cal.source == f"{path} (sha256 {file_sha256(path)[:16]})" and cal.sha256 == file_sha256(path)
    ws.record_panel.path_edit.setText(str(tmp_path / "run.zarr"))
    ws.record_panel.frames_box.setValue(4)
    with qtbot.waitSignal(ws.recording_finished, timeout=20_000) as finished:
        assert ws.record()
    assert finished.args[0].ok
    stored = open_recording(tmp_path / "run.zarr").attrs["calibration"]
    np.testing.assert_allclose(stored["homography"], H_SHIFT)
    assert stored["phase_slots"] == 3 and stored["source"] == cal.source and stored["sha256"] == cal.sha256
    # another timing: the phase is only a guess, and the box says so
    ws.set_tile((2, 4))
    assert "the sync was measured at K = 16, 1041 µs patterns; this capture is K = 8" in label.text()
    ws.clear_calibration()
    assert ws.calibration is None and ws.capture_calibration().source == "identity (uncalibrated)"


def test_a_file_for_another_resolution_or_rig_is_refused_in_words(capture, tmp_path):
    ws = capture
    good = _write(tmp_path / "good.json", capture_identity(ws.service))
    assert ws.load_calibration(good)
    other = capture_identity(ws.service).as_dict() | {"camera_size": [120, 160]}
    path = _write(tmp_path / "other.json", other)
    assert not ws.load_calibration(path)
    text = html.unescape(ws.calibration_panel.label.text())
    assert re.search(r"refused: .*other\.json was made for a camera resolution of 120x160, this rig's is 48x64: "
                     r"calibrate this rig", text)
    assert ws.calibration is not None and str(good) in text  # the previous calibration stays active
    renamed = capture_identity(ws.service).as_dict() | {"name": "lab rig 2"}
    with pytest.raises(CalibrationRefused, match=r"was made for rig 'lab rig 2', not 'simulated rig \(mock, seed 0\)'"):
        load_for_capture(_write(tmp_path / "rig2.json", renamed), capture_identity(ws.service))
    with pytest.raises(CalibrationRefused, match=r"missing\.json: no such file"):
        load_for_capture(tmp_path / "missing.json", capture_identity(ws.service))


def test_a_sync_profile_loads_into_capture_with_its_phase_and_delay(capture, tmp_path):
    from flexvox_calibration.sync import SYNC_FORMAT, SYNC_VERSION

    ws = capture
    identity = capture_identity(ws.service)
    assert ws.load_calibration(_write(tmp_path / "cal.json", identity))
    sync = {"status": "ok", "K": 16, "period_us": 1041, "phase_slots": 6, "delay_us": 600.0,
            "recommended_camera_delay_us": 441.0, "effective_phase_slots": 7}
    profile = write_versioned(tmp_path / "sync.json", SYNC_FORMAT, SYNC_VERSION, identity, {"sync": sync})
    assert ws.load_sync_profile(profile)
    cal = ws.capture_calibration()
    np.testing.assert_allclose(cal.homography, H_SHIFT)  # the calibration's homography stays
    assert (cal.phase_slots, cal.trigger_delay_us) == (7, 441.0)
    text = ws.calibration_panel.label.text()
    assert "recordings use phase <b>7</b> and a <b>441 µs</b> camera trigger delay (set by the camera)" in text
    assert not ws.calibration_panel.delay_check.isVisibleTo(ws)  # the simulated camera sets it itself


def test_the_calibrate_workspaces_result_hands_over_to_capture(qtbot, settings, runner, tmp_path):
    """The simulated rig calibrates itself: "Use for capture" makes Capture record with the fresh result,
    the phase that goes with the recommended trigger delay, and that delay."""
    from flexvox_app.gui.application import build_window
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="balls", subframes=64, clock=VirtualClock())
    window = build_window(rig, settings=settings, runner=runner)
    qtbot.addWidget(window)
    window.capture.live_panel.preview_check.setChecked(False)
    cal = window.calibrate
    assert not cal.save_panel.use_button.isEnabled()
    cal.run_calibration()
    qtbot.waitUntil(lambda: not cal.running, timeout=30_000)
    assert cal.outcome.success and cal.save_panel.use_button.isEnabled()
    cal.save_panel.use_button.click()
    capture = window.capture
    assert window.tabs.currentWidget() is capture
    assert capture.calibration.source == "the calibration just run (not saved)" and capture.calibration.sha256 == ""
    # Saved afterwards: recordings now name the file by its path and content hash, as when it is loaded.
    path = cal.save_panel.save(tmp_path / "fresh.json")
    digest = file_sha256(path)
    assert capture.calibration.source == f"{path} (sha256 {digest[:16]})" and capture.calibration.sha256 == digest
    window.show_workspace("Calibrate")
    cal.save_panel.use_button.click()  # saved first, then used: the same file
    assert capture.calibration.sha256 == digest and settings.get_str("capture/calibration_file") == str(path)
    active = capture.calibration
    np.testing.assert_allclose(active.homography, cal.outcome.homography.homography)
    sync = cal.outcome.sync
    assert active.phase_slots == sync.effective_phase_slots != sync.phase_slots
    assert active.trigger_delay_us == pytest.approx(sync.recommended_camera_delay_us)
    assert f"RMS {cal.outcome.homography.rms_px:.3f} px" in capture.calibration_panel.label.text()
    window.close()


def test_another_simulated_rigs_calibration_is_refused(qtbot, settings, runner):
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    other = RigService(open_rig("mock", scene="static", camera_size=(48, 64), subframes=16, seed=1,
                                clock=VirtualClock()))
    outcome = run_workspace_calibration(target_for(other))
    assert outcome.success
    service = RigService(small_rig())
    with pytest.raises(CalibrationRefused, match=r"was made for rig 'simulated rig \(mock, seed 1\)', not "
                                                 r"'simulated rig \(mock, seed 0\)'.*with the seed it was made on: "
                                                 r"--seed\)"):
        from_run(outcome.run, outcome.identity, capture_identity(service))
    ws = CaptureWorkspace(service, settings, runner)
    qtbot.addWidget(ws)
    assert not ws.use_outcome(outcome)
    assert ws.calibration_error.startswith("the calibration just run was made for rig")
    assert ws.calibration_error.endswith("calibrate this rig in the Calibrate workspace instead of reusing it (or "
                                         "start flexvox on the simulated rig with the seed that file was made with)")
    assert "refused: the calibration just run was made for" in html.unescape(ws.calibration_panel.label.text())
    assert ws.calibration is None
    ws.shutdown()
    service.close()
    other.close()


# ---------------------------------------------------------------------- the file in use changes on disk
def _info(path, capsys) -> str:
    from flexvox_app.cli.main import main

    capsys.readouterr()
    assert main(["info", str(path)]) == 0
    return capsys.readouterr().out


def test_a_file_in_use_changed_on_disk_is_said_at_once_offered_and_record_asks(qtbot, capture, tmp_path, capsys):
    from flexvox_app.gui.widgets.questions import answering

    ws, panel = capture, capture.calibration_panel
    path = _write(tmp_path / "cal.json", capture_identity(ws.service))
    old = file_sha256(path)
    assert ws.load_calibration(path) and not panel.use_new_button.isVisibleTo(ws)
    _write(path, capture_identity(ws.service), phase=5, overwrite=True)  # another program writes it (a rename)
    new = file_sha256(path)
    qtbot.waitUntil(lambda: panel.replaced == "changed", timeout=5000)  # the watcher, no click
    top = html.unescape(panel.status_label.text())
    assert top.startswith("<b>calibrated</b>: phase 3") and "its file changed on disk: recordings use the one " \
        "loaded until “Use the new calibration”" in top
    assert panel.use_new_button.isVisibleTo(ws) and ws.capture_calibration().sha256 == old
    ws.record_panel.path_edit.setText(str(tmp_path / "kept.zarr"))
    ws.record_panel.frames_box.setValue(2)
    with answering(False) as asked:  # Record asks; Cancel records nothing
        assert not ws.record()
    assert asked[0].title == "Use the new calibration?" and f"{path}, changed on disk" in asked[0].text
    assert f"(sha256 {old[:16]}), not the new one" in asked[0].text
    assert not (tmp_path / "kept.zarr").exists()
    with answering(True) as asked, qtbot.waitSignal(ws.recording_finished, timeout=20_000):
        assert ws.record()
    assert [q.accept for q in asked] == ["Use the new calibration and record"]
    assert ws.capture_calibration().sha256 == new and ws.capture_calibration().phase_slots == 5
    assert not panel.replaced and not panel.use_new_button.isVisibleTo(ws)
    stored = open_recording(tmp_path / "kept.zarr").attrs["calibration"]
    assert stored["sha256"] == new and stored["phase_slots"] == 5
    assert f"calibration: {path} (sha256 {new[:16]}), phase 5 slot(s)" in _info(tmp_path / "kept.zarr", capsys)


def test_the_new_calibration_button_takes_the_file_and_a_removed_file_is_said(qtbot, capture, tmp_path):
    from flexvox_calibration.sync import SYNC_FORMAT, SYNC_VERSION

    ws, panel = capture, capture.calibration_panel
    identity = capture_identity(ws.service)
    path = _write(tmp_path / "cal.json", identity)
    assert ws.load_calibration(path)
    _write(path, identity, h=np.eye(3), overwrite=True)
    assert panel.check_file()  # (what the watcher calls) at once
    panel.use_new_button.click()
    np.testing.assert_allclose(ws.capture_calibration().homography, np.eye(3))
    assert ws.capture_calibration().sha256 == file_sha256(path)
    # a sync profile loaded on top stays on top when the new calibration is taken
    sync = {"status": "ok", "K": 16, "period_us": 1041, "phase_slots": 6, "delay_us": 600.0,
            "recommended_camera_delay_us": 441.0, "effective_phase_slots": 7}
    assert ws.load_sync_profile(write_versioned(tmp_path / "sync.json", SYNC_FORMAT, SYNC_VERSION, identity,
                                                {"sync": sync}))
    _write(path, identity, phase=6, overwrite=True)
    assert panel.check_file()
    panel.use_new_button.click()
    assert ws.capture_calibration().phase_slots == 7 and ws.capture_calibration().sha256 == file_sha256(path)
    np.testing.assert_allclose(ws.capture_calibration().homography, H_SHIFT)
    path.unlink()
    qtbot.waitUntil(lambda: panel.replaced == "removed", timeout=5000)
    assert "its file was removed: recordings use the one loaded" in panel.status_label.text()
    assert not panel.use_new_button.isVisibleTo(ws) and ws.capture_calibration().phase_slots == 7


def test_calibrate_saving_over_the_file_in_use_is_said_in_capture_at_once(qtbot, settings, runner, tmp_path,
                                                                            capsys):
    """The operator's repro: Capture uses rig-calibration.json; Calibrate runs and saves over it; the next
    recording (after Record's question) holds the new calibration, and `flexvox info` names its hash."""
    from flexvox_app.gui.application import build_window
    from flexvox_app.gui.widgets.questions import answering
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="balls", subframes=64, clock=VirtualClock())
    window = build_window(rig, settings=settings, runner=runner)
    qtbot.addWidget(window)
    capture, cal = window.capture, window.calibrate
    capture.live_panel.preview_check.setChecked(False)
    path = _write(tmp_path / "rig-calibration.json", capture_identity(window.service))
    assert capture.load_calibration(path)
    old = file_sha256(path)
    cal.run_calibration()
    qtbot.waitUntil(lambda: not cal.running, timeout=30_000)
    with answering(True) as asked:  # "Replace the existing calibration?"
        assert cal.save_panel.save(path) == path
    assert asked[0].accept == "Replace"
    new = file_sha256(path)
    panel = capture.calibration_panel
    assert panel.replaced == "changed" and panel.use_new_button.isVisibleTo(capture)  # at once: no event loop
    assert "its file changed on disk" in panel.status_label.text() and capture.calibration.sha256 == old
    assert window.statusBar().currentMessage() == ("the calibration file in use changed on disk: rig-calibration.json "
                                                   "— Capture offers the new calibration")
    capture.record_panel.path_edit.setText(str(tmp_path / "after.zarr"))
    capture.record_panel.frames_box.setValue(2)
    with answering(default=True) as asked, qtbot.waitSignal(capture.recording_finished, timeout=30_000):
        assert capture.record()
    assert asked[0].accept == "Use the new calibration and record"
    stored = open_recording(tmp_path / "after.zarr").attrs["calibration"]
    assert stored["sha256"] == new != old
    assert f"(sha256 {new[:16]})" in _info(tmp_path / "after.zarr", capsys)
    with answering(default=True):
        window.close()


def calibrated_window(qtbot, settings, tmp_path):
    from flexvox_app.gui.models.capture_calibration import capture_identity

    from .conftest import write_calibration

    w = truth_window(qtbot, settings)
    plan = w.capture.plan()
    path = write_calibration(tmp_path / "cal.json", capture_identity(w.service), K=plan.K, period_us=plan.period_us)
    assert w.capture.load_calibration(path)
    return w, path


def test_drop_the_calibration_says_what_it_does_and_asks_before_dropping_one(qtbot, settings, tmp_path):
    w, path = calibrated_window(qtbot, settings, tmp_path)
    panel = w.capture.calibration_panel
    button = panel.clear_button
    assert button.text() == "Drop the calibration…" and "identity homography, phase 0" in button.toolTip()
    assert button.isEnabled()
    with answering(False) as asked:
        button.click()
    assert asked[0].title == "Drop the calibration?" and str(path) in asked[0].text
    assert "phase 0 and no trigger delay" in asked[0].text and asked[0].accept == "Drop the calibration"
    assert w.capture.calibration is not None  # kept
    with answering(True):
        button.click()
    assert w.capture.calibration is None and not button.isEnabled()  # nothing left to drop
    with answering(default=True):
        w.close()


def test_a_refused_load_follows_the_state_in_use_and_goes_once_live_view_starts(qtbot, settings, tmp_path):
    w, path = calibrated_window(qtbot, settings, tmp_path)
    panel = w.capture.calibration_panel
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    assert not w.capture.load_calibration(junk)
    top = panel.status_label.text()
    assert top.startswith("<b>calibrated</b>: phase") and "not loaded:" in top and "GroupNotFound" not in top
    assert top.index("calibrated") < top.index("not loaded")
    w.show_workspace("Capture")
    w.capture.live_panel.live_button.setChecked(True)
    assert "not loaded" not in panel.status_label.text()
    w.capture.stop_live()
    with answering(default=True):
        w.close()


def test_a_calibration_file_changed_since_last_used_is_said_on_the_top_line(qtbot, settings, tmp_path):
    from flexvox_app.gui.models.capture_calibration import capture_identity

    from .conftest import write_calibration

    w, path = calibrated_window(qtbot, settings, tmp_path)
    plan = w.capture.plan()
    with answering(default=True):
        w.close()
    write_calibration(path, capture_identity(w.service), K=plan.K, period_us=plan.period_us, rms=0.2, overwrite=True)
    again = truth_window(qtbot, settings)
    top = again.capture.calibration_panel.status_label.text()
    assert "calibrated" in top and "the file changed since it was last used" in top
    with answering(default=True):
        again.close()
