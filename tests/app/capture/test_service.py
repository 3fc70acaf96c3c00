"""The capture service on the simulated rig (virtual clock: nothing sleeps for the camera)."""

import errno
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from flexvox_app.capture import CaptureError, CapturePlan, CaptureService, LatestFrame, QueuePolicy, SyncSetting
from flexvox_app.capture.pacing import PacedClock
from flexvox_calibration.capture_setup import CalibrationRefused, CaptureCalibration, SyncTiming
from flexvox_calibration.shutter import make_shutter_patterns
from flexvox_core.design import design_code
from flexvox_core.forward import capture, tiled_code
from flexvox_core.recording import RecordingWriter, open_recording
from rig_drivers.errors import DeviceError, DeviceTimeoutError
from rig_drivers.interfaces import DeviceState, Frame
from rig_drivers.simulated_rig import SimulatedRig

from .simulated_rig_helpers import CODE, PERIOD, PLAN, make_rig


def phase(p: int) -> CaptureCalibration:
    """An identity-map calibration whose sync says phase ``p`` (no trigger delay)."""
    return CaptureCalibration(sync=SyncTiming(p, 0.0, 4, PERIOD, p), calibrated=True)


def test_capture_matches_the_forward_model_with_the_phase_compensated(tmp_path):
    rig = make_rig(phase_slots=3)
    svc = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=12, calibration=phase(3),
                         ground_truth=True)
    result = svc.run()
    assert result.ok and result.reason == "done" and result.frames_in_recording == 12
    assert "captured 12 frames: 0 dropped" in result.message
    rec = open_recording(tmp_path / "r.zarr")
    assert not rec.interrupted and rec.frames.chunks == (1, 16, 24)
    assert rec.per_frame("frame_id").tolist() == list(range(12))
    np.testing.assert_allclose(rec.frames[:], capture(rec.ground_truth[:], CODE), atol=1e-6)
    assert rec.attrs["kind"] == "captured" and rec.attrs["calibration"]["phase_slots"] == 3
    assert rec.attrs["capture"]["rows"] == 12 and rec.attrs["rig"]["sync"] == "simulated sync box"
    s = result.stats
    assert (s.frames_received, s.rows_written, s.drops, s.queue_drops) == (12, 12, 0, 0)
    assert s.write_rate_hz > 0 and s.max_queue_depth <= s.queue_capacity
    # The devices the service opened are closed again.
    assert all(d.state is DeviceState.CLOSED for d in (rig.camera, rig.projector, rig.sync))


def test_latest_frame_is_the_newest(tmp_path):
    slot = LatestFrame()
    assert slot.get() == (None, 0)
    for i in range(3):
        slot.put(Frame(np.zeros((2, 2)), i, float(i)))
    frame, seq = slot.get()
    assert frame.frame_id == 2 and seq == 3
    rig = make_rig()
    svc = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=5)
    svc.run()
    frame, seq = svc.latest()
    assert frame.frame_id == 4 and seq == 5


def test_frame_id_gaps_become_dropped_zero_rows(tmp_path):
    rig = make_rig(seed=3, effects={"dropped_frames": {"probability": 0.3}})
    result = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=20).run()
    rec = open_recording(tmp_path / "r.zarr")
    dropped = rec.per_frame("dropped")
    assert rec.n_frames == 20 and rec.per_frame("frame_id").tolist() == list(range(20))
    assert dropped.sum() == len([i for i in rig.camera.dropped_ids if i < 20]) == result.stats.drops > 0
    assert not rec.frames[:][dropped].any() and rec.frames[:][~dropped].all(axis=(1, 2)).any()


class SlowWriter(RecordingWriter):
    """A disk slower than the camera (sleeps in every append)."""

    delay_s = 0.03

    def append(self, frame, **kw):
        import time

        time.sleep(self.delay_s)
        super().append(frame, **kw)


def test_slow_disk_discards_after_blocking_and_records_the_loss(tmp_path):
    rig = make_rig()
    svc = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=15, writer_factory=SlowWriter,
                         queue_policy=QueuePolicy(capacity=2, block_s=0.001))
    result = svc.run()
    rec = open_recording(tmp_path / "r.zarr")
    s = result.stats
    assert rec.n_frames == 15 and rec.per_frame("frame_id").tolist() == list(range(15))
    assert s.queue_drops > 0 and s.drops == s.queue_drops == int(rec.per_frame("dropped").sum())
    assert s.max_queue_depth <= 2
    assert f"{s.drops} dropped ({s.queue_drops} by the queue)" in result.message


