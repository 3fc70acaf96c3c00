"""Recording from the Capture workspace through the capture service, on the simulated rig."""

import errno
import re
from functools import partial

import pytest

from flexvox_app.capture.service import CaptureService
from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.capture_model import Action, Holder
from flexvox_app.gui.models.recording import counters_text, result_text
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.questions import Question, answering
from flexvox_core.recording import RecordingWriter, open_recording
from rig_drivers.interfaces import DeviceState, RunState

from .conftest import small_rig

RATE_HZ = 60.0  # K = 16 at 60 Hz: 1041 µs patterns, a frame every 16.7 ms


def _workspace(qtbot, settings, runner, **kw):
    service = RigService(small_rig())
    ws = CaptureWorkspace(service, settings, runner, **kw)
    qtbot.addWidget(ws)
    ws.code.rate.setValue(RATE_HZ)
    ws.clear_calibration()  # “Record uncalibrated”: these recordings need no calibration
    return ws


@pytest.fixture
def capture(qtbot, settings, runner):
    ws = _workspace(qtbot, settings, runner)
    yield ws
    ws.shutdown()
    ws.service.close()


def _wait_ended(qtbot, ws, timeout=20_000):
    qtbot.waitUntil(lambda: not ws.recording, timeout=timeout)


def test_record_n_frames_then_the_recording_opens_with_n_frames(qtbot, capture, tmp_path):
    ws = capture
    rig = ws.service.rig
    assert ws.start_live()  # a running live view gives the devices up to the recording
    qtbot.waitUntil(lambda: ws.live_panel.stats.received >= 1, timeout=10_000)
    path = tmp_path / "run.zarr"
    ws.record_panel.path_edit.setText(str(path))
    ws.record_panel.frames_box.setValue(12)
    with qtbot.waitSignal(ws.recording_finished, timeout=20_000) as finished:
        ws.record_panel.record_button.click()
        assert ws.recording and not ws.live, "Record stops the live view: the capture service owns the camera"
        assert not ws.record_panel.record_button.isEnabled() and not ws.live_panel.live_button.isEnabled()
        assert not ws.record_panel.path_edit.isEnabled() and not ws.code.tile_box.isEnabled()
    result = finished.args[0]
    assert result.ok and result.reason == "done" and result.frames_in_recording == 12
    rec = open_recording(path)
    assert rec.n_frames == 12 and rec.K == 16
    assert rec.ground_truth[:].shape == (12 * 16, 48, 64)  # the simulated scene, kept as truth
    text = ws.record_panel.recording_label.text()
    assert "recording done: 0.20 s of video at 60 Hz; captured 12 frames: 0 dropped" in text
    assert "holds 12 frame(s)" in text
    assert re.search(r"12 of 12 frames written = 0.20 s of video \(\d+ received\) · 0 dropped",
                     ws.record_panel.counters_label.text())
    assert "write" in ws.record_panel.counters_label.text() and "queue" in ws.record_panel.counters_label.text()
    assert ws.live_panel.image_panel.has_image() and ws.live_panel.image_panel.image.image.shape == (48, 64)
    rec = ws.record_panel
    assert rec.record_button.isEnabled() and ws.live_panel.live_button.isEnabled() and rec.review_button.isEnabled()
    assert not rig.camera.acquiring and rig.projector.run_state is RunState.STOPPED
    assert rig.camera.state is DeviceState.ENABLED  # the live view had connected it: left open, stopped
    with qtbot.waitSignal(ws.open_requested) as asked:
        ws.record_panel.review_button.click()
    assert asked.args == [path]


def test_stop_early_keeps_what_was_captured(qtbot, capture, tmp_path):
    ws = capture
    path = tmp_path / "until-stop.zarr"
    ws.record_panel.path_edit.setText(str(path))
    ws.record_panel.frames_box.setValue(0)
    assert ws.record_panel.frames_box.text() == "until Stop"
    assert ws.record()
    qtbot.waitUntil(lambda: ws.capture.stats().rows_written >= 4, timeout=10_000)
    before = ws.record_panel.counters_label.text()
    qtbot.waitUntil(lambda: ws.record_panel.counters_label.text() != before, timeout=5000)  # refreshed on its timer
    assert ws.record_panel.stop_button.isEnabled()
    ws.record_panel.stop_button.click()
    assert not ws.record_panel.stop_button.isEnabled()
    _wait_ended(qtbot, ws)
    result = ws.last_result
    assert result.ok and result.reason == "stopped" and result.frames_in_recording >= 4
    assert open_recording(path).n_frames == result.frames_in_recording
    assert re.search(r"recording done: [\d.]+ s of video at 60 Hz; stopped after \d+ frames: 0 dropped",
                     ws.record_panel.recording_label.text())
    assert ws.service.rig.camera.state is DeviceState.CLOSED  # the service opened it, so it closed it


