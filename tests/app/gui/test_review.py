"""The Review workspace driven through its widgets on a simulated recording."""

import shutil

import numpy as np
import pytest
import tifffile
from PySide6.QtCore import Qt, QTimer

from flexvox_app.gui.review.workspace import ReviewWorkspace
from flexvox_app.gui.widgets.questions import Question, answering

from .conftest import FRAMES, SIZE
from .model_helpers import without_ground_truth
from .widget_helpers import reconstruct

S = FRAMES * 8  # sub-frames of the test recording (K = 8)


def test_open_shows_the_recording_and_plays_it(qtbot, opened):
    ws = opened
    assert "6 frames of 48×32" in ws.summary_label.text() and "K = 8" in ws.summary_label.text()
    assert ws.raw_panel.has_image() and ws.raw_panel.image.image.shape == SIZE
    np.testing.assert_array_equal(ws.raw_panel.image.image, ws.session.raw[0])
    assert ws.frame_slider.maximum() == S - 1
    assert ws.reconstruct_button.isEnabled() and not ws.cancel_button.isEnabled()
    assert "dB PSNR" in ws.expected_label.text()
    ws.fps.setValue(100)
    ws.play_button.click()
    assert ws.playing and ws.play_button.text() == "Pause"
    qtbot.waitUntil(lambda: ws.subframe >= 16, timeout=5000)
    assert ws.subframe % 8 == 0  # without a reconstruction, playback steps whole camera frames
    ws.play_button.click()
    assert not ws.playing
    f = ws.subframe // 8
    np.testing.assert_array_equal(ws.raw_panel.image.image, ws.session.raw[f])


def test_the_speed_says_sub_frames_per_second_and_real_time_plays_the_recording_s_own_rate(opened):
    """Point 7: "12 fps" was sub-frames per second; real time plays 15 Hz × 8 = 120 sub-frames a second."""
    ws = opened
    assert ws.fps.suffix() == " sub-frames/s" and ws.real_time.text() == "real time (120/s)"
    ws.fps.setValue(12)
    assert ws.speed() == 12.0
    ws.real_time.setChecked(True)
    assert ws.speed() == 120.0 and not ws.fps.isEnabled()
    ws.frame_slider.setValue(0)
    ws.set_playing(True)
    start = ws.model.playback.last_tick
    ws.model.playback.tick(start + 0.5)  # half a second at 15 Hz: 7 whole frames of 8 (half carried), wrapped at 6
    assert ws.subframe == 56 % 48 and ws.model.playback.carried == pytest.approx(4.0)
    ws.model.playback.tick(start + 1.0)
    assert ws.subframe == 120 % 48  # a second: 15 frames
    ws.set_playing(False)


def test_open_failure_is_said_in_words(qtbot, review, tmp_path):
    (tmp_path / "junk.zarr").mkdir()
    review.open_recording(tmp_path / "junk.zarr")
    qtbot.waitUntil(lambda: "cannot open" in review.path_label.text(), timeout=5000)
    assert "is not a recording" in review.path_label.text()
    assert review.session is None and not review.reconstruct_button.isEnabled()


def test_a_damaged_recording_is_refused_never_shown_as_zeros(qtbot, review, recording, tmp_path):
    import shutil

    damaged = tmp_path / "damaged.zarr"
    shutil.copytree(recording, damaged)
    (damaged / "frames" / "c" / "4" / "0" / "0").unlink()
    review.open_recording(damaged)
    qtbot.waitUntil(lambda: "cannot open" in review.path_label.text(), timeout=5000)
    assert "frames row 4 is damaged: its chunk file is missing" in review.path_label.text()
    assert review.session is None