def test_slow_disk_within_the_blocking_time_loses_nothing(tmp_path):
    rig = make_rig()
    result = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=10, writer_factory=SlowWriter,
                            queue_policy=QueuePolicy(capacity=2, block_s=10.0)).run()
    assert result.stats.drops == 0 and result.stats.rows_written == 10


class FullDiskWriter(RecordingWriter):
    """Raises ENOSPC from the 6th frame on."""

    def append(self, frame, **kw):
        if self.count >= 5:
            raise OSError(errno.ENOSPC, "No space left on device")
        super().append(frame, **kw)


def test_full_disk_stops_cleanly_with_a_valid_recording(tmp_path):
    rig = make_rig()
    result = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=50, writer_factory=FullDiskWriter).run()
    assert not result.ok and result.reason == "error" and result.frames_in_recording == 5
    assert result.message.startswith("capture stopped: cannot write")
    assert "the disk is full" in result.message and "holds 5 frame(s) and opens cleanly" in result.message
    rec = open_recording(tmp_path / "r.zarr")
    assert rec.n_frames == 5 and rec.attrs["capture"]["reason"] == "error"
    assert all(d.state is DeviceState.CLOSED for d in (rig.camera, rig.projector, rig.sync))


class VanishingWriter(RecordingWriter):
    """Its folder is deleted after 3 frames."""

    def append(self, frame, **kw):
        if self.count == 3:
            shutil.rmtree(self.path)
        super().append(frame, **kw)


def test_vanished_folder_stops_with_a_clear_message(tmp_path):
    result = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=50, writer_factory=VanishingWriter).run()
    assert result.reason == "error" and result.frames_in_recording is None
    assert "the recording folder" in result.message and "vanished" in result.message
    assert "the recording cannot be opened" in result.message


def test_a_recording_that_cannot_be_created_says_why_and_leaves_nothing(tmp_path, monkeypatch):
    """The recording's first metadata file refused (EFBIG, as under ``ulimit -f``): the capture says so and that
    nothing was recorded, and leaves no folder that would read as a damaged recording."""
    import zarr

    def refused(store, **kw):
        Path(store).mkdir()
        raise OSError(errno.EFBIG, "File too large")

    monkeypatch.setattr(zarr, "open_group", refused)
    rig = make_rig()
    result = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=50).run()
    assert not result.ok and result.reason == "error" and result.frames_in_recording is None
    assert re.fullmatch(r"capture stopped: cannot create \S*r\.zarr: a file would pass the file-size limit "
                        r"\(`ulimit -f`\) or the largest file the file system holds \(\[Errno 27\] File too large\); "
                        r"nothing was recorded \(\S*r\.zarr was not created\); 0 dropped \(0 by the queue\)",
                        result.message), result.message
    assert list(tmp_path.iterdir()) == []
    assert all(d.state is DeviceState.CLOSED for d in (rig.camera, rig.projector, rig.sync))
    monkeypatch.undo()
    assert CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=3).run().ok
    monkeypatch.setattr(zarr, "open_group", refused)
    result = CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=5, overwrite=True).run()
    assert not result.ok and result.message.endswith(
        f"nothing was recorded; the recording that was at {tmp_path / 'r.zarr'} is unchanged; 0 dropped (0 by the "
        "queue)")
    monkeypatch.undo()
    assert open_recording(tmp_path / "r.zarr").n_frames == 3


def test_a_capture_stopped_before_its_first_frame_that_cannot_create_its_recording_says_so(tmp_path, monkeypatch):
    import zarr

    def refused(store, **kw):
        Path(store).mkdir()
        raise OSError(errno.ENOSPC, "No space left on device")

    def never(timeout_s):
        raise DeviceTimeoutError("no frame")

    rig = make_rig()
    monkeypatch.setattr(rig.camera, "_do_read_frame", never)
    monkeypatch.setattr(zarr, "open_group", refused)
    svc = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=None, sync=SyncSetting(read_slice_s=0.01))
    svc.start()
    result = svc.stop(timeout_s=10)
    assert result.reason == "error" and not result.ok and result.frames_in_recording is None
    assert re.fullmatch(r"capture stopped: cannot create \S*r\.zarr: the disk is full \(\[Errno 28\] No space left on "
                        r"device\); nothing was recorded \(\S*r\.zarr was not created\); 0 dropped \(0 by the queue\)",
                        result.message), result.message
    assert list(tmp_path.iterdir()) == []