def test_a_path_in_a_missing_folder_is_refused_in_words(qtbot, capture, tmp_path):
    ws = capture
    ws.record_panel.path_edit.setText("")
    assert not ws.record() and "choose a recording path first" in ws.record_panel.recording_label.text()
    ws.record_panel.path_edit.setText(str(tmp_path / "no-such-folder" / "run.zarr"))
    assert not ws.record()
    assert re.search(r"cannot record: cannot write .*run\.zarr: the folder .*no-such-folder does not exist",
                     ws.record_panel.recording_label.text())
    assert not ws.recording and ws.record_panel.record_button.isEnabled() and ws.capture is None
    existing = tmp_path / "taken.zarr"
    existing.mkdir()
    ws.record_panel.path_edit.setText(str(existing))
    with answering(False) as asked:  # the one rule for an existing file: ask, naming it
        assert not ws.record()
    assert asked == [Question("Replace the existing recording?",
                              f"{existing} already exists. Replace it with the new recording?", "Replace")]
    assert f"not recording: {existing} is kept" in ws.record_panel.recording_label.text() and existing.is_dir()


def test_a_timing_the_projector_refuses_cannot_record(capture, tmp_path):
    ws = capture
    ws.record_panel.path_edit.setText(str(tmp_path / "run.zarr"))
    ws.code.rate.setValue(1000.0)
    assert not ws.record_panel.record_button.isEnabled()
    assert not ws.record() and "cannot record: projector:" in ws.record_panel.recording_label.text()


class _DiskFullWriter(RecordingWriter):
    """Writes two frames, then the disk is full."""

    def append(self, *args, **kwargs):
        if self.count >= 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().append(*args, **kwargs)


def test_a_disk_that_fills_up_ends_the_recording_with_the_reason(qtbot, settings, runner, tmp_path):
    factory = partial(CaptureService, writer_factory=_DiskFullWriter)
    ws = _workspace(qtbot, settings, runner, capture_factory=factory)
    try:
        ws.record_panel.path_edit.setText(str(tmp_path / "full.zarr"))
        ws.record_panel.frames_box.setValue(20)
        ws.record_panel.truth_check.setChecked(False)
        with qtbot.waitSignal(ws.recording_finished, timeout=20_000) as finished:
            assert ws.record()
        result = finished.args[0]
        assert not result.ok and result.frames_in_recording == 2
        text = ws.record_panel.recording_label.text()
        assert "recording failed: capture stopped: cannot write" in text and "the disk is full" in text
        assert "holds 2 frame(s)" in text and "#c0392b" in text
        assert open_recording(tmp_path / "full.zarr").n_frames == 2
    finally:
        ws.shutdown()
        ws.service.close()


def test_the_window_keeps_running_while_it_records(qtbot, capture, tmp_path):
    """The GUI thread is never blocked: a 20 ms timer keeps firing during start, capture and stop."""
    from PySide6.QtCore import QTimer

    ws = capture
    ticks = []
    timer = QTimer()
    timer.setInterval(20)
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start()
    ws.record_panel.path_edit.setText(str(tmp_path / "run.zarr"))
    ws.record_panel.frames_box.setValue(30)  # half a second at 60 Hz
    with qtbot.waitSignal(ws.recording_finished, timeout=20_000):
        assert ws.record()
    timer.stop()
    assert len(ticks) >= 10
    assert ws.last_result.frames_in_recording == 30


def test_counter_and_result_lines():
    from flexvox_app.capture.service import CaptureStats

    s = CaptureStats(frames_received=10, rows_written=9, drops=1, queue_drops=1, queue_depth=2, queue_capacity=64,
                     max_queue_depth=5, write_rate_hz=14.9, camera_rate_hz=15.0, elapsed_s=0.7)
    assert counters_text(s, 100) == ("9 of 100 frames written (10 received) · 1 dropped (1 by the queue) · queue 2/64 "
                                     "(max 5) · write 14.9 Hz · camera 15.0 Hz · 0.7 s since Record")
    # the length of the video, as flexvox info says it: 63 frames at 15 Hz are 4.20 s (7.1 s went by since Record)
    s63 = CaptureStats(frames_received=63, rows_written=63, camera_rate_hz=15.0, elapsed_s=7.1)
    assert counters_text(s63, 63, 1 / 15).startswith("63 of 63 frames written = 4.20 s of video (63 received)")
    assert counters_text(s63, 63, 1 / 15).endswith("7.1 s since Record")
    assert "did not stop within the time allowed" in result_text(None, "x.zarr")


