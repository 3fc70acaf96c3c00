"""The Calibrate workspace and the synchronisation wizard, driven end to end on the simulated rig."""

import re

import numpy as np
import pytest

from flexvox_app.gui.calibrate.workspace import CalibrateWorkspace
from flexvox_app.gui.models.calibration_model import (
    CalibrationTarget,
    run_workspace_calibration,
    summary_rows,
    target_for,
)
from flexvox_app.gui.models.holder import Holder
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.questions import Question, answering
from flexvox_calibration.files import load_calibration
from flexvox_calibration.sync import load_sync_profile
from rig_drivers.simulated_target import hidden_timing
from tests.rig_drivers.mock_rigs import calibration_rig

from .conftest import small_rig
from .widget_helpers import truth_window

SEED = 0


@pytest.fixture
def calibrate(qtbot, settings, runner):
    # The simulated rig of seed 0 at 120x160 on a virtual clock (calibration takes no real time).
    ws = CalibrateWorkspace(RigService(calibration_rig(SEED)), settings, runner)
    qtbot.addWidget(ws)
    ws.resize(1300, 850)
    yield ws
    ws.shutdown()


def test_who_holds_the_rig_has_one_name_and_the_old_names_warn(qtbot, settings, runner):
    """``held_elsewhere`` (what ``rig_guard`` was) refuses a run and the live numbers in its words; ``held_here`` and
    ``holder`` say what this workspace holds; the old names work one more release, warned."""
    recording = "a recording is running in the Capture workspace"
    asked = []

    def held_elsewhere():
        asked.append(1)
        return recording

    with pytest.warns(DeprecationWarning, match=r"`rig_guard` of CalibrateWorkspace is deprecated and will be removed "
                                                r"in the next release: call it `held_elsewhere`"):
        ws = CalibrateWorkspace(RigService(calibration_rig(SEED)), settings, runner, rig_guard=held_elsewhere)
    qtbot.addWidget(ws)
    assert ws.held_elsewhere() == recording and ws.held_here() is None and ws.holder is Holder.IDLE
    assert not ws.run_calibration() and ws.step_label.text() == f"<span style='color:#c0392b'>cannot start: " \
                                                                f"{recording}</span>"
    ws.live_panel.set_live(True)
    assert not ws.live_panel.live and ws.live_panel.label.text().endswith(f"cannot measure: {recording}</span>")
    assert len(asked) == 3 and ws.service.holder is Holder.IDLE
    with pytest.warns(DeprecationWarning, match=r"CalibrateWorkspace\.rig_busy_reason\(\) is deprecated .*: call "
                                                r"CalibrateWorkspace\.held_here\(\)$"):
        assert ws.rig_busy_reason() is None
    with pytest.warns(DeprecationWarning, match=r"CalibrateWorkspace\.rig_guard is deprecated .*: call "
                                                r"CalibrateWorkspace\.held_elsewhere\(\)$"):
        assert ws.rig_guard is held_elsewhere
    with pytest.warns(DeprecationWarning, match=r"CalibrateWorkspace\.rig_guard is deprecated .*: call "
                                                r"CalibrateWorkspace\(held_elsewhere=\)$"):
        ws.rig_guard = None
    assert ws.held_elsewhere() is None
    ws.service.begin_use("the synchronisation wizard")  # as the wizard holds the devices
    assert ws.held_here() == "the synchronisation wizard uses the devices (Calibrate workspace)"
    assert ws.holder is Holder.CALIBRATING and ws.service.holder is Holder.CALIBRATING
    ws.service.end_use("the synchronisation wizard")
    assert ws.held_here() is None and ws.holder is Holder.IDLE
    ws.shutdown()
    with pytest.warns(DeprecationWarning, match=r"`rig_guard` of CalibrateWorkspace"), \
            pytest.raises(TypeError, match=r"CalibrateWorkspace got `held_elsewhere` and its deprecated name "
                                           r"`rig_guard`: give `held_elsewhere` alone"):
        CalibrateWorkspace(ws.service, settings, runner, held_elsewhere=held_elsewhere, rig_guard=held_elsewhere)
    with pytest.raises(TypeError, match=r"CalibrateWorkspace\(\) got unexpected keywords guard$"):
        CalibrateWorkspace(ws.service, settings, runner, guard=held_elsewhere)


