"""The operator's path through the window on the simulated rig, by its buttons:
calibrate → use for capture → record → open in Review → reconstruct.

The simulated rig is the one ``flexvox app`` opens (a projector twice as fine as the camera behind a hidden
homography, a trigger offset that is not a whole slot), with a strobe in front of it so the recording says
which slot every pixel sampled. Its clock is virtual, so nothing waits for real time.
"""

import re

import numpy as np
import pytest
from PySide6.QtCore import Qt

from flexvox_app.gui.application import build_window
from flexvox_app.gui.widgets.questions import answering
from flexvox_core.recording import open_recording
from flexvox_core.slot_check import slot_accuracy
from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock

FRAMES = 17  # the strobe visits every slot of K = 16 in 17 frames


@pytest.fixture
def window(qtbot, settings, runner):
    rig = open_rig("mock", scene="strobe", subframes=FRAMES * 16, seed=0, clock=VirtualClock())
    w = build_window(rig, settings=settings, runner=runner)  # not qtbot's to close: its close asks, answered here
    w.capture.live_panel.preview_check.setChecked(False)
    yield w
    with answering(default=True):  # whatever it would stop or lose
        w.close()
    w.deleteLater()


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
    return rec, slot_accuracy(rec.normalised_frames(), rec.ground_truth[:], rec.code)


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
    with answering(True) as asked:
        _, slots = record(qtbot, capture, tmp_path / "uncalibrated.zarr")
    assert [q.accept for q in asked] == ["Record uncalibrated"]  # Record asked before recording uncalibrated
    assert slots.accuracy < 0.5, slots.describe()


def test_the_cli_and_the_workspace_record_the_same_phase_from_one_calibration_file(qtbot, window, tmp_path):
    from flexvox_app.cli.main import main

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
    cli_slots = slot_accuracy(by_cli.normalised_frames(), by_cli.ground_truth[:], by_cli.code)
    assert cli_slots.accuracy == 1.0


SESSION_FRAMES = 10


