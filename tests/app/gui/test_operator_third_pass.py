"""The operator's session, third pass: work is never dropped unasked, the state shown is the state held, where a
result ran is named, and messages are in the operator's words. (The start-up window: ``test_startup.py``.)"""

import html
import shutil

import pytest

from flexvox_app.gui.widgets.questions import answering

from .widget_helpers import reconstruct


# ---------------------------------------------------------------------- opening another recording asks first
def test_opening_another_recording_during_a_run_asks_naming_it_and_keeping_it_says_so(qtbot, opened, recording,
                                                                                        tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    review.form.set_method_name("diffusion")
    assert review.reconstruct() is not None and review.model.busy
    with answering(False) as asked:
        assert review.open_recording(other) is None
    assert [q.accept for q in asked] == ["Open other.zarr"]
    assert asked[0].text.startswith("Opening other.zarr now:\n\n• the reconstruction running stops; what it "
                                    "computed is lost")
    # The run ends on its worker (busy goes False there); its result reaches the list on the GUI thread after.
    qtbot.waitUntil(lambda: len(review.results) == 1, timeout=30_000)
    assert review.session.path == recording and not review.model.busy  # the run went on and was kept


def test_opening_another_recording_with_a_result_not_exported_asks_and_then_shows_only_the_new_one(
        qtbot, opened, recording, tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    reconstruct(qtbot, review, "diffusion")
    with answering(True) as asked:
        review.open_recording(other)
    assert "1 reconstruction not exported is lost: diffusion" in asked[0].text
    qtbot.waitUntil(lambda: review.session.path == other, timeout=10_000)
    assert review.results == [] and review.model.result_line.text == ""
    with answering() as asked:  # nothing to lose now: no question
        review.open_recording(recording)
    assert asked == []
    qtbot.waitUntil(lambda: review.session.path == recording, timeout=10_000)


def test_a_run_cancelled_by_opening_another_recording_leaves_no_cancelled_line_on_the_new_one(
        qtbot, opened, recording, tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    review.form.set_method_name("motion-aware")
    review.reconstruct()
    with answering(True):
        review.open_recording(other)
    qtbot.waitUntil(lambda: review.session.path == other and not review.model.busy, timeout=30_000)
    qtbot.wait(50)
    assert "cancelled" not in review.result_label.text() and review.results == []


def test_a_refused_open_names_the_recording_still_open(qtbot, opened, recording, tmp_path):
    review = opened
    (tmp_path / "junk.zarr").mkdir()
    review.open_recording(tmp_path / "junk.zarr")
    qtbot.waitUntil(lambda: "cannot open" in review.path_label.text(), timeout=5000)
    text = review.path_label.text()
    assert f"{recording} (still open)" in text and "cannot open junk.zarr" in text
    assert review.session.path == recording and review.reconstruct_button.isEnabled()


# ---------------------------------------------------------------------- messages in words
@pytest.mark.parametrize("message, words, gone", [
    ("/d/x.zarr: not a readable Zarr store (GroupNotFoundError: No group found in store /d/x.zarr at path '')",
     "is not a recording", "GroupNotFoundError"),
    ("/d/cal.json: not valid JSON (Expecting value at line 1)", "not a file flexvox wrote", "Expecting value"),
])
def test_messages_for_programmers_become_words_naming_what_to_open_instead(message, words, gone):
    from flexvox_app.gui.models.operator_words import in_gui_words

    text = in_gui_words(message)
    assert words in text and gone not in text and "open" in text, text


# ---------------------------------------------------------------------- ground truth: its cost, its finish, remembered
def truth_window(qtbot, settings):
    from flexvox_app.gui.application import build_window
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="strobe", subframes=17 * 16, seed=0, clock=VirtualClock())
    w = build_window(rig, settings=settings)
    qtbot.addWidget(w)
    w.capture.live_panel.preview_check.setChecked(False)
    return w


def test_ground_truth_says_what_it_costs_and_the_choice_survives_a_restart(qtbot, settings):
    w = truth_window(qtbot, settings)
    panel = w.capture.record_panel
    w.show()
    w.show_workspace("Capture")
    panel.frames_box.setValue(300)
    assert panel.truth_check.isChecked() and panel.truth_cost.isVisible()
    cost = panel.truth_cost.text()  # 4x4 code on a 120x160 camera at 15 Hz: 16 float32 pictures per frame
    assert "ground truth adds 1.2 MB per frame (18 MB per second at 15 Hz, about 32× the frames' size)" in cost, cost
    assert "369 MB for 300 frames" in cost and "finishing takes longer" in cost
    panel.truth_check.setChecked(False)
    assert not panel.truth_cost.isVisible()
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


def test_the_sink_says_which_ground_truth_frame_it_writes(tmp_path):
    from flexvox_app.capture.plan import CapturePlan
    from flexvox_app.capture.service import CaptureService
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="strobe", subframes=17 * 16, seed=0, clock=VirtualClock())
    svc = CaptureService(rig, CapturePlan(), tmp_path / "r.zarr", frames=4, ground_truth=True)
    seen = []
    truth = svc.sink._ground_truth
    svc.sink._ground_truth = lambda i, K: (seen.append(svc.stats().finishing), truth(i, K))[1]
    svc.start()
    assert svc.wait(30)
    result = svc.result() if callable(svc.result) else svc.result
    assert result is not None and result.ok, result
    assert seen == [f"writing the scene's ground truth: frame {i} of 4" for i in range(1, 5)]
    assert svc.stats().finishing == ""


# ---------------------------------------------------------------------- dropping a calibration asks; refusals after
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


# ---------------------------------------------------------------------- where each result ran
def test_where_it_ran_names_the_gpu_the_simulator_and_why_a_gpu_is_unused(monkeypatch):
    import flexvox_core.gpu.device as device
    from flexvox_app.gui.models import device_words as words

    monkeypatch.setattr(device, "simulator", lambda: False)
    monkeypatch.setattr(words, "gpu_name", lambda: "NVIDIA H200")
    monkeypatch.setattr(words, "gpu_status", lambda: (True, "CUDA", True))
    assert words.where_it_ran("cuda") == "on the GPU (NVIDIA H200)"
    assert words.where_it_ran("cpu", "gap-tv has no GPU path") == "on the CPU (gap-tv has no GPU path)"
    assert words.where_it_ran("cpu") == "on the CPU (the GPU was not asked for)"
    monkeypatch.setattr(words, "gpu_status", lambda: (False, "numba-cuda is not installed (pip install "
                                                             "'flexvox[gpu]')", True))
    assert words.where_it_ran("cpu") == ("on the CPU (a GPU is here but unused: numba-cuda is not installed "
                                         "(pip install 'flexvox[gpu]'))")
    monkeypatch.setattr(words, "gpu_status", lambda: (False, "no NVIDIA driver found (libcuda)", False))
    assert words.where_it_ran("cpu") == "on the CPU"
    monkeypatch.setattr(device, "simulator", lambda: True)
    simulated = words.where_it_ran("cuda")
    assert simulated.startswith("on numba-cuda's simulator (") and "no GPU" in simulated


def test_review_s_result_line_and_the_compare_list_say_where_each_result_ran(qtbot, opened):
    review = opened
    reconstruct(qtbot, review, "diffusion")
    reconstruct(qtbot, review, "rebin")
    assert "sub-frames in" in review.result_label.text() and " on the CPU" in review.result_label.text()
    items = [review.compare_view.box_a.itemText(i) for i in range(review.compare_view.box_a.count())]
    assert len(items) == 2 and all(" on the CPU" in item for item in items), items


def test_the_live_preview_line_says_where_it_runs():
    import numpy as np

    from flexvox_app.capture.live_preview import PreviewResult, Region
    from flexvox_app.gui.capture.live_preview import LivePreview

    preview = LivePreview(device="cpu")
    preview.enabled, preview.runs = True, 1
    preview.result = PreviewResult(np.zeros((16, 48, 64), np.float32), 3, 3, Region(0, 48, 0, 64), (48, 64), 0.01,
                                   (0.0, 1.0), "motion-aware", "cpu")
    assert preview.text().startswith("motion-aware preview on the CPU: 64×48 (the whole frame)"), preview.text()


# ---------------------------------------------------------------------- the live preview's region grows back
def test_the_preview_region_shrunk_under_load_grows_back_when_runs_get_faster():
    from flexvox_app.capture.live_preview import PixelCost, preview_region

    cost, budget, shape = PixelCost(), 0.6, (120, 160)

    def run(pixels, load):  # a run: a large fixed part and a part per pixel, both slowed by the load
        return load * (0.45 + 5e-6 * pixels)  # idle, the whole 160×120 frame takes 0.55 s: it fits 0.6 s

    region = preview_region(shape, (4, 4), 160 * 120)
    for _ in range(6):  # under load the region shrinks
        cost.add(run(region.pixels, 3.0), region.pixels)
        region = preview_region(shape, (4, 4), cost.pixels_for(budget, 160 * 120))
    small = region.pixels
    assert small < 160 * 120 / 8
    for _ in range(8):  # the load falls: runs are quick again
        cost.add(run(region.pixels, 1.0), region.pixels)
        region = preview_region(shape, (4, 4), cost.pixels_for(budget, 160 * 120))
    assert region.covers(shape), (small, region)


# ---------------------------------------------------------------------- small things
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


def test_the_drift_note_says_sub_second_drifts_in_milliseconds():
    from flexvox_app.capture.plan import CapturePlan

    notes = " ".join(CapturePlan(camera_hz=200.0).timing().notes)
    assert "drifts one slot every" in notes and "every 0 s" not in notes, notes


# ---------------------------------------------------------------------- the sync wizard keeps finished work
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
    assert f"the synchronisation wizard saved {profile}" in w.capture.calibration_panel.label.text()
    assert "sync profile is not loaded" in w.capture.calibration_panel.status_label.text()
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


def test_the_slider_s_default_step_gives_the_benched_default_tensor(review):
    from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR

    review.form.set_method_name("diffusion")
    review.form.set_position(0.18)
    assert tuple(review.form.method().tensor) == tuple(DEFAULT_TENSOR) == (0.15, 0.15, 1.0)
    assert "not benched" not in review.expected_label.text()
    review.form.set_position(0.25)
    assert tuple(review.form.method().tensor) != tuple(DEFAULT_TENSOR)


def test_the_camera_rate_is_the_camera_s_own_not_its_delivery_bursts(tmp_path):
    from flexvox_app.capture.plan import CapturePlan
    from flexvox_app.capture.service import CaptureService
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    # the virtual clock delivers every frame at once in real time: only the camera's timestamps say 15 Hz
    rig = open_rig("mock", scene="strobe", subframes=17 * 16, seed=0, clock=VirtualClock())
    svc = CaptureService(rig, CapturePlan(camera_hz=15.0), tmp_path / "r.zarr", frames=17)
    svc.start()
    assert svc.wait(30)
    assert svc.stats().camera_rate_hz == pytest.approx(15.0, rel=0.01)


def test_the_close_question_s_text_follows_the_recording_while_it_is_open(qtbot):
    from flexvox_app.gui.widgets.questions import question_box

    frames = [3]
    box = question_box(None, "Quit flexvox?", "3 frames", accept="Quit", update=lambda: f"{frames[0]} frames")
    qtbot.addWidget(box)
    frames[0] = 40  # the recording went on while the operator read
    qtbot.waitUntil(lambda: box.text() == "40 frames", timeout=3000)
    assert box.yes.text() == "Quit" and box.defaultButton() is not box.yes