def _run(qtbot, ws):
    assert ws.run_calibration()
    assert not ws.run_button.isEnabled() and ws.cancel_button.isEnabled()
    qtbot.waitUntil(lambda: not ws.running, timeout=30_000)


def test_calibration_runs_off_the_gui_thread_shows_its_figures_and_saves(qtbot, calibrate, tmp_path):
    ws = calibrate
    steps_seen = set()
    with qtbot.waitSignal(ws.calibrated, timeout=30_000) as done:
        assert ws.run_calibration()
        qtbot.waitUntil(lambda: ws.tracker.step != "", timeout=10_000)
        while ws.running:
            steps_seen.add(ws.tracker.step)
            qtbot.wait(5)
    outcome = done.args[0]
    assert outcome.success and ws.outcome is outcome
    assert {"co-location", "homography"} & steps_seen  # progress named the steps as they ran
    truth_phase, truth_delay = hidden_timing(SEED)
    assert outcome.sync.phase_slots == truth_phase and abs(outcome.sync.delay_us - truth_delay) < 200
    assert outcome.truth["homography_error_px"] < 0.05
    text = ws.results_view.results.text()
    for phrase in ("calibration succeeded", "Co-location", "co-located: one homography fits all 2 depths",
                   "RMS reprojection error", "coverage (decoded)", "inliers / decoded", "slot accuracy",
                   "Synchronisation", "Drops and drift", "no gaps", "hidden truth"):
        assert phrase in text, phrase
    assert f"{truth_phase} / {truth_phase}" in text  # phase found / true
    # the time it took, then what to do (it read "save it in 30.2 s", a deadline); the two phases say which is which
    assert re.search(r"calibration succeeded in [\d.]+ s at \d\d:\d\d:\d\d</b>: save it, or use it for capture", text)
    assert "phase with no camera delay (exposure slot 0 sees slot)" in text
    assert "phase the shutter patterns use, with that delay" in text
    assert "calibration succeeded" in ws.step_label.text() and ws.run_button.isEnabled()
    # residual heat map with a colour map, and the map of wrong pixels
    assert ws.results_view.residuals.image.image.shape == (120, 160) and ws.results_view.residuals.colorbar is not None
    assert re.search(r"RMS 0\.\d{3} px, 100\.0% decoded", ws.results_view.residuals.title.text())
    assert ws.results_view.wrong_panel.image.image.shape == (120, 160, 3)
    assert "0 camera pixels see another slot" in ws.results_view.wrong_panel.title.text()
    x, h = ws.results_view.leakage_bars.opts["x"], ws.results_view.leakage_bars.opts["height"]
    assert len(x) == 16 and h[truth_phase + 1] > 0.9 and h[max(truth_phase - 1, 0)] < 0.1
    # save
    assert ws.save_panel.save_button.isEnabled()
    assert ws.save_panel.save("") is None and "choose where to save" in ws.save_panel.label.text()
    path = tmp_path / "cal.json"
    ws.save_panel.path.setText(str(path))
    ws.save_panel.save_button.click()
    assert "saved" in ws.save_panel.label.text()
    data = load_calibration(path, outcome.identity)
    np.testing.assert_allclose(data["H"], outcome.homography.homography)
    assert data["sync"]["phase_slots"] == truth_phase
    # Point 9, one rule for existing files: ask, naming the file (a second Save replaced it unasked)
    before = path.read_bytes()
    with answering(False) as asked:
        ws.save_panel.save_button.click()
    assert asked == [Question("Replace the existing calibration?",
                              f"{path} already exists. Replace it with the new calibration?", "Replace")]
    assert f"not saved: {path} is kept" in ws.save_panel.label.text() and path.read_bytes() == before
    with answering(True):
        ws.save_panel.save_button.click()
    assert f"saved {path}" in ws.save_panel.label.text()