def test_camera_unplugged_keeps_the_frames_received(tmp_path, monkeypatch):
    rig = make_rig()
    real = rig.camera._do_read_frame
    calls = {"n": 0}

    def flaky(timeout_s):
        calls["n"] += 1
        if calls["n"] > 4:
            raise DeviceError("USB device disconnected")
        return real(timeout_s)

    monkeypatch.setattr(rig.camera, "_do_read_frame", flaky)
    result = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=50).run()
    assert result.reason == "error" and result.frames_in_recording == 4
    assert "the camera failed (unplugged?): USB device disconnected" in result.message
    assert "holds 4 frame(s)" in result.message


def test_no_frame_timeout_and_prompt_stop(tmp_path, monkeypatch):
    rig = make_rig()

    def never(timeout_s):
        raise DeviceTimeoutError("no frame")

    monkeypatch.setattr(rig.camera, "_do_read_frame", never)
    svc = CaptureService(rig, PLAN, tmp_path / "r.zarr", frames=5,
                         sync=SyncSetting(read_slice_s=0.01, no_frame_timeout_s=0.05))
    result = svc.run()
    assert result.reason == "error" and "no frame from the camera for 0.05 s" in result.message
    assert result.frames_in_recording == 0
    # Until stopped: stop() returns a result (its waits are bounded).
    svc2 = CaptureService(make_rig(), PLAN, tmp_path / "s.zarr", frames=None)
    svc2.start()
    result2 = svc2.stop(timeout_s=10)
    assert result2 is not None and result2.reason == "stopped"
    from flexvox_core.recording import open_recording

    assert result2.frames_in_recording == open_recording(tmp_path / "s.zarr").n_frames  # what it says is there
    with pytest.raises(CaptureError, match=r"a service captures once"):
        svc2.start()


def test_setup_errors_are_clear(tmp_path):
    with pytest.raises(CaptureError, match=r"r.zarr already exists; choose another path, or pass overwrite=True"):
        (tmp_path / "r.zarr").mkdir()
        CaptureService(make_rig(), PLAN, tmp_path / "r.zarr", frames=1)
    with pytest.raises(CaptureError, match=r"shortest is 235 µs"):
        CaptureService(make_rig(), CapturePlan.from_code(CODE, camera_hz=5000), tmp_path / "a.zarr",
                       frames=1).start()
    with pytest.raises(CalibrationRefused, match=r"`phase_slots` must be a whole number 0..3; got 4"):
        phase(4)
    with pytest.raises(CaptureError, match=r"`frames` must be a whole number >= 1 or None; got 0"):
        CaptureService(make_rig(), PLAN, tmp_path / "c.zarr", frames=0)
    with pytest.raises(CalibrationRefused, match=r"`homography` must be a finite 3x3 matrix"):
        CaptureCalibration(homography=np.eye(2))
    rig = make_rig()
    with pytest.raises(CaptureError, match=r"the sync setting asks for a sync box, but the rig has none"):
        rig.sync = None
        CaptureService(rig, PLAN, tmp_path / "d.zarr", frames=1, sync=SyncSetting(use_sync_box=True)).start()
    assert rig.camera.state is DeviceState.CLOSED  # set-up failures close what they opened


def test_patterns_identity_phase_and_shift():
    code = design_code((4, 4)).code
    p = make_shutter_patterns(code, np.eye(3), (8, 12), (8, 12)).patterns
    np.testing.assert_array_equal(p, tiled_code(code, 8, 12))
    np.testing.assert_array_equal(make_shutter_patterns(code, np.eye(3), (8, 12), (8, 12), phase_slots=5).patterns,
                                  np.roll(p, 5, axis=0))
    # Projector pixel (x, y) lands on camera pixel (x + 2, y + 1).
    h = np.array([[1, 0, 2], [0, 1, 1], [0, 0, 1]], float)
    q = make_shutter_patterns(code, h, (8, 12), (8, 12)).patterns
    np.testing.assert_array_equal(q[:, :7, :10], p[:, 1:, 2:])
    assert not q[:, 7:, :].any() and not q[:, :, 10:].any()  # lands outside the camera: dark
    with pytest.raises(ValueError, match=r"`phase_slots` must be a whole number 0..15; got 16"):
        make_shutter_patterns(code, np.eye(3), (8, 12), (8, 12), phase_slots=16)


