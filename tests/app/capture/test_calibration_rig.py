"""A calibration object handed to the capture service: refused on another rig as its file is, and its timing
warnings reach the user (a CalibrationWarning, a WARNING in the log, the result's ``warnings``)."""

import logging
import re

import pytest

from flexvox_app.capture import CaptureError, CapturePlan, CaptureService
from flexvox_app.capture.rig_setup import set_up_rig
from flexvox_app.capture.service import warnings_shown_by_caller
from flexvox_calibration import CalibrationRefused, CalibrationWarning, calibrate_rig, load_rig_calibration
from flexvox_calibration.capture_setup import CaptureCalibration
from flexvox_calibration.session import RigSession
from rig_drivers import open_rig
from rig_drivers.simulated_camera import VirtualClock

SIZE = (48, 64)
OTHER_RIG = (r"was made for rig 'simulated rig \(mock, seed 0\)', not 'simulated rig \(mock, seed 1\)': calibrate "
             r"this rig \(flexvox calibrate\) instead of reusing it \(or open the simulated rig with the seed it was "
             r"made on: --seed\)")
OTHER_SIZE = (r"was made for a camera resolution of 48x64, this rig's is 40x64: calibrate this rig \(flexvox "
              r"calibrate\) instead of reusing it")


def _rig(seed=0, size=SIZE):
    return open_rig("mock", scene="strobe", camera_size=size, seed=seed, clock=VirtualClock())


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """(the calibration just run, the same saved and loaded back, its file) on the seed-0 rig."""
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    rig = _rig()
    try:
        run = calibrate_rig(rig, progress=False)
        saved = calibrate_rig(rig, progress=False, save=path)
    finally:
        rig.close()
    return run, saved, path


def test_calibrations_keep_the_rig_they_were_made_for(calibrated):
    run, saved, _ = calibrated
    rig = _rig()
    identity = RigSession.from_rig(rig).identity.as_dict()
    rig.close()
    assert run.rig == identity and saved.rig == identity
    assert CaptureCalibration().rig is None
    with pytest.raises(CalibrationRefused, match=r"`rig` must be a RigIdentity, its as_dict\(\), or None; got str"):
        CaptureCalibration(rig="simulated rig (mock, seed 0)")


def test_the_rig_it_was_made_on_takes_it(calibrated, tmp_path):
    run, saved, _ = calibrated
    rig = _rig()
    try:
        for i, cal in enumerate((run, saved)):
            result = CaptureService(rig, CapturePlan(tile=(4, 4)), tmp_path / f"r{i}.zarr", frames=2,
                                    calibration=cal).run(timeout_s=60)
            assert result.ok and result.frames_in_recording == 2 and result.warnings == ()
    finally:
        rig.close()


@pytest.mark.parametrize(("seed", "size", "words"), [(1, SIZE, OTHER_RIG), (0, (40, 64), OTHER_SIZE)])
def test_another_rig_or_camera_size_refuses_the_object_as_it_refuses_the_file(calibrated, tmp_path, seed, size,
                                                                             words):
    run, saved, path = calibrated
    rig = _rig(seed, size)
    try:
        with pytest.raises(CalibrationRefused, match=rf"^{re.escape(str(path))} {words}"):
            load_rig_calibration(rig, path)
        with pytest.raises(CalibrationRefused, match=rf"^the calibration just run \(not saved\) {words}"):
            CaptureService(rig, CapturePlan(tile=(4, 4)), tmp_path / "r.zarr", frames=2, calibration=run)
        with pytest.raises(CalibrationRefused, match=rf"^{re.escape(str(path))} \(sha256 [0-9a-f]{{16}}\) {words}"):
            CaptureService(rig, CapturePlan(tile=(4, 4)), tmp_path / "r.zarr", frames=2, calibration=saved)
        # the live view's set-up too (a front end may set the rig up without a service)
        with pytest.raises(CaptureError, match=rf"^the calibration just run \(not saved\) {words}"):
            set_up_rig(rig, CapturePlan(tile=(4, 4)), run, preview=True)
    finally:
        rig.close()
    assert not (tmp_path / "r.zarr").exists()


def test_a_phase_that_is_a_guess_is_warned_logged_and_in_the_result(calibrated, tmp_path, caplog):
    run, _, _ = calibrated
    rig = _rig()
    guess = (r"the sync was measured at K = 16, 4166 µs patterns; this capture is K = 8, \d+ µs: phase \d+ is a "
             r"guess, run the synchronisation at this timing")
    caplog.set_level(logging.INFO, logger="flexvox_app.capture.service")
    try:
        with pytest.warns(CalibrationWarning, match=guess) as caught:
            svc = CaptureService(rig, CapturePlan(tile=(2, 4)), tmp_path / "g.zarr", frames=2, calibration=run)
        assert caught[0].filename == __file__  # at the line that built the service
        assert [r.levelno for r in caplog.records if re.search(guess, r.getMessage())] == [logging.WARNING]
        result = svc.run(timeout_s=60)
        assert result.ok and len(result.warnings) == 1 and re.fullmatch(guess, result.warnings[0])
        caplog.clear()
        with warnings_shown_by_caller():  # a front end that shows them itself: only the log, at INFO
            svc = CaptureService(rig, CapturePlan(tile=(2, 4)), tmp_path / "h.zarr", frames=2, calibration=run)
        assert re.fullmatch(guess, svc.warnings[0])
        assert [r.levelno for r in caplog.records if re.search(guess, r.getMessage())] == [logging.INFO]
    finally:
        rig.close()