def test_cancel_stops_between_steps_and_keeps_nothing(qtbot, calibrate):
    ws = calibrate
    assert ws.run_calibration()
    qtbot.waitUntil(lambda: ws.tracker.index >= 1, timeout=10_000)  # past the co-location step
    ws.cancel_button.click()
    assert ws.step_label.text() == "cancelling …"
    qtbot.waitUntil(lambda: not ws.running, timeout=20_000)
    assert re.fullmatch(r"cancelled during (parallax: near target|parallax: far target|homography|shutter|sync)"
                        r"; the devices were stopped", ws.step_label.text())
    assert ws.outcome is None and not ws.save_panel.save_button.isEnabled() and ws.run_button.isEnabled()
    assert "nothing to save (the new run was cancelled)" in ws.save_panel.label.text()
    assert ws.save_panel.save("x.json") is None and "nothing to save" in ws.save_panel.label.text()


def test_a_cancelled_second_run_keeps_the_first_result_and_the_bar_never_goes_back(qtbot, calibrate, tmp_path):
    """Point 6: the bar fills once over the whole run (it restarted at every step); a second run that is cancelled
    leaves the first result shown, offered and savable (it said "succeeded" beside "nothing to save")."""
    ws = calibrate
    seen = []
    ws.progress.valueChanged.connect(lambda v: seen.append((v, ws.progress.maximum())) if ws.running else None)
    _run(qtbot, ws)
    first = ws.outcome
    assert first.success and first.finished_at
    run = [v for v, top in seen if top == 6000]
    assert len(run) > 10 and run == sorted(run) and run[-1] >= 5000, run  # one bar, never going back
    assert ws.progress.value() == ws.progress.maximum()
    assert ws.run_calibration()
    assert not ws.save_panel.save_button.isEnabled() and not ws.save_panel.use_button.isEnabled()  # running
    assert f"shown: the calibration of {first.finished_at}" in ws.results_view.results.text()
    qtbot.waitUntil(lambda: ws.tracker.index >= 1, timeout=10_000)
    ws.cancel_button.click()
    qtbot.waitUntil(lambda: not ws.running, timeout=20_000)
    assert ws.outcome is first and ws.save_panel.save_button.isEnabled() and ws.save_panel.use_button.isEnabled()
    text = ws.results_view.results.text()
    assert f"the new run was cancelled; shown: the calibration of {first.finished_at}" in text
    assert "calibration succeeded" in text
    assert (f"the new run was cancelled; the calibration of {first.finished_at} can still be saved"
            in ws.save_panel.label.text())
    path = ws.save_panel.save(tmp_path / "first.json")
    np.testing.assert_allclose(load_calibration(path, first.identity)["H"], first.homography.homography)


def test_a_rig_that_is_not_co_located_is_reported_and_not_saved(qtbot, calibrate):
    """The projector 30 % of the target distance off the camera's axis: the parallax test fails."""
    ws = calibrate
    target = CalibrationTarget(calibration_rig(SEED, baseline=(0.3, 0.0, 0.0)), True)
    outcome = run_workspace_calibration(target)
    assert not outcome.success and outcome.report["failed"] == "colocation"
    ws.show_outcome(outcome)
    text = ws.results_view.results.text()
    assert "✗ not co located" in text and "NOT co-located" in text and "move the projector" in text
    assert not ws.save_panel.save_button.isEnabled()
    assert "not saved: the colocation step failed" in ws.save_panel.label.text()
    assert ws.results_view.wrong_panel.placeholder_text() == "the run stopped before the shutter step"
    titles = [row[0] for row in summary_rows(outcome)]
    assert "Homography" not in titles and "Parallax (co-located?)" in titles