def test_paced_clock_only_moves_when_sleeping():
    clock = PacedClock()
    t = clock.now_us()
    assert clock.now_us() == t == clock()
    clock.sleep_until_us(t + 2000)
    assert clock.now_us() >= t + 2000
    before = clock.now_us()
    clock.sleep_until_us(0)  # already past: jumps to the wall clock, never backwards
    assert clock.now_us() >= before
    frozen = clock.now_us()
    clock.resync()
    assert clock.now_us() >= frozen


def test_capture_on_a_dlpc350_uses_its_video_port(tmp_path):
    """The LightCrafter runs VSYNC-triggered sequences from its video input; capture must ask for one."""
    from flexvox_core.recording import open_recording
    from rig_drivers.interfaces import ProjectorTrigger

    from ...rig_drivers.display_rig import RecordingScreen, display_rig

    screen = RecordingScreen()
    rig = display_rig(screen)
    service = CaptureService(rig, CapturePlan(tile=(2, 4)), tmp_path / "r.zarr", frames=3, projector_size=(48, 64))
    result = service.run(timeout_s=20.0)
    assert result.ok, result.message
    assert rig.projector.sequence.trigger is ProjectorTrigger.VSYNC
    assert screen.calls and open_recording(tmp_path / "r.zarr").n_frames == 3


def test_capture_refuses_a_sync_box_with_a_video_port_projector(tmp_path):
    from rig_drivers.simulated import SimulatedSyncController

    from ...rig_drivers.display_rig import RecordingScreen, display_rig

    rig = display_rig(RecordingScreen())
    rig = type(rig)(rig.projector, rig.camera, SimulatedSyncController(), rig.spec)
    service = CaptureService(rig, CapturePlan(tile=(2, 4)), tmp_path / "r.zarr", frames=2, projector_size=(48, 64))
    with pytest.raises(CaptureError, match=r"a sync box cannot clock it.*kind = \"projector-trigger\""):
        service.run(timeout_s=20.0)


def test_the_simulated_camera_warms_up_before_the_first_trigger_and_charges_the_capture_no_frame(tmp_path,
                                                                                                 monkeypatch):
    """The VGA case (frames 1–38 lost): the patterns' warp into camera pixels took a second at the first
    exposure, on a paced clock that stood still through the set-up. Now the camera warps them when its
    acquisition starts, before the projector triggers it, and brings the paced clock up to the wall after."""
    import time

    import rig_drivers.simulated_rig as simulated_rig

    warp = simulated_rig.warp_patterns
    warped_at = []

    def slow_warp(*args, **kw):  # as slow as VGA's warp, at a size a test renders quickly
        time.sleep(1.5)
        warped_at.append(rig.projector.run_state.value)
        return warp(*args, **kw)

    monkeypatch.setattr(simulated_rig, "warp_patterns", slow_warp)
    clock = PacedClock()
    rig = SimulatedRig.create("balls", camera_size=(48, 64), subframes=64, clock=clock)
    plan = CapturePlan(tile=(4, 4), camera_hz=15.0)
    result = CaptureService(rig, plan, tmp_path / "first.zarr", frames=8, calibration=CaptureCalibration()).run()
    assert warped_at == ["stopped"]  # once, before the projector ran
    assert rig.camera.dropped_ids == [] and result.stats.drops == 0 and result.ok, result.message
    assert open_recording(tmp_path / "first.zarr").per_frame("frame_id").tolist() == list(range(8))
    rig.close()


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


def test_the_drift_note_says_sub_second_drifts_in_milliseconds():
    from flexvox_app.capture.plan import CapturePlan

    notes = " ".join(CapturePlan(camera_hz=200.0).timing().notes)
    assert "drifts one slot every" in notes and "every 0 s" not in notes, notes


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


def test_a_capture_into_a_name_not_ending_in_zarr_is_refused_before_the_rig_opens(tmp_path):
    """The GUI and Python's CaptureService share the command line's rule: a recording's folder ends in .zarr."""
    rig = make_rig()
    with pytest.raises(CaptureError, match=r"a recording \(a Zarr store\) is a folder whose name ends in .zarr: "
                                           r".*run1.npy ends in .npy; write .*run1.zarr"):
        CaptureService(rig, PLAN, tmp_path / "run1.npy", frames=2)
    assert list(tmp_path.iterdir()) == []