@pytest.mark.parametrize("method, knobs", [
    ("rebin", {"position": 0.5}),  # the balanced division (2x1x4 / 1x2x4)
    ("diffusion", {"position": 0.18}),  # the default tensor
    ("gap-tv", {"iterations": 20}),
    ("motion-aware", {}),
    ("motion-aware", {"slow_reach": 0.0}),
])
def test_reconstruct_each_method_beats_the_raw_frames(qtbot, opened, naive_psnr, method, knobs):
    r = reconstruct(qtbot, opened, method, **knobs)
    assert r.method.name == method
    if "slow_reach" in knobs:
        assert r.method.slow_reach == knobs["slow_reach"] and "slow-reach 0" in r.method.label()
    assert r.video.shape == (S, *SIZE) and r.video.dtype == np.float32
    assert 0 <= r.video.min() and r.video.max() <= 1
    assert r.psnr > naive_psnr + 0.8, (r.psnr, naive_psnr)
    assert f"{r.psnr:.2f} dB" in opened.result_label.text()
    assert opened.progress.value() == FRAMES
    # The reconstruction panel now shows the result at the current sub-frame, and playback steps sub-frames.
    opened.frame_slider.setValue(13)
    np.testing.assert_array_equal(opened.recon_panel.image.image, r.video[13])
    opened.model.playback.tick(opened.model.playback.last_tick + 1.5 / opened.speed())  # a sub-frame and a half
    assert opened.subframe == 14


def test_event_loop_runs_during_a_reconstruction_and_cancel_stops_it(qtbot, opened):
    ws = opened
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(10)
    ws.form.set_method_name("gap-tv")
    ws.form.widget("iterations").setValue(500)  # about 0.1-0.2 s per camera frame: a slow job of 6 chunks
    handle = ws.reconstruct()
    assert ws.cancel_button.isEnabled() and not ws.reconstruct_button.isEnabled()
    qtbot.waitUntil(lambda: ws.progress.value() >= 1, timeout=20_000)  # the first chunk is done
    assert len(ticks) >= 3, "the GUI thread's timer did not run while the reconstruction ran"
    ws.cancel_button.click()
    qtbot.waitUntil(lambda: not handle.running, timeout=20_000)
    timer.stop()
    assert handle.outcome == "cancelled"
    assert ws.progress.value() == 0 and handle.result is None
    assert ws.results == [] and "cancelled" in ws.result_label.text()
    qtbot.waitUntil(lambda: ws.reconstruct_button.isEnabled(), timeout=2000)
    assert not ws.cancel_button.isEnabled()


def test_continuum_slider_changes_the_method_and_recomputes_the_preview(qtbot, opened):
    ws = opened
    ws.preview_check.setChecked(True)
    ws.form.set_method_name("diffusion")
    ws.frame_slider.setValue(3 * 8 + 2)
    ws.form.set_position(0.0)
    assert ws.form.method().tensor == (0.05, 0.05, 1.0)
    assert "high SR" in ws.form.slider_text.text()
    qtbot.waitUntil(lambda: ws.shown is not None and ws.shown.method.tensor == (0.05, 0.05, 1.0), timeout=10_000)
    high_sr = ws.shown
    assert high_sr.extra["preview"] and high_sr.first_frame == 2 and high_sr.video.shape == (24, *SIZE)
    assert "preview" in ws.recon_panel.title.text()
    ws.form.set_position(1.0)
    assert ws.form.method().tensor == (1.0, 1.0, 0.05)
    qtbot.waitUntil(lambda: ws.shown.method.tensor == (1.0, 1.0, 0.05), timeout=10_000)
    assert not np.allclose(ws.shown.video, high_sr.video)
    np.testing.assert_array_equal(ws.recon_panel.image.image, ws.shown.video[3 * 8 + 2 - 16])
    # Re-binning: the slider walks the divisions from TR 1 to TR K.
    ws.form.set_method_name("rebin")
    ws.form.set_position(0.0)
    assert ws.form.method().block.label == "1x1x8"
    ws.form.set_position(1.0)
    assert ws.form.method().block.label == "2x4x1" and "TR ×8" in ws.form.slider_text.text()
    ws.form.set_method_name("gap-tv")
    assert ws.form.slider.isEnabled() and not ws.form.comparing