def test_live_co_location_numbers_update_on_a_timer(qtbot, calibrate):
    ws = calibrate
    ws.live_panel.check.setChecked(True)
    qtbot.waitUntil(lambda: ws.live_panel.alignment is not None, timeout=20_000)
    first = ws.live_panel.alignment
    qtbot.waitUntil(lambda: ws.live_panel.alignment is not first, timeout=20_000)  # measured again
    text = ws.live_panel.label.text()
    assert ws.live_panel.alignment.success and "offset" in text and "rotation" in text
    assert text.count("offset") == 1 and text.count("rotation") == 1 and text.count("scale") == 1  # said once
    assert abs(ws.live_panel.alignment.scale - 0.645) < 0.01
    ws.live_panel.check.setChecked(False)
    qtbot.waitUntil(lambda: ws.live_panel.job is None or not ws.live_panel.job.running, timeout=10_000)
    assert ws.live_panel.label.text().startswith("stopped · last: offset")
    assert ws.run_calibration()  # the live numbers are off: a calibration may start
    qtbot.waitUntil(lambda: not ws.running, timeout=30_000)


def test_sync_wizard_end_to_end(qtbot, calibrate, tmp_path):
    from PySide6.QtWidgets import QWizard

    ws = calibrate
    wizard = ws.open_sync_wizard()  # a child of the workspace, deleted when closed
    truth_phase, _ = hidden_timing(SEED)
    # 1. wiring checklist: Next only when every box is ticked
    next_button = wizard.button(QWizard.WizardButton.NextButton)
    assert wizard.currentPage() is wizard.wiring and not next_button.isEnabled()
    for box in wizard.wiring.boxes:
        box.setChecked(True)
    assert next_button.isEnabled()
    wizard.next()
    # 2. trigger test
    assert wizard.currentPage() is wizard.trigger and not next_button.isEnabled()
    wizard.trigger.button.click()
    qtbot.waitUntil(wizard.trigger.isComplete, timeout=10_000)
    verdict = wizard.trigger.verdict.text()
    assert "3 triggered frames arrived (camera frame numbers " in verdict and "–" not in verdict  # the ids, no range
    assert "skipped while the pattern settled" in verdict
    assert "in relative units (a white target seen through" in verdict
    wizard.next()
    # 3. phase sweep (no homography from the workspace yet: the page measures one first)
    assert wizard.homography is None
    wizard.phase.button.click()
    qtbot.waitUntil(wizard.phase.isComplete, timeout=30_000)
    assert wizard.sync.phase_slots == truth_phase and f"sees projected slot {truth_phase}" in \
        wizard.phase.verdict.text()
    assert len(wizard.phase.bars.opts["height"]) == 16 and len(wizard.phase.points.getData()[0]) == 8
    for plot, bottom, left in ((wizard.phase.leakage, "projected slot", "fraction of the slot's light"),
                               (wizard.phase.sweep, "camera trigger delay (µs)", "slots of light lost")):
        item = plot.getPlotItem()
        assert item.getAxis("bottom").labelText == bottom and item.getAxis("left").labelText == left
        title = item.titleLabel
        assert title.item.boundingRect().width() <= plot.width()  # the title fits its plot
    wizard.next()
    # 4. drops and drift
    wizard.drift.button.click()
    qtbot.waitUntil(wizard.drift.isComplete, timeout=20_000)
    assert wizard.frame_check.success and "no gaps" in wizard.drift.verdict.text()
    wizard.next()
    # 5. save
    assert wizard.currentPage() is wizard.save_page
    assert wizard.save_page.save("") is None and "choose where to save" in wizard.save_page.label.text()
    path = tmp_path / "sync.json"
    wizard.save_page.path.setText(str(path))
    wizard.save_page.button.click()
    assert "saved" in wizard.save_page.label.text()
    data = load_sync_profile(path, wizard.identity)
    assert data["sync"]["phase_slots"] == truth_phase and data["frame_check"]["status"] == "ok"
    with answering(False) as asked:  # the one rule for an existing file
        wizard.save_page.button.click()
    assert [q.text for q in asked] == [f"{path} already exists. Replace it with the new sync profile?"]
    assert f"not saved: {path} is kept" in wizard.save_page.label.text()
    with qtbot.waitSignal(wizard.destroyed, timeout=5000):
        wizard.accept()
    again = ws.open_sync_wizard()  # the Save page offers the last profile's path
    assert again.save_page.path.text() == str(path)
    again.reject()