def test_the_operator_s_whole_session_through_the_buttons_at_1280x800(qtbot, settings, runner, tmp_path):
    """Connect, calibrate, the sync wizard, save, use for capture, code, live view with preview,
    record, open in Review, diffusion, motion-aware, the slider, the motion overlay, compare, export, cancel,
    quit — checking what the operator checks: the actions in view at 1280×800, no clipped text, a layout that
    does not move, the export equal to what is shown, and nothing left running."""
    import zarr

    from flexvox_app.gui.operator_session import SIZE, OperatorSession, clipped, flexvox_threads, outside_view
    from flexvox_core.methods import Method

    rig = open_rig("mock", scene="drummer", camera_size=(60, 80), subframes=4 * SESSION_FRAMES * 16, seed=0,
                   clock=VirtualClock())
    window = build_window(rig, settings=settings, runner=runner)
    qtbot.addWidget(window)
    assert window.tabs.currentWidget() is window.calibrate  # a first start opens where the path starts
    window.resize(*SIZE)
    window.show()
    qtbot.waitExposed(window)
    s = OperatorSession(window, tmp_path)
    cal, capture, review = window.calibrate, window.capture, window.review
    layout = []  # where the workspaces start: the Devices dock must not push them sideways

    def check(actions, labels):
        s.settle()
        assert window.size().toTuple() == SIZE
        layout.append((window.devices.width(), window.tabs.mapTo(window, window.tabs.rect().topLeft()).x()))
        assert outside_view(window, actions) == []
        assert clipped(labels) == []

    s.connect_devices()
    assert all("enabled" in window.devices.state_text(r) for r in ("projector", "camera", "sync"))
    s.calibrate()
    check([cal.run_button, cal.save_panel.save_button, cal.save_panel.use_button, cal.wizard_button],
          [cal.step_label, cal.save_panel.label])
    verdicts = s.sync_wizard()
    assert re.search(r"3 triggered frames arrived \(camera frame numbers \d+, \d+, \d+; the camera numbers every "
                     r"frame, and 1 before each was skipped while the pattern settled\); mean level [\d.]+ in "
                     r"relative units", verdicts["Trigger test"]), verdicts["Trigger test"]
    assert "The Calibrate run measured" in verdicts["Phase sweep"]  # and why the two delays differ
    assert "saved" in verdicts["Save"]
    saved = s.save_calibration()
    s.use_for_capture()
    assert window.tabs.currentWidget() is capture
    assert "calibrated" in capture.calibration_panel.status_label.text()
    s.choose_code((4, 4))
    s.live_view(frames=6, previews=1)
    panel = capture.record_panel
    check([capture.live_panel.live_button, panel.record_button, panel.stop_button, panel.review_button],
          [capture.calibration_panel.status_label, capture.live_panel.live_label, panel.counters_label,
           panel.recording_label])
    assert "fps" in capture.live_panel.live_label.text() and "dropped" in capture.live_panel.live_label.text()
    s.record(SESSION_FRAMES)
    from flexvox_calibration.capture_setup import file_sha256

    named = open_recording(s.recording_path).attrs["calibration"]  # the recording names the file it used
    assert named["sha256"] == file_sha256(saved) and named["source"].startswith(f"{saved} (sha256 ")
    check([panel.record_button, panel.review_button], [panel.counters_label, panel.recording_label])
    assert panel.review_button.isEnabled()

    s.open_in_review()
    assert window.tabs.currentWidget() is review
    diffusion = s.reconstruct("diffusion", position=0.18)
    motion = s.reconstruct("motion-aware")
    assert motion.flow is not None and diffusion.video.shape == motion.video.shape == (SESSION_FRAMES * 16, 60, 80)
    check([review.open_button, review.reconstruct_button, review.cancel_button, review.export_button],
          [review.path_label, review.summary_label, review.expected_label, review.result_label, review.frame_label])
    # timed here (off the GUI thread, first use only), not read off the bench table
    qtbot.waitUntil(lambda: "on this machine" in review.expected_label.text(), timeout=30_000)
    # The slider, without leaving motion-aware: a fixed tensor's preview beside the motion-aware result (point 6).
    s.go_to(4 * 16 + 5)
    preview = s.slide(0.8)
    assert review.form.method_box.currentText() == "motion-aware" and review.form.comparing
    assert preview.extra["preview"] and preview.method.name == "diffusion" and review.comparison is preview
    assert review.shown is motion and review.slider_panel.isVisible() and review.recon_panel.has_image()
    assert review.recon_panel.title.text().startswith(f"reconstruction: {motion.method.label()}")
    assert review.slider_panel.title.text().startswith(f"slider preview: {preview.method.label()}")
    assert "beside the motion-aware result for comparison" in review.form.slider_text.text()
    # The Motion tab keeps the full motion-aware result while the diffusion preview shows.
    s.motion_overlay("color")
    mv = review.motion_view
    assert review.flow_result() is motion and mv.flow_panel.has_image() and mv.map_panel.colorbar.isVisible()
    assert "sub-frame 70/160" in mv.note.text() and review.frame_label.text().endswith("sub-frame 70/160")
    s.motion_overlay("quiver")
    assert "colour saturates" not in mv.note.text()
    check([review.export_button], [mv.note])
    s.compare()
    check([review.export_button], [review.compare_view.box_a, review.compare_view.box_b])
    # Export what the reconstruction panel shows: the motion-aware result, over every frame.
    path, written = s.export("shown.zarr")
    assert written is motion
    store = zarr.open_group(str(path), mode="r")
    np.testing.assert_array_equal(store["video"][:], written.video)
    assert Method(**store.attrs["flexvox"]["method"]) == motion.method
    assert motion.method.label() in review.export_label.text()
    check([review.export_button], [review.export_label])
    # Back from the slider's preview: the result itself, not a preview of it.
    review.form.stop_comparing()
    s.wait_preview()
    assert review.shown is motion and review.comparison is None and not review.slider_panel.isVisible()
    assert review.recon_panel.title.text().startswith("reconstruction: ")
    # Cancel says so at once, then goes idle with nothing kept.
    n = len(review.results)
    job = s.cancel("motion-aware")
    assert job.outcome == "cancelled" and "cancelling" in s.cancelling_text and len(review.results) == n
    assert "cancelled" in review.result_label.text() and review.reconstruct_button.isEnabled()
    assert len(set(layout)) == 1, layout  # the dock's width and the workspaces' place never moved
    asked = s.quit()  # the result not exported is named before it is lost
    assert [q.title for q in asked] == ["Quit flexvox?"]
    assert f"1 reconstruction not exported is lost: {diffusion.method.label()}" in asked[0].text
    assert not window.isVisible() and not capture.live and not capture.recording
    assert runner.pool.activeThreadCount() == 0 and capture.live_panel.preview.runner.pool.activeThreadCount() == 0
    assert flexvox_threads() == []
    assert all(window.service.status(r).state.value == "closed" for r in ("projector", "camera", "sync"))