def test_the_slider_previews_a_fixed_tensor_beside_motion_aware_without_switching_method(qtbot, opened):
    from flexvox_app.gui.models.continuum import continuum_tensor

    ws = opened
    ws.preview_check.setChecked(True)
    ws.form.set_method_name("motion-aware")
    assert ws.form.slider.isEnabled() and ws.form.preview_method().name == "motion-aware"
    ws.form.set_position(0.9)
    assert ws.form.comparing and ws.form.method_box.currentText() == "motion-aware"
    assert ws.form.preview_method().tensor == continuum_tensor(0.9)
    assert ("in place of motion-aware (no motion-aware result to set it beside yet); Reconstruct runs motion-aware"
            in ws.form.slider_text.text())
    qtbot.waitUntil(lambda: ws.shown is not None and ws.shown.method.name == "diffusion", timeout=10_000)
    assert ws.shown.method.tensor == continuum_tensor(0.9)
    assert ws.reconstruct_button.text() == "Reconstruct: motion-aware"
    ws.form.widget("time").setValue(3.0)  # a knob of the chosen method: back to previewing it
    assert not ws.form.comparing and ws.form.preview_method().name == "motion-aware"


@pytest.mark.parametrize("suffix", [".npy", ".tif", ".mp4"])
def test_export_writes_the_reconstruction(qtbot, opened, tmp_path, suffix):
    r = reconstruct(qtbot, opened, "diffusion")
    path = tmp_path / f"out{suffix}"
    handle = opened.export(path)
    qtbot.waitUntil(lambda: not handle.running, timeout=10_000)
    assert handle.outcome == "finished"
    assert path.exists() and f"wrote {path}" in opened.export_label.text()
    if suffix == ".npy":
        np.testing.assert_array_equal(np.load(path), r.video)
    elif suffix == ".tif":
        np.testing.assert_array_equal(tifffile.imread(path), r.video)
        with tifffile.TiffFile(path) as tif:  # Fiji shows seconds: one sub-frame period per frame
            rate = opened.session.recording.attrs["rates"]["subframe_hz"]
            assert tif.imagej_metadata["finterval"] == pytest.approx(1 / rate)
            assert r.method.label() in tif.imagej_metadata["Info"]  # the file names what it holds
    else:
        assert path.stat().st_size > 1000
    with answering(False) as asked:  # no silent overwrite: asked, naming the file, before any work
        assert opened.export(path) is None
    assert asked == [Question("Replace the existing export?", f"{path} already exists. Replace it with the new "
                                                              "export?", "Replace")]
    assert f"not exported: {path} is kept" in opened.export_label.text()
    assert opened.export(path, overwrite=False) is None and "already exists" in opened.export_label.text()
    assert opened.export(opened.session.path) is None  # never onto the recording under review
    assert "an output never replaces its input" in opened.export_label.text()


def test_an_mp4_its_writer_cannot_keep_is_refused_before_any_work(qtbot, review, tmp_path):
    from tests.recordings import simulate_recording

    review.preview_check.setChecked(False)
    review.open_recording(simulate_recording(tmp_path, frames=3, size=(15, 24), tile=(2, 2), name="odd.zarr"))
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    reconstruct(qtbot, review, "diffusion")
    assert review.export(tmp_path / "out.mp4") is None  # 15 rows: OpenCV's writer would drop one
    assert ("not exported: cannot write" in review.export_label.text()
            and "needs a height and width even" in review.export_label.text())
    assert not (tmp_path / "out.mp4").exists()


def test_export_needs_something_shown(opened):
    assert opened.export("/nonexistent/x.npy") is None
    assert "nothing to export: reconstruct, or preview, first" in opened.export_label.text()


def test_export_writes_the_shown_preview_s_method_over_every_frame(qtbot, opened, tmp_path):
    import zarr

    from flexvox_app.gui.models.continuum import continuum_tensor
    from flexvox_core.methods import Method

    ws = opened
    motion = reconstruct(qtbot, ws, "motion-aware")
    ws.preview_check.setChecked(True)
    ws.form.set_method_name("diffusion")
    ws.form.set_position(0.8)
    qtbot.waitUntil(lambda: ws.shown is not None and bool(ws.shown.extra.get("preview"))
                    and ws.shown.method == ws.form.method(), timeout=10_000)
    assert ws.shown.method.tensor == continuum_tensor(0.8)
    shown = ws.shown
    assert ws.export_candidate() is shown
    path = tmp_path / "shown.zarr"
    handle = ws.export(path)
    assert "to export what is shown" in ws.export_label.text()
    qtbot.waitUntil(lambda: not handle.running, timeout=20_000)
    assert handle.outcome == "finished", handle.message
    written, result = ws.exported
    assert result.method == shown.method and result is not motion and not result.extra.get("preview")
    g = zarr.open_group(str(path), mode="r")
    np.testing.assert_array_equal(g["video"][:], result.video)
    attrs = g.attrs["flexvox"]
    assert Method(**attrs["method"]) == shown.method and attrs["method_label"] == shown.method.label()
    assert f"wrote {path}: {shown.method.label()} (6 frames, 48 sub-frames)" in ws.export_label.text()
    # The full result is kept: a second export of the same settings writes it without reconstructing again.
    assert ws.full_result_of(shown.method) is result and ws.results[-1] is result