def test_trigger_test_says_when_the_camera_is_not_triggered(qtbot, runner):
    from flexvox_app.gui.calibrate.sync_wizard import SyncWizard
    from flexvox_calibration.session import RigSession
    from rig_drivers.interfaces import TriggerConfig, TriggerSource

    class Miswired(CalibrationTarget):
        """TRIG_OUT_2 goes to Line2; the camera listens on Line0."""

        def session(self):
            return RigSession.from_rig(self.rig, trigger=TriggerConfig(source=TriggerSource.LINE0), timeout_s=0.3)

    target = Miswired(calibration_rig(SEED, camera_line=TriggerSource.LINE2), True)
    wizard = SyncWizard(target, runner)
    qtbot.addWidget(wizard)
    wizard.trigger.start()
    qtbot.waitUntil(lambda: wizard.trigger.job is not None and not wizard.trigger.job.running, timeout=20_000)
    assert not wizard.trigger.isComplete()
    assert "the camera is not triggered by the projector" in wizard.trigger.verdict.text()


def test_target_for_the_simulated_rig_is_the_rig_capture_uses():
    service = RigService(small_rig(seed=3))
    target = target_for(service)
    assert target.simulated and target.rig is service.rig and target.seed == 3
    assert target.rig.simulated.truth.phase_slots == hidden_timing(3)[0]
    target.session()  # a calibration session puts the calibration target in view
    assert service.rig.simulated.viewing == "target"


def test_the_sync_wizard_s_finish_with_an_unsaved_sweep_asks_as_cancel_does(qtbot, settings):
    from types import SimpleNamespace

    from flexvox_app.gui.application import build_window
    from flexvox_app.gui.widgets.questions import answering
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    w = build_window(open_rig("mock", scene="balls", subframes=64, clock=VirtualClock()), settings=settings)
    qtbot.addWidget(w)
    w.show_workspace("Calibrate")
    wizard = w.calibrate.open_sync_wizard()
    wizard.sync = SimpleNamespace(success=True, effective_phase_slots=6, recommended_camera_delay_us=412.0)
    with answering(False) as asked:  # Finish on the Save page, the sweep not saved
        wizard.accept()
    assert wizard.isVisible() and asked[0].title == "Close the synchronisation wizard?"
    assert "the phase sweep's result (phase 6, camera trigger delay 412 µs)" in asked[0].text
    with answering(True):
        wizard.accept()
    assert not wizard.isVisible()
    with answering(default=True):
        w.close()


def test_the_sync_wizard_asks_before_cancel_loses_work_has_browse_and_its_profile_reaches_capture(
        qtbot, settings, tmp_path):
    from types import SimpleNamespace

    w = truth_window(qtbot, settings)
    w.show_workspace("Calibrate")
    wizard = w.calibrate.open_sync_wizard()
    assert wizard.save_page.browse_button.text() == "Browse…"
    wizard.sync = SimpleNamespace(success=True, effective_phase_slots=6, recommended_camera_delay_us=412.0)
    wizard.frame_check = object()
    with answering(False) as asked:
        wizard.reject()
    assert wizard.isVisible() and asked[0].title == "Close the synchronisation wizard?"
    assert "the phase sweep's result (phase 6, camera trigger delay 412 µs)" in asked[0].text
    assert "the drop/drift test's verdict" in asked[0].text
    profile = tmp_path / "sync.json"
    wizard.save_page.written = profile  # as a save would leave it
    statuses = []
    w.calibrate.status.connect(statuses.append)
    with answering() as asked:  # saved: nothing to lose, no question
        wizard.accept()
    assert asked == []
    assert any(str(profile) in s and "Load sync profile" in s for s in statuses), statuses
    assert str(profile) in w.calibrate.wizard_button.toolTip()
    assert f"sync profile saved by the wizard: {profile}" in w.calibrate.profile_label.text()  # the panel says it
    assert f"the synchronisation wizard saved {profile}" in w.capture.calibration_panel.label.text()
    assert "sync profile is not loaded" in w.capture.calibration_panel.status_label.text()
    with answering(default=True):
        w.close()


