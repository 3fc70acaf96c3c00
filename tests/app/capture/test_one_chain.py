"""One acquisition chain on the one simulated rig: calibrate it, capture through the calibration, check the slots.

The ``--rig mock`` rig is built as a real one (a projector twice as fine as the camera behind a hidden
homography, a trigger offset that is not a whole slot), so these tests fail when any step of the chain
(patterns, phase, trigger delay, calibration loading) goes wrong. The ``strobe`` scene (one flash every
17 sub-frames) lets a recording of 17 frames say which slot every camera pixel sampled.
"""

import numpy as np
import pytest

from flexvox_app.capture import CapturePlan, CaptureService
from flexvox_app.capture.rig_setup import set_up_rig, stop_rig
from flexvox_app.cli import main as cli_main
from flexvox_calibration.capture_setup import (
    CalibrationRefused,
    CaptureCalibration,
    SyncTiming,
    from_run,
    load_for_capture,
    load_sync_for_capture,
)
from flexvox_calibration.pipeline import run_calibration
from flexvox_calibration.session import RigSession
from flexvox_core.recording import open_recording
from flexvox_core.slot_check import slot_accuracy
from rig_drivers.dlpc350.bitplanes import pack_bitplanes
from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock

SEED = 0
FRAMES = 17  # the strobe visits every slot of K = 16 in 17 frames


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory):
    """``flexvox calibrate --rig mock -o CAL.json`` (the default rig, seed 0)."""
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    assert cli_main.main(["calibrate", "--rig", "mock", "--seed", str(SEED), "-o", str(path)]) == 0
    return path


def mock_rig(scene="strobe"):
    return open_rig("mock", scene=scene, seed=SEED, clock=VirtualClock())


def record(rig, calibration, path, *, plan=None):
    plan = plan or CapturePlan()
    service = CaptureService(rig, plan, path, frames=FRAMES, calibration=calibration,
                             ground_truth=True)
    result = service.run()
    assert result.ok, result.message
    return open_recording(path)


def slots(rec):
    return slot_accuracy(rec.normalised_frames(), rec.ground_truth[:], rec.code)


def test_the_cli_records_through_its_calibration_and_every_slot_is_right(calibration_file, tmp_path, capsys):
    out = tmp_path / "r.zarr"
    assert cli_main.main(["capture", "--rig", "mock", "--seed", str(SEED), "--scene", "strobe", "--frames",
                          str(FRAMES), "--clock", "virtual", "--ground-truth", "--calibration",
                          str(calibration_file), "-o", str(out)]) == 0
    rec = open_recording(out)
    truth = mock_rig().simulated.truth
    # The exposure opens part-way into a slot: the delay that moves it to the next boundary goes with phase + 1.
    assert 0 < truth.delay_us < 4166
    assert rec.attrs["calibration"]["phase_slots"] == (truth.phase_slots + 1) % 16
    assert rec.attrs["calibration"]["trigger_delay_us"] == pytest.approx(4166 - truth.delay_us, abs=60)
    assert rec.attrs["rig"]["trigger_delay_set_by"] == "camera"
    check = slots(rec)
    assert check.decidable_fraction > 0.95 and check.accuracy == 1.0, check.describe()
    assert "phase" in capsys.readouterr().out
    # `flexvox info --slots` says the same
    assert cli_main.main(["info", str(out), "--slots"]) == 0
    text = capsys.readouterr().out
    assert "slot accuracy 100.0% of the 19200 of 19200 pixels (100.0%)" in text and "camera trigger delay" in text


def test_a_mock_capture_at_another_size_says_how_to_go_on(calibration_file, tmp_path, capsys):
    # `flexvox calibrate` cannot size the simulated rig, so "calibrate this rig" alone could not be followed
    code = cli_main.main(["capture", "--rig", "mock", "--size", "64x80", "--calibration", str(calibration_file),
                          "--frames", "2", "-o", str(tmp_path / "r.zarr")])
    err = capsys.readouterr().err
    assert code == 2 and "made for a camera resolution of 120x160, this rig's is 64x80" in err
    assert "the simulated rig is calibrated at its default 120x160 camera only" in err
    assert "capture at 120x160, or leave out --calibration" in err and not (tmp_path / "r.zarr").exists()


def test_the_raw_phase_or_no_calibration_visibly_fail(calibration_file, tmp_path):
    rig = mock_rig()
    good = load_for_capture(calibration_file, RigSession.from_rig(rig).identity)
    s = good.sync
    # The phase of a zero camera delay, used with the recommended delay (what the Capture workspace did).
    raw = good.with_sync(SyncTiming(s.raw_phase_slots, s.trigger_delay_us, s.K, s.period_us, s.raw_phase_slots))
    assert slots(record(rig, raw, tmp_path / "raw.zarr")).accuracy < 0.05
    uncalibrated = slots(record(mock_rig(), None, tmp_path / "none.zarr"))
    assert uncalibrated.accuracy < 0.5, uncalibrated.describe()