def test_compare_shows_two_reconstructions_side_by_side(qtbot, opened):
    a = reconstruct(qtbot, opened, "rebin")
    b = reconstruct(qtbot, opened, "motion-aware")
    cv = opened.compare_view
    assert cv.box_a.count() == 2 and (cv.box_a.currentIndex(), cv.box_b.currentIndex()) == (0, 1)
    opened.frame_slider.setValue(20)
    np.testing.assert_array_equal(cv.panel_a.image.image, a.video[20])
    np.testing.assert_array_equal(cv.panel_b.image.image, b.video[20])
    assert "rebin" in cv.panel_a.title.text() and "dB" in cv.panel_a.title.text()
    assert "motion-aware" in cv.panel_b.title.text()
    cv.select(1, 0)
    np.testing.assert_array_equal(cv.panel_a.image.image, b.video[20])
    cv.panel_a.view.setRange(xRange=(0, 10), yRange=(0, 10), padding=0)  # zoom A: B follows
    assert cv.panel_b.view.viewRange()[0] == pytest.approx(cv.panel_a.view.viewRange()[0])


def test_motion_tab_shows_flow_and_resolution_map(qtbot, opened):
    mv = opened.motion_view
    assert not mv.flow_panel.has_image()
    r = reconstruct(qtbot, opened, "motion-aware")
    opened.frame_slider.setValue(21)
    colour = mv.flow_panel.image.image.copy()
    assert colour.shape == (*SIZE, 3) and colour.dtype == np.uint8
    np.testing.assert_array_equal(mv.map_panel.image.image, r.tr[21])
    assert mv.map_panel.image.levels.tolist() == [1, 8]
    mv.quiver.setChecked(True)
    assert mv.mode == "quiver" and not np.array_equal(mv.flow_panel.image.image, colour)
    assert "sub-frame 22/48" in mv.note.text() and "colour saturates" not in mv.note.text()
    opened.form.set_method_name("diffusion")
    reconstruct(qtbot, opened, "diffusion")  # another method shown: the Motion tab keeps the motion-aware result
    np.testing.assert_array_equal(mv.map_panel.image.image, r.tr[21])
    assert "motion-aware" in mv.note.text() and "the Frames tab shows diffusion" in mv.note.text()
    assert mv.map_panel.colorbar.isVisible() or not mv.isVisible()


def test_the_motion_tab_says_what_to_do_before_a_flow_exists(opened):
    mv = opened.motion_view
    assert "no flow yet: reconstruct with motion-aware" in mv.flow_panel.placeholder_text()
    assert not mv.map_panel.colorbar.isVisible()


def test_settings_persist_between_sessions(qtbot, settings, runner, recording):
    first = ReviewWorkspace(settings, runner, None)
    qtbot.addWidget(first)
    first.form.set_method_name("gap-tv")
    first.form.widget("iterations").setValue(77)
    first.form.set_position(0.7)
    first.fps.setValue(33)
    first.preview_check.setChecked(False)
    settings.sync()
    second = ReviewWorkspace(settings, runner, None)
    qtbot.addWidget(second)
    assert second.form.method_box.currentText() == "gap-tv" and second.form.widget("iterations").value() == 77
    assert second.form.position == pytest.approx(0.7) and second.fps.value() == 33
    assert not second.preview_check.isChecked()
    assert "no bench figures" in second.expected_label.text() or "open a recording" in second.expected_label.text()


