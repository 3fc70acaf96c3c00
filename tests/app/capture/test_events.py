"""The capture's events: the small signal, their order, and subscribers that cannot hold a capture up."""

import logging
import threading
import time

import pytest

from flexvox_app.capture import CaptureService, Signal
from flexvox_app.capture.engine import AcquisitionEngine, CameraStopped
from flexvox_app.capture.settings import SyncSetting
from flexvox_calibration.capture_setup import CaptureCalibration
from flexvox_core.recording import open_recording
from rig_drivers.errors import DeviceTimeoutError

from .simulated_rig_helpers import PLAN, make_rig


def test_a_signal_calls_its_callbacks_in_order_and_logs_one_that_raises(caplog):
    signal = Signal("progress")
    calls = []

    def broken(x):
        raise RuntimeError("a subscriber's bug")

    signal.connect(lambda x: calls.append(("a", x)))
    signal.connect(broken)
    second = signal.connect(lambda x: calls.append(("b", x)))
    with caplog.at_level(logging.ERROR, logger="flexvox_app.capture.events"):
        signal.emit(1)
    assert calls == [("a", 1), ("b", 1)] and len(signal) == 3
    assert "a subscriber to progress failed" in caplog.text and "a subscriber's bug" in caplog.text
    signal.disconnect(second)
    signal.disconnect(second)  # not connected any more: nothing happens
    signal.emit(2)
    assert calls[-1] == ("a", 2) and len(signal) == 2
    with pytest.raises(TypeError, match=r"`callback` of progress must be callable; got int"):
        signal.connect(3)
    model_signal = Signal("changed", contain=False)  # a model on the GUI thread: the error reaches the emitter
    model_signal.connect(broken)
    with pytest.raises(RuntimeError, match=r"a subscriber's bug"):
        model_signal.emit(1)


def test_a_capture_publishes_started_progress_and_finished_in_order(tmp_path):
    svc = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=12, progress_every_s=0.01)
    seen = []
    ended = threading.Event()
    svc.events.started.connect(lambda setup: seen.append(("started", setup)))
    svc.events.progress.connect(lambda stats: seen.append(("progress", stats)))
    svc.events.finished.connect(lambda result: (seen.append(("finished", result)), ended.set()))
    result = svc.run()
    assert ended.wait(10)
    names = [name for name, _ in seen]
    assert names[0] == "started" and names[-2:] == ["progress", "finished"] and names.count("finished") == 1
    assert set(names[1:-1]) <= {"progress"}
    assert seen[0][1] is svc.setup and seen[-1][1] is result
    assert seen[-2][1] is result.stats and result.stats.rows_written == 12 and result.stats.state == "done"
    rows = [stats.rows_written for name, stats in seen if name == "progress"]
    assert rows == sorted(rows)  # counters only grow


def test_a_subscriber_that_never_returns_does_not_hold_the_capture_up(tmp_path):
    """Events run on a thread of their own: the reader and the writer never wait for a subscriber."""
    svc = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=20, progress_every_s=0.01)
    threads = set()

    def stuck(stats):  # returns only once the capture has ended: it holds the event thread for the whole capture
        threads.add(threading.current_thread().name)
        deadline = time.monotonic() + 60
        while svc.result is None and time.monotonic() < deadline:
            time.sleep(0.01)

    svc.events.progress.connect(stuck)
    ended = threading.Event()
    svc.events.finished.connect(lambda result: ended.set())
    result = svc.run(timeout_s=30)
    assert ended.is_set()  # run() returns once finished was delivered
    assert result.ok and result.stats.drops == 0 and open_recording(tmp_path / "r.zarr").n_frames == 20
    assert threads == {"flexvox-capture-events"}


def test_stop_returns_after_the_last_progress_and_finished_were_delivered(tmp_path):
    """In a notebook a subscriber prints: its output belongs to the cell that stopped the capture."""
    svc = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", progress_every_s=0.01)
    seen = []

    def slow_finished(result):
        time.sleep(0.2)  # a subscriber that takes a while (printing, drawing)
        seen.append(("finished", result))

    svc.events.progress.connect(lambda stats: seen.append(("progress", stats)))
    svc.events.finished.connect(slow_finished)
    svc.start()
    result = svc.stop(timeout_s=30)
    assert [name for name, _ in seen[-2:]] == ["progress", "finished"]
    assert seen[-1][1] is result is svc.result and seen[-2][1] is result.stats and result.reason == "stopped"
    assert svc.wait(0)  # ended, and every event delivered


def test_wait_waits_for_the_events_and_stop_gives_the_result_when_a_subscriber_hangs(tmp_path, caplog):
    svc = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=5, progress_every_s=0.01)
    release = threading.Event()
    svc.events.finished.connect(lambda result: release.wait(60))
    assert not svc.wait(0)  # not started
    svc.start()
    try:
        deadline = time.monotonic() + 30
        while svc.result is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert svc.result is not None and svc.result.reason == "done"
        assert not svc.wait(0.05)  # the recording is finalised, but finished has not been delivered
        with caplog.at_level(logging.WARNING, logger="flexvox_app.capture.service"):
            result = svc.stop(timeout_s=0.05)
        assert result is svc.result
        assert "a subscriber to its events still runs 0.05 s after the stop" in caplog.text
    finally:
        release.set()
    assert svc.wait(10)


def test_a_subscriber_may_wait_for_the_capture_from_the_event_thread(tmp_path):
    """``wait`` called from a subscriber waits for the capture's end only (the event it runs in cannot wait for
    itself)."""
    svc = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=5, progress_every_s=0.01)
    answers = []
    svc.events.finished.connect(lambda result: answers.append(svc.wait(5)))
    result = svc.run(timeout_s=30)
    assert result.ok and answers == [True]


def test_the_engine_reads_until_stopped_and_says_when_the_camera_stops_delivering(monkeypatch):
    rig = make_rig()
    engine = AcquisitionEngine(rig, PLAN, CaptureCalibration(), SyncSetting(read_slice_s=0.01,
                                                                             no_frame_timeout_s=0.05))
    assert engine.frame_period_s == 0.0
    engine.set_up()
    try:
        assert engine.frame_period_s == pytest.approx(4 * PLAN.period_us / 1e6)
        stop = threading.Event()
        ids = []
        for frame in engine.frames(stop):
            ids.append(frame.frame_id)
            if len(ids) == 3:
                stop.set()
        assert ids == [0, 1, 2]

        def never(timeout_s):
            raise DeviceTimeoutError("no frame")

        monkeypatch.setattr(rig.camera, "_do_read_frame", never)
        with pytest.raises(CameraStopped, match=r"no frame from the camera for 0.05 s \(no frame\)"):
            next(engine.frames(threading.Event()))
    finally:
        engine.tear_down()
    assert not rig.camera.acquiring