def test_run_calibration_says_what_it_pauses_before_and_restores_both_after(qtbot, settings, runner):
    from flexvox_app.gui.application import build_window
    from flexvox_app.gui.widgets.questions import answering
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    w = build_window(open_rig("mock", scene="balls", subframes=64, clock=VirtualClock()), settings=settings,
                     runner=runner)
    qtbot.addWidget(w)
    cal, capture = w.calibrate, w.capture
    capture.live_panel.preview_check.setChecked(False)
    assert cal.pause_note.text() == ""
    assert capture.start_live()
    assert cal.pause_note.text() == "Run pauses Capture's live view; it resumes when it ends"  # said before
    assert cal.run_calibration() and not capture.live
    assert cal.pause_note.text() == "paused: Capture's live view (resumed when it ends)"
    qtbot.waitUntil(lambda: not cal.running, timeout=30_000)
    qtbot.waitUntil(lambda: capture.live, timeout=5000)  # restored
    capture.stop_live()
    cal.live_panel.check.setChecked(True)  # "measure continuously"
    assert "Run pauses “measure continuously”; it resumes" in cal.pause_note.text()
    qtbot.waitUntil(lambda: not cal.live_panel.measuring, timeout=10_000)
    assert cal.run_calibration() and not cal.live_panel.check.isChecked()
    qtbot.waitUntil(lambda: not cal.running, timeout=30_000)
    qtbot.waitUntil(cal.live_panel.check.isChecked, timeout=5000)  # ticked again
    cal.live_panel.check.setChecked(False)
    qtbot.waitUntil(lambda: not cal.live_panel.measuring, timeout=10_000)
    with answering(default=True):
        w.close()


def test_the_phase_sweep_bar_only_goes_forward(qtbot, settings):
    from flexvox_app.gui.models.jobs import CancelToken

    w = truth_window(qtbot, settings)
    wizard = w.calibrate.open_sync_wizard()
    wizard.homography = None  # measured on the page first: two parts on one bar
    seen = []
    h, sync, _ = wizard.phase.work(CancelToken(), lambda done, total: seen.append(done / total))
    assert h is not None and sync.success
    assert seen == sorted(seen) and seen[-1] == 1.0 and seen[0] < 0.5, seen
    with answering(default=True):
        wizard.reject()
        w.close()


def test_after_a_cancelled_calibration_the_steps_list_shows_the_run_the_results_show(qtbot, settings):
    from flexvox_app.gui.calibrate.workspace import STEPS, steps_html

    w = truth_window(qtbot, settings)
    cal = w.calibrate
    assert cal.run_calibration()
    qtbot.waitUntil(lambda: not cal.running, timeout=120_000)
    assert cal.outcome.success
    assert cal.run_calibration()
    qtbot.waitUntil(lambda: "▶" in cal.steps_label.text() and steps_html(0) != cal.steps_label.text(),
                    timeout=60_000)
    cal.cancel()
    qtbot.waitUntil(lambda: not cal.running, timeout=60_000)
    assert cal.steps_label.text() == steps_html(len(STEPS), finished=True)  # the earlier run's, as the results
    with answering(default=True):
        w.close()