def test_a_recording_the_reader_refuses_opens_for_playback_with_the_reason(qtbot, review, tmp_path, rng):
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.simulator import simulate_video

    result = simulate_video(rng.random((4 * 4, 16, 16)).astype(np.float32), design_code((2, 2)).code)
    result.frames[:] = 0
    result.dropped[:] = True  # every frame dropped: nothing to reconstruct
    path = write_simulation(tmp_path / "d.zarr", result)
    with qtbot.waitSignal(review.session_opened, timeout=10_000):
        review.open_recording(path)
    assert review.session.frames is None and "all 4 frames were dropped" in review.session.blocked
    assert "cannot reconstruct" in review.summary_label.text() and "all 4 frames were dropped" in \
        review.summary_label.text()
    assert not review.reconstruct_button.isEnabled() and review.raw_panel.has_image()


def test_dropped_frames_are_bridged_and_said(qtbot, review, tmp_path, rng):
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    result = simulate_video(render_scene("balls", 6 * 4, 24, 32), design_code((2, 2)).code)
    result.frames[2] = 0
    result.dropped[2] = True
    path = write_simulation(tmp_path / "d.zarr", result)
    with qtbot.waitSignal(review.session_opened, timeout=10_000):
        review.open_recording(path)
    assert review.session.blocked == "" and review.session.missing.tolist() == [0, 0, 1, 0, 0, 0]
    assert "1 dropped frame(s), bridged from both sides" in review.summary_label.text()
    r = reconstruct(qtbot, review, "diffusion")
    np.testing.assert_array_equal(r.extra["interpolated"], np.repeat([0, 0, 1, 0, 0, 0], 4).astype(bool))
    assert np.isfinite(r.video).all() and r.video[8:12].mean() > 0.05  # the gap is filled, not black


def test_the_method_form_is_built_from_the_registered_methods(qtbot, settings):
    from flexvox_app.gui.review.method_form import MethodForm
    from flexvox_core.methods import Method
    from tests.flexvox_core.methods.tiny_method import frame_mean_registered

    with frame_mean_registered():
        form = MethodForm(settings)
        qtbot.addWidget(form)
        form.set_method_name("frame-mean")
        form.widget("radius").setValue(3)
        assert form.method() == Method("frame-mean", radius=3)
        assert form.slider.isEnabled() and not form.comparing  # no tensor or division option: it compares
        assert "frame-mean keeps space and gives up time; moving the slider previews diffusion at its tensor beside " \
            "frame-mean, for comparison" in form.slider_text.text()
    form.set_method_name("motion-aware")
    form.widget("slow_reach").setValue(0.75)  # the pipeline's default is shown, and stands for None
    assert form.method().slow_reach is None and form.slider.isEnabled()
    # The refinement's default depends on the code ((K/16)²): a choice of its own, shown in words, below 0.
    refine = form.widget("refine_time")
    assert refine.text() == "default ((K/16)²)" and form.method().refine_time is None
    refine.setValue(1.0)  # every number means itself, 1.0 included (0.5 would be the default at K = 8)
    assert form.method().refine_time == 1.0
    refine.setValue(0.0)
    assert form.method().refine_time == 0.0
    refine.setValue(refine.minimum())
    assert form.method().refine_time is None
    refine.setValue(-0.25)  # typed below the range: the default, not a value Reconstruct would refuse
    assert form.method().refine_time is None


def test_a_refinement_stored_before_the_default_was_in_words_does_not_come_back_as_a_number(qtbot, settings):
    from flexvox_app.gui.review.method_form import MethodForm

    settings.set("review/motion-aware/refine_time", 1.0)  # where 1.0 used to stand for the default
    form = MethodForm(settings)
    qtbot.addWidget(form)
    form.set_method_name("motion-aware")
    assert form.widget("refine_time").text() == "default ((K/16)²)" and form.method().refine_time is None
    with pytest.raises(ValueError, match=r"motion-aware has no widget for 'tensor'"):
        form.widget("tensor")
    form.set_method_name("diffusion")
    from flexvox_app.gui.models.continuum import continuum_tensor

    assert form.slider.isEnabled() and form.method().tensor == (0.15, 0.15, 1.0)  # the default step: the default
    form.set_position(0.3)
    assert form.method().tensor == continuum_tensor(form.position)
    with pytest.raises(ValueError, match=r"`method` must be one of rebin, diffusion, gap-tv, motion-aware; got 'x'"):
        form.set_method_name("x")