# ---------------------------------------------------------------------- the operator's session, second pass
def wheel(widget, clicks: int = -1) -> None:
    """Turn the mouse wheel ``clicks`` notches over the middle of ``widget`` (negative: towards the operator)."""
    from PySide6.QtCore import QPoint, QPointF
    from PySide6.QtGui import QWheelEvent
    from PySide6.QtWidgets import QApplication

    pos = QPointF(widget.width() / 2, widget.height() / 2)
    event = QWheelEvent(pos, QPointF(widget.mapToGlobal(pos.toPoint())), QPoint(), QPoint(0, 120 * clicks),
                        Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def value_widgets(root):
    """Every spin box, combo box and slider under ``root`` an operator can reach, with its value."""
    from PySide6.QtWidgets import QAbstractSlider, QAbstractSpinBox, QComboBox, QScrollBar

    found = []
    for kind in (QAbstractSpinBox, QComboBox, QAbstractSlider):
        found += [w for w in root.findChildren(kind) if not isinstance(w, QScrollBar) and w.isEnabled()]
    return found


def value_of(w):
    from PySide6.QtWidgets import QComboBox

    return w.currentIndex() if isinstance(w, QComboBox) else w.value()


def shown_window(qtbot, window, size=(1280, 800)):
    window.resize(*size)
    window.show()
    window.activateWindow()  # clicks give the focus in the active window
    qtbot.waitUntil(window.isActiveWindow)
    return window


def test_the_wheel_scrolls_the_column_and_changes_only_the_box_clicked_into(qtbot, window):
    """Point 1: scrolling the Capture column over its boxes changes none of them; the column scrolls instead."""
    from PySide6.QtWidgets import QLineEdit

    shown_window(qtbot, window)
    window.show_workspace("Capture")
    capture = window.capture
    capture.code.resolutions.set_expanded(True)
    capture.record_panel.options.set_expanded(True)
    widgets = value_widgets(capture)
    names = {type(w).__name__ for w in widgets}
    assert {"QDoubleSpinBox", "QSpinBox", "QComboBox"} <= names and len(widgets) >= 6, names
    column = capture.controls_scroll
    bar = column.verticalScrollBar()
    assert bar.maximum() > 0  # the column scrolls at 1280×800
    for w in widgets:
        in_column = column.widget().isAncestorOf(w)
        if in_column:
            column.ensureWidgetVisible(w)
            bar.setValue(0 if bar.value() > bar.maximum() // 2 else bar.maximum())  # room to scroll either way
        before, top = value_of(w), bar.value()
        edit = w.findChild(QLineEdit)  # a spin box's text: the pointer is over it
        for target in (w,) if edit is None else (w, edit):
            wheel(target, -3 if top == 0 else +3)
        assert value_of(w) == before, f"the wheel changed {type(w).__name__} {w.accessibleName()!r}"
        if in_column:
            assert bar.value() != top, f"the column did not scroll over {type(w).__name__}"
    rate = capture.code.rate
    capture.controls_scroll.ensureWidgetVisible(rate)
    assert rate.value() == 15.0
    qtbot.mouseClick(rate, Qt.MouseButton.LeftButton)  # the operator clicks into it: now the wheel is its
    assert rate.hasFocus()
    wheel(rate, -3)
    assert rate.value() == pytest.approx(12.0)


def test_a_plan_at_another_timing_says_so_on_top_and_record_asks(qtbot, window, tmp_path):
    """Point 1: the top line says "calibrated" only while the plan matches what the sync was measured at."""
    from flexvox_app.gui.models.capture_calibration import capture_identity
    from flexvox_app.gui.widgets.rich_text import AMBER

    from .conftest import write_calibration

    capture = window.capture
    plan = capture.plan()
    cal = write_calibration(tmp_path / "cal.json", capture_identity(window.service), K=plan.K,
                            period_us=plan.period_us, phase=6)
    assert capture.load_calibration(cal)
    top = capture.calibration_panel.status_label
    assert top.text().startswith("<b>calibrated</b>: phase 6") and AMBER not in top.text()
    capture.code.rate.setValue(13.0)  # what the wheel did: another pattern period than the sync's
    assert "calibrated at another timing" in top.text() and AMBER in top.text()
    assert "phase 6 is a guess" in top.text()
    capture.record_panel.path_edit.setText(str(tmp_path / "guess.zarr"))
    capture.record_panel.frames_box.setValue(2)
    with answering(False) as asked:
        click(qtbot, capture.record_panel.record_button)
    assert [q.title for q in asked] == ["Record at another timing than the sync was measured at?"]
    assert asked[0].text.startswith("The sync was measured at K = 16, 4166 µs patterns; this capture is K = 16, "
                                    "4807 µs: phase 6 is a guess, run the calibration or the synchronisation wizard "
                                    "in Calibrate at this timing")
    assert not capture.recording
    assert not (tmp_path / "guess.zarr").exists()
    with answering(True) as asked, qtbot.waitSignal(capture.recording_finished, timeout=30_000):
        click(qtbot, capture.record_panel.record_button)
    assert len(asked) == 1
    capture.record_panel.path_edit.setText(str(tmp_path / "again.zarr"))
    with answering() as asked, qtbot.waitSignal(capture.recording_finished, timeout=30_000):
        click(qtbot, capture.record_panel.record_button)  # asked once: not again
    assert asked == []


def test_a_restart_restores_the_calibration_file_checked_and_named_by_its_hash(qtbot, settings, tmp_path):
    """Points 2 and 3: the calibration file in use comes back at the next start, checked against the rig and named
    by its path and content hash in the recording; one that cannot come back is named with the reason, and then
    Record asks once before recording uncalibrated."""
    from flexvox_app.gui.models.capture_calibration import capture_identity
    from flexvox_calibration.capture_setup import file_sha256

    from .conftest import write_calibration

    def start():
        rig = open_rig("mock", scene="strobe", subframes=FRAMES * 16, seed=0, clock=VirtualClock())
        w = build_window(rig, settings=settings)  # a runner of its own: closing the window shuts it down
        qtbot.addWidget(w)
        w.capture.live_panel.preview_check.setChecked(False)
        return w

    first = start()
    plan = first.capture.plan()
    path = write_calibration(tmp_path / "cal.json", capture_identity(first.service), K=plan.K,
                             period_us=plan.period_us)
    assert first.capture.load_calibration(path)
    first.close()

    second = start()
    cal = second.capture.calibration
    digest = file_sha256(path)
    assert cal is not None and cal.sha256 == digest and cal.source == f"{path} (sha256 {digest[:16]})"
    assert f"restored at start: {path}, checked against this rig" in second.capture.calibration_panel.label.text()
    rec, _ = record(qtbot, second.capture, tmp_path / "restored.zarr")
    assert rec.attrs["calibration"]["sha256"] == digest and str(path) in rec.attrs["calibration"]["source"]
    second.close()

    write_calibration(path, capture_identity(second.service), K=plan.K, period_us=plan.period_us, rms=0.2,
                      overwrite=True)  # the file changed behind the app's back
    third = start()
    assert third.capture.calibration.sha256 == file_sha256(path) != digest
    assert "the file changed since it was last used" in third.capture.calibration_panel.label.text()
    third.close()

    path.unlink()
    fourth = start()
    capture = fourth.capture
    assert capture.calibration is None
    error = capture.calibration_panel.status_label.text()
    assert "the calibration last used was not restored" in error and "cal.json: no such file" in error
    with answering(True) as asked:
        record(qtbot, capture, tmp_path / "uncalibrated.zarr")
    assert [q.title for q in asked] == ["Record uncalibrated?"]
    with answering() as asked:  # once: not again
        record(qtbot, capture, tmp_path / "uncalibrated-2.zarr")
    assert asked == []
    fourth.close()


def test_closing_asks_first_naming_what_would_stop_or_be_lost(qtbot, settings, tmp_path):
    """Point 4: closing during a recording or a calibration, or with results not exported, asks first."""
    from .conftest import small_rig

    window = build_window(small_rig(), settings=settings)  # real time: the recording runs while the window closes
    qtbot.addWidget(window)
    capture = window.capture
    capture.live_panel.preview_check.setChecked(False)
    capture.code.rate.setValue(60.0)
    capture.clear_calibration()
    path = tmp_path / "long.zarr"
    capture.record_panel.path_edit.setText(str(path))
    capture.record_panel.frames_box.setValue(6000)  # 100 s: far longer than the test
    with qtbot.waitSignal(capture.record_panel.started, timeout=20_000):
        assert capture.record()
    qtbot.waitUntil(lambda: capture.capture.stats().rows_written >= 3, timeout=20_000)
    window.show()
    with answering(False) as asked:
        window.close()
    assert window.isVisible() and capture.recording  # "Keep working": nothing stopped
    assert asked[0].title == "Quit flexvox?" and asked[0].accept == "Quit"
    assert f"the recording to {path} stops (" in asked[0].text and "frames written so far are kept" in asked[0].text
    with answering(True):
        window.close()
    assert not window.isVisible() and not capture.recording
    assert open_recording(path).n_frames >= 3  # what was written is kept

    second = build_window(open_rig("mock", scene="strobe", subframes=FRAMES * 16, seed=0, clock=VirtualClock()),
                          settings=settings)
    qtbot.addWidget(second)
    second.show()
    assert second.calibrate.run_calibration()
    with answering(False) as asked:
        second.close()
    assert second.isVisible() and asked[0].text.startswith("Closing the window now:\n\n• the calibration running "
                                                           "stops; its result is lost")
    qtbot.waitUntil(lambda: not second.calibrate.running, timeout=60_000)
    assert second.calibrate.outcome.success
    with answering(False) as asked:  # a calibration that succeeded and was not saved is lost too
        second.close()
    assert "is not saved: it is lost (the next start restores only a saved calibration)" in asked[0].text
    second.calibrate.save_panel.save(tmp_path / "cal.json")
    with answering() as asked:  # nothing to lose: no question
        second.close()
    assert asked == [] and not second.isVisible()


@pytest.mark.parametrize("folded", [False, True], ids=["devices open", "devices folded"])
def test_at_1024x700_every_primary_action_the_tabs_and_the_scrubber_are_usable(qtbot, window, recording, folded):
    """Point 5: a 1024×700 window holds every workspace's primary actions in view, the Calibrate tabs without scroll
    arrows, images at least 300 px wide and a scrubber across the view that moves the player."""
    from flexvox_app.gui.operator_session import clipped, outside_view, too_wide

    window.device_dock.set_folded(folded)
    shown_window(qtbot, window, (1024, 700))
    assert window.size().toTuple() == (1024, 700)  # no minimum size above it
    assert window.device_dock.width() == (28 if folded else 240)
    cal, capture, review = window.calibrate, window.capture, window.review

    def check(name, actions, labels, images):
        window.show_workspace(name)
        for _ in range(5):
            qtbot.wait(10)
        assert outside_view(window, actions) == []
        assert clipped(labels) == []
        assert too_wide([getattr(window, name.lower()).controls_scroll]) == []
        narrow = [(p.title.text(), p.width()) for p in images if p.width() < 300]
        assert narrow == [], f"{name}: images narrower than 300 px"

    check("Calibrate", [cal.run_button, cal.cancel_button, cal.save_panel.save_button, cal.save_panel.use_button,
                        cal.wizard_button], [cal.step_label, cal.save_panel.label], [cal.results_view.residuals])
    bar = cal.results_view.tabBar()
    for i in range(bar.count()):  # every tab in view: none behind scroll arrows
        assert bar.rect().contains(bar.tabRect(i)), bar.tabText(i)
    panel = capture.record_panel
    check("Capture", [capture.live_panel.live_button, panel.record_button, panel.stop_button, panel.review_button],
          [capture.live_panel.live_label, panel.counters_label, panel.recording_label],
          [capture.live_panel.image_panel, capture.live_panel.preview_panel])
    review.preview_check.setChecked(False)
    review.open_recording(recording)
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    check("Review", [review.open_button, review.reconstruct_button, review.cancel_button, review.export_button,
                     review.play_button, review.frame_slider],
          [review.summary_label, review.expected_label, review.result_label, review.frame_label],
          [review.raw_panel, review.recon_panel])
    slider = review.frame_slider
    assert slider.width() >= 0.9 * review.tabs.width()  # the scrubber spans the view
    before = slider.value()
    qtbot.mouseClick(slider, Qt.MouseButton.LeftButton, pos=slider.rect().center() + slider.rect().topRight() / 3)
    assert slider.value() > before and review.frame_label.text().startswith(f"frame {slider.value() // 8 + 1}/")


def test_the_devices_and_the_refusals_say_what_holds_now(qtbot, window):
    """Point 6: the Devices panel says who holds the devices while a calibration opens and closes them, and gives
    them back connected; a refusal leaves the screen once it no longer holds; a stopped preview does not claim to be
    reconstructing."""
    from flexvox_app.gui.widgets.rich_text import AMBER

    shown_window(qtbot, window)
    panel, dock = window.devices, window.device_dock
    for role in ("projector", "camera", "sync"):
        click(qtbot, panel.rows[role]["button"])
    assert all(panel.state_text(r).startswith("● enabled") for r in ("projector", "camera", "sync"))
    cal, capture = window.calibrate, window.capture
    assert cal.run_calibration()
    for role in ("projector", "camera", "sync"):
        assert panel.state_text(role) == "● in use by the calibration", role
        assert not panel.rows[role]["button"].isEnabled() and AMBER in dock.dots[role].styleSheet()
    window.show_workspace("Capture")
    click(qtbot, capture.live_panel.live_button)
    live = capture.live_panel.live_label
    assert live.text() == "<span style='color:#c0392b'>cannot start: a calibration is running in the Calibrate " \
                          "workspace</span>" and not capture.live
    capture.record_panel.path_edit.setText("")
    click(qtbot, capture.record_panel.record_button)
    assert "choose a recording path first" in capture.record_panel.recording_label.text()
    qtbot.waitUntil(lambda: not cal.running, timeout=60_000)
    assert cal.outcome.success
    assert all(panel.state_text(r).startswith("● enabled") for r in ("projector", "camera", "sync"))  # given back
    assert live.text() == "stopped"  # the calibration ended: the refusal went with it
    capture.record_panel.path_edit.setText("somewhere.zarr")  # the path it was about changed
    assert capture.record_panel.recording_label.text() == "not recorded yet"
    capture.live_panel.preview_check.setChecked(True)
    capture.clear_calibration()
    assert capture.start_live()
    assert capture.live_panel.preview_panel.placeholder_text() == "reconstructing the newest frames …"
    capture.stop_live()  # before its first picture
    assert capture.live_panel.preview_panel.placeholder_text() == "starts with the live view"


def test_a_camera_that_goes_away_is_said_in_the_window_s_words(qtbot, settings, runner):
    """Point 8: the live view's end after the camera went away says what happened and what to do in the window's
    words ("call start_acquisition() first" was shown as it came from the driver)."""
    from .conftest import small_rig

    window = build_window(small_rig(), settings=settings, runner=runner)  # real time: the reader waits on frames
    window.capture.live_panel.preview_check.setChecked(False)
    capture = window.capture
    capture.code.rate.setValue(60.0)
    capture.clear_calibration()
    assert capture.start_live()
    qtbot.waitUntil(lambda: capture.live_panel.stats.received >= 2, timeout=10_000)
    window.service.rig.camera.stop_acquisition()  # unplugged: it delivers nothing more
    qtbot.waitUntil(lambda: not capture.live, timeout=10_000)
    text = capture.live_panel.live_label.text()
    assert "live view stopped: the camera is not delivering frames (it was disconnected, switched off or closed): " \
           "connect it in the Devices panel and start again" in text
    error = window.devices.rows["camera"]["error"].text()
    assert "connect it in the Devices panel" in error and "start_acquisition" not in error + text
    with answering(default=True):
        window.close()


def test_buttons_hold_still_while_status_lines_grow_and_the_method_changes(qtbot, window, recording):
    """Point 10: status lines keep their height (the whole text on hover), so no button moves under the pointer."""
    from PySide6.QtCore import QPoint

    from flexvox_app.gui.widgets.rich_text import RED, coloured

    shown_window(qtbot, window)
    cal, capture, review = window.calibrate, window.capture, window.review
    review.preview_check.setChecked(False)
    review.open_recording(recording)
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    buttons = {"Calibrate": [cal.run_button, cal.cancel_button, cal.save_panel.save_button, cal.save_panel.use_button,
                             cal.wizard_button],
               "Capture": [capture.live_panel.live_button, capture.record_panel.record_button,
                           capture.record_panel.stop_button, capture.record_panel.review_button],
               "Review": [review.reconstruct_button, review.cancel_button, review.export_button, review.play_button]}
    lines = {"Calibrate": [cal.step_label, cal.save_panel.label],
             "Capture": [capture.calibration_panel.status_label, capture.live_panel.live_label,
                         capture.record_panel.counters_label, capture.record_panel.recording_label],
             "Review": [review.path_label, review.summary_label, review.expected_label, review.result_label,
                        review.export_label, review.form.slider_text]}
    long = coloured("cannot record: " + "a reason that goes on and on, " * 20, RED)

    def where(name):
        window.show_workspace(name)
        for _ in range(5):
            qtbot.wait(10)
        return [b.mapTo(window, QPoint(0, 0)).toTuple() for b in buttons[name]]

    for name in buttons:
        before = where(name)
        if name == "Review":
            for method in ("gap-tv", "diffusion", "motion-aware", "rebin"):  # the slider's line changes with it
                review.form.set_method_name(method)
                assert where(name) == before, method
        for line in lines[name]:
            line.setText(long)
        assert where(name) == before, name
        for line in lines[name]:
            assert line.text() == long and line.elided and line.toolTip() == long  # all of it on hover


def test_the_window_s_frame_fits_a_1024x700_screen_with_its_status_bar_and_capture_s_details_get_room(qtbot, window):
    """A 1280×800 window (or one restored so) on a 1024×700 screen whose window manager adds a title bar: the
    whole frame fits, the status bar is on screen, and Capture's scrolled details keep a useful height."""
    from PySide6.QtCore import QMargins, QPoint, QRect

    shown_window(qtbot, window, (1280, 800))
    window.move(40, 60)
    window.device_dock.set_folded(True)
    screen, frame = QRect(0, 0, 1024, 700), QMargins(1, 29, 1, 1)  # a title bar and a border
    window.fit_to_screen(screen, frame)
    outer = QRect(window.frameGeometry().topLeft(), window.size().grownBy(frame))
    assert screen.contains(outer), (outer, screen)
    assert window.size().toTuple() == (1022, 670) and window.minimumSizeHint().height() <= 670
    bar = window.statusBar()
    assert bar.isVisible() and bar.mapTo(window, QPoint(0, bar.height())).y() <= window.height()
    window.show_workspace("Capture")
    for _ in range(5):
        qtbot.wait(10)
    details = window.capture.controls_scroll.viewport().height()
    assert details >= 120, f"Capture's details get {details} px at 1024×700"
    window.fit_to_screen(screen, frame)  # fitting again changes nothing
    assert window.size().toTuple() == (1022, 670)