class _RecordingFsync(RecordingWriter):
    """Remembers whether the capture asked for durable writes."""

    seen: list = []

    def __init__(self, *args, fsync=False, **kwargs):
        _RecordingFsync.seen.append(fsync)
        super().__init__(*args, fsync=fsync, **kwargs)


def test_durable_and_a_second_writer_from_the_workspace(qtbot, settings, runner, tmp_path):
    from flexvox_core.writer_lock import WriterLock

    factory = partial(CaptureService, writer_factory=_RecordingFsync)
    ws = _workspace(qtbot, settings, runner, capture_factory=factory)
    try:
        path = tmp_path / "d.zarr"
        ws.record_panel.path_edit.setText(str(path))
        ws.record_panel.frames_box.setValue(3)
        ws.record_panel.truth_check.setChecked(False)
        ws.record_panel.durable_check.setChecked(True)
        assert settings.get_bool("capture/durable", False)
        with qtbot.waitSignal(ws.recording_finished, timeout=20_000) as finished:
            assert ws.record()
        assert finished.args[0].ok and _RecordingFsync.seen[-1] is True
        assert open_recording(path).verify() == []
        with WriterLock(path), answering(True) as asked:  # replace it? yes; but another process writes it
            assert not ws.record()
        assert [q.title for q in asked] == ["Replace the existing recording?"]
        assert re.search(r"cannot record: .*d.zarr is being written by process \d+",
                         ws.record_panel.recording_label.text())
        assert open_recording(path).n_frames == 3  # untouched
    finally:
        ws.shutdown()
        ws.service.close()


def test_a_capture_s_events_reach_the_gui_thread_as_qt_signals(qtbot, tmp_path):
    import threading

    from flexvox_app.capture import CapturePlan
    from flexvox_app.gui.capture.capture_signals import CaptureSignals

    signals = CaptureSignals()
    threads, counters = set(), []
    signals.progress.connect(lambda c, stats: (threads.add(threading.current_thread()), counters.append(stats)))
    capture = CaptureService(small_rig(), CapturePlan(tile=(2, 2), camera_hz=RATE_HZ), tmp_path / "r.zarr", frames=6,
                             progress_every_s=0.02)
    signals.follow(capture)
    assert len(capture.events.progress) == len(capture.events.finished) == 1
    with qtbot.waitSignal(signals.finished, timeout=20_000) as finished:
        capture.start()
    assert finished.args[0] is capture and finished.args[1] is capture.result and capture.result.ok
    assert threads == {threading.main_thread()} and counters[-1] is capture.result.stats
    signals.release()
    assert len(capture.events.progress) == len(capture.events.finished) == 0


def test_the_holder_follows_the_live_view_and_the_recording_and_what_waits_is_refused_in_words(qtbot, capture,
                                                                                               tmp_path):
    ws = capture
    held = []
    ws.model.holder_changed.connect(held.append)
    assert ws.holder is Holder.IDLE and ws.start_live()
    ws.record_panel.path_edit.setText(str(tmp_path / "run.zarr"))
    ws.record_panel.frames_box.setValue(6)
    with qtbot.waitSignal(ws.recording_finished, timeout=20_000):
        assert ws.record()
        assert ws.holder is Holder.RECORDING and not ws.live
        assert not ws.load_calibration(tmp_path / "any.json") and not ws.clear_calibration()
        assert ws.calibration_error == "a recording is running: the calibration changes after it"
        assert not ws.start_live()
        assert ws.live_panel.live_label.text().endswith("cannot start: a recording is running</span>")
    assert ws.holder is Holder.IDLE and held == [Holder.LIVE, Holder.RECORDING, Holder.IDLE]
    assert ws.model.shown(Action.LIVE) is None and ws.live_panel.live_label.text() == "stopped"


def test_a_device_error_at_live_start_goes_once_the_devices_change_state(capture, monkeypatch):
    import flexvox_app.gui.capture.live_panel as live_panel
    from flexvox_app.gui.models.capture_model import Action, Cause
    from flexvox_app.gui.models.live_source import LiveStartError

    def failing(*_args, **_kw):
        raise LiveStartError("the camera did not answer within 2 s")

    monkeypatch.setattr(live_panel, "start_live", failing)
    ws = capture
    assert not ws.start_live()
    shown = ws.model.shown(Action.LIVE)
    assert shown.cause is Cause.DEVICE and "the camera did not answer" in shown.text
    assert "the camera did not answer" in ws.live_panel.live_label.text()
    ws._on_devices("camera")  # the device panel says a device changed state (reconnected)
    assert ws.model.shown(Action.LIVE) is None and "did not answer" not in ws.live_panel.live_label.text()