def test_the_expected_time_comes_from_timing_this_machine_and_is_logged_against_the_measured(qtbot, opened, caplog):
    import logging

    from flexvox_app.gui.models.machine_speed import SpeedModel, settings_key

    ws = opened
    ws.form.set_method_name("diffusion")
    key = settings_key("diffusion", 8)
    # The first use times the method here (off the GUI thread) and keeps the model in the settings.
    qtbot.waitUntil(lambda: ws.speed_model("diffusion", 8) is not None, timeout=20_000)
    assert SpeedModel.from_json(ws.settings.get_str(key)) == ws.speed_model("diffusion", 8)
    assert "on this machine" in ws.expected_label.text() and "timing this machine" not in ws.expected_label.text()
    expected_s = ws.expected_seconds()
    assert expected_s > 0
    with caplog.at_level(logging.INFO, logger="flexvox_app.gui.models.review_jobs"):
        r = reconstruct(qtbot, ws, "diffusion")
    assert "(expected ≈" in ws.result_label.text()
    assert any(f"measured {r.seconds:.3f} s, expected {expected_s:.3f} s" in m for m in caplog.messages)


def test_a_folder_that_is_no_recording_is_refused_before_asking_about_an_unexported_result(qtbot, opened,
                                                                                           recording, tmp_path):
    from flexvox_app.gui.widgets.questions import answering

    review = opened
    reconstruct(qtbot, review, "diffusion")
    (tmp_path / "junk").mkdir()
    (tmp_path / "notes.txt").write_text("x")
    for path in (tmp_path / "junk", tmp_path / "notes.txt", tmp_path / "missing.zarr"):
        with answering() as asked:  # no question: nothing would be lost
            assert review.open_recording(path) is None
        assert asked == []
        text = review.path_label.text()
        assert f"{recording} (still open)" in text and f"cannot open {path.name}" in text, text
        assert "Zarr store" not in text
    assert len(review.results) == 1 and review.session.path == recording


def test_a_wrong_pick_logs_one_line_and_keeps_the_traceback_for_the_debug_level(qtbot, opened, recording, tmp_path,
                                                                                 caplog):
    import logging

    import zarr

    review = opened
    zarr.open_group(str(tmp_path / "other.zarr"), mode="w")  # a Zarr folder of another program
    with caplog.at_level(logging.DEBUG, logger="flexvox_app.gui.widgets.qt_jobs"):
        review.open_recording(tmp_path / "other.zarr")
        qtbot.waitUntil(lambda: "cannot open other.zarr" in review.path_label.text(), timeout=10_000)
    failed = [r for r in caplog.records if r.name == "flexvox_app.gui.widgets.qt_jobs" and "failed" in r.getMessage()]
    shown = [r for r in failed if r.levelno >= logging.WARNING]
    assert len(shown) == 1 and shown[0].exc_info is None and "\n" not in shown[0].getMessage()
    assert "not a flexvox recording" in shown[0].getMessage()
    assert [r.levelno for r in failed if r.exc_info] == [logging.DEBUG]