def test_a_camera_without_a_trigger_delay_needs_the_operator(calibration_file, tmp_path, monkeypatch):
    from dataclasses import replace

    from flexvox_app.capture import CaptureError, SyncSetting
    from rig_drivers.simulated_camera import SimulatedCamera

    caps = SimulatedCamera.capabilities.fget
    monkeypatch.setattr(SimulatedCamera, "capabilities", property(lambda self: replace(caps(self),
                                                                                       trigger_delay=False)))
    rig = mock_rig()
    cal = load_for_capture(calibration_file, RigSession.from_rig(rig).identity)
    with pytest.raises(CaptureError, match=r"needs a \d+ µs camera trigger delay, and simulated camera cannot be "
                                           r"told one: set it on the camera"):
        CaptureService(rig, CapturePlan(), tmp_path / "r.zarr", frames=2, calibration=cal).run()
    confirmed = CaptureService(mock_rig(), CapturePlan(), tmp_path / "s.zarr", frames=2, calibration=cal,
                               sync=SyncSetting(delay_set_by_hand=True)).run()
    assert confirmed.ok and open_recording(tmp_path / "s.zarr").attrs["rig"]["trigger_delay_set_by"] == "operator"


def test_the_patterns_calibration_verified_are_the_patterns_projected(tmp_path):
    """Under a non-trivial homography with a projector finer than the camera, bit for bit."""
    rig = mock_rig()
    h_true = rig.simulated.truth.homography
    assert rig.projector.size == (240, 320) and not np.allclose(h_true, np.eye(3))
    session = RigSession.from_rig(rig)
    run = run_calibration(rig, session, tile=(4, 4))
    assert run.success, run.report
    verified = run.keep["shutter_patterns"]
    assert run.report["shutter"]["accuracy"] == 1.0
    cal = from_run(run, session.identity, RigSession.from_rig(rig).identity)
    phase = cal.phase_slots
    plan = CapturePlan()
    service = CaptureService(rig, plan, tmp_path / "r.zarr", frames=2, calibration=cal)
    assert service.run().ok
    projected = rig.projector.sequence.patterns
    np.testing.assert_array_equal(projected, np.roll(verified.patterns, phase, axis=0))
    # The live view (the same set-up, as a preview) and the projector output window show the same masks.
    set_up_rig(rig, plan, cal, preview=True)
    np.testing.assert_array_equal(rig.projector.sequence.patterns, projected)
    stop_rig(rig)
    np.testing.assert_array_equal(plan.patterns(rig.camera.sensor_shape, rig.projector.size, cal).packed,
                                  pack_bitplanes(projected))


def test_at_the_lightcrafters_size_too(tmp_path):
    """A 912x1140 DMD over a 640x480 camera: where OpenCV's warp and calibration's rounding parted (13-38
    projector pixels per seed on the old capture path), the projected masks are the verified ones."""
    from flexvox_calibration.shutter import make_shutter_patterns

    rig = open_rig("mock", scene="static", subframes=16, camera_size=(480, 640), projector_size=(1140, 912),
                   seed=SEED, clock=VirtualClock())
    h = rig.simulated.truth.homography
    sync = SyncTiming(5, 1000.0, 16, CapturePlan().period_us, 4)
    cal = CaptureCalibration(h, sync, calibrated=True)
    assert CaptureService(rig, CapturePlan(), tmp_path / "r.zarr", frames=1, calibration=cal).run().ok
    verified = make_shutter_patterns(CapturePlan().code, h, (480, 640), (1140, 912))
    np.testing.assert_array_equal(rig.projector.sequence.patterns, np.roll(verified.patterns, 5, axis=0))


def test_a_sync_profile_replaces_the_calibrations_timing(calibration_file, tmp_path):
    from flexvox_calibration.files import write_versioned
    from flexvox_calibration.sync import SYNC_FORMAT, SYNC_VERSION

    rig = mock_rig()
    identity = RigSession.from_rig(rig).identity
    cal = load_for_capture(calibration_file, identity)
    sync = {"status": "ok", "K": 16, "period_us": 4166, "phase_slots": 3, "delay_us": 1000.0,
            "recommended_camera_delay_us": 3166.0, "effective_phase_slots": 4}
    profile = write_versioned(tmp_path / "sync.json", SYNC_FORMAT, SYNC_VERSION, identity, {"sync": sync})
    both = load_sync_for_capture(profile, identity, base=cal)
    np.testing.assert_array_equal(both.homography, cal.homography)
    assert (both.phase_slots, both.trigger_delay_us) == (4, 3166.0) and "sync.json" in both.source
    alone = load_sync_for_capture(profile, identity)
    assert not alone.calibrated and alone.phase_slots == 4
    # each kind of file is refused where the other is expected (a calibration's homography must not slip in)
    with pytest.raises(CalibrationRefused, match=r"sync.json is a sync profile .* not a calibration: it has no "
                                                 r"homography\. Give it as a sync profile \(flexvox capture --sync"):
        load_for_capture(profile, identity)
    with pytest.raises(CalibrationRefused, match=r"cal.json is a calibration file, not a sync profile: give it as "
                                                 r"the calibration \(flexvox capture --calibration"):
        load_sync_for_capture(calibration_file, identity, base=cal)
    assert CaptureCalibration().for_plan(16, 4166)[:2] == (0, 0.0)


def test_info_slots_needs_ground_truth(calibration_file, tmp_path):
    from flexvox_app.cli.errors import CliError

    out = tmp_path / "r.zarr"
    assert cli_main.main(["capture", "--rig", "mock", "--scene", "static", "--frames", "2", "--clock", "virtual",
                          "--calibration", str(calibration_file), "-o", str(out)]) == 0
    with pytest.raises(CliError, match=r"holds no ground truth: --slots needs a simulated recording"):
        from flexvox_app.cli import info

        info.run(type("Args", (), {"recording": out, "repair": False, "slots": True, "json": False, "quick": False})())