def test_opening_another_recording_during_a_run_asks_naming_it_and_keeping_it_says_so(qtbot, opened, recording,
                                                                                        tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    review.form.set_method_name("diffusion")
    assert review.reconstruct() is not None and review.model.jobs.busy
    with answering(False) as asked:
        assert review.open_recording(other) is None
    assert [q.accept for q in asked] == ["Open other.zarr"]
    assert asked[0].text.startswith("Opening other.zarr now:\n\n• the reconstruction running stops; what it "
                                    "computed is lost")
    # The run ends on its worker (busy goes False there); its result reaches the list on the GUI thread after.
    qtbot.waitUntil(lambda: len(review.results) == 1, timeout=30_000)
    assert review.session.path == recording and not review.model.jobs.busy  # the run went on and was kept


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
    assert review.results == [] and review.model.jobs.result_line.text == ""
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
    qtbot.waitUntil(lambda: review.session.path == other and not review.model.jobs.busy, timeout=30_000)
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


def test_review_s_result_line_and_the_compare_list_say_where_each_result_ran(qtbot, opened):
    review = opened
    reconstruct(qtbot, review, "diffusion")
    reconstruct(qtbot, review, "rebin")
    assert "sub-frames in" in review.result_label.text() and " on the CPU" in review.result_label.text()
    items = [review.compare_view.box_a.itemText(i) for i in range(review.compare_view.box_a.count())]
    assert len(items) == 2 and all(" on the CPU" in item for item in items), items
    # the preview's title says where it ran too
    review.form.set_method_name("diffusion")
    review.preview_check.setChecked(True)
    review.form.set_position(0.0)  # settings no result has: the preview is shown
    qtbot.waitUntil(lambda: review.recon_panel.title.text().startswith("preview: "), timeout=20_000)
    assert " on the CPU · sub-frame " in review.recon_panel.title.text()


def test_without_ground_truth_the_result_line_and_the_compare_list_show_the_estimate(qtbot, review, recording,
                                                                                     tmp_path, monkeypatch):
    from flexvox_core import accuracy

    monkeypatch.setitem(accuracy.REFUSED, "rebin", "refused here")  # a refused method's line and list entry
    review.preview_check.setChecked(False)
    review.open_recording(without_ground_truth(recording, tmp_path))
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    diffusion = reconstruct(qtbot, review, "diffusion")
    qtbot.waitUntil(lambda: diffusion.estimate is not None, timeout=30_000)
    est = diffusion.estimate
    assert review.result_label.text().endswith(f"; {est.line()}") and "estimated PSNR " in est.line()
    cv = review.compare_view
    assert f"estimated PSNR {est.psnr:.2f} dB (± {est.half_width:.2f} dB)" in cv.box_a.itemText(0)
    assert est.line() in cv.box_a.itemData(0, Qt.ItemDataRole.ToolTipRole)
    review.frame_slider.setValue(13)  # camera frame 1: its own estimate in the panel's title
    assert cv.panel_b.title.text().endswith(f" · this frame estimated PSNR {est.per_frame[1]:.2f} dB")
    rebin = reconstruct(qtbot, review, "rebin")  # refused: nothing on the line, why in the list's tooltip
    assert rebin.no_estimate is not None and "refused here" in rebin.no_estimate
    assert rebin.estimate is None and "estimat" not in review.result_label.text()
    assert "estimat" not in cv.box_b.itemText(1)
    assert f"no estimate: {rebin.no_estimate}" in cv.box_b.itemData(1, Qt.ItemDataRole.ToolTipRole)
    assert cv.box_a.currentIndex() == 0 and "estimated PSNR" in cv.box_a.itemText(0)


def test_the_slider_s_default_step_gives_the_benched_default_tensor(review):
    from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR

    review.form.set_method_name("diffusion")
    review.form.set_position(0.18)
    assert tuple(review.form.method().tensor) == tuple(DEFAULT_TENSOR) == (0.15, 0.15, 1.0)
    # one rounding everywhere: the line under the slider says what the method's label says
    assert "tensor (0.15, 0.15, 1)" in review.form.slider_text.text() and "0.147" not in review.form.slider_text.text()
    assert "(0.15,0.15,1)" in review.form.method().label()
    assert "not benched" not in review.expected_label.text()
    review.form.set_position(0.25)
    assert tuple(review.form.method().tensor) != tuple(DEFAULT_TENSOR)


def test_the_auto_box_makes_reconstruct_choose_the_time_by_the_estimate(qtbot, review, recording, tmp_path):
    review.preview_check.setChecked(False)
    review.open_recording(without_ground_truth(recording, tmp_path))
    qtbot.waitUntil(lambda: review.session is not None, timeout=10_000)
    review.form.set_method_name("diffusion")
    review.form.auto_box.setChecked(True)
    chosen = reconstruct(qtbot, review, "diffusion")
    choice = chosen.extra["choice"]
    assert chosen.method.time == choice.value and chosen.estimate is choice.estimate
    assert f"chose time {choice.value:g} for diffusion" in review.result_label.text()
    review.form.auto_box.setChecked(False)
    plain = reconstruct(qtbot, review, "diffusion")
    assert "choice" not in plain.extra
