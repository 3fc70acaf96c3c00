"""Phase, sub-slot delay, drops and drift on the simulated rig."""

import numpy as np
import pytest

from flexvox_calibration.errors import CalibrationError, CalibrationMismatchError
from flexvox_calibration.session import RigSession
from flexvox_calibration.sync import band_patterns, check_frames, load_sync_profile, measure_sync, save_sync_profile
from rig_drivers.interfaces import TriggerConfig, TriggerSource
from tests.rig_drivers.mock_rigs import calibration_rig

from .conftest import SEEDS


@pytest.mark.parametrize("seed", SEEDS)
def test_phase_found_exactly_and_delay_within_a_fortieth_of_a_slot(calibrated, seed):
    rig, res = calibrated[seed]
    truth = rig.simulated.truth
    with RigSession.from_rig(rig) as session:
        sync = measure_sync(session, res.homography, K=16)
    assert sync.status == "ok", sync.message
    assert sync.phase_slots == truth.phase_slots
    assert sync.delay_us == pytest.approx(truth.delay_us, abs=4166 / 40)
    assert sync.slope == pytest.approx(1.0, abs=0.05)
    lk = np.asarray(sync.leakage)
    p = truth.phase_slots
    assert np.all(np.abs(lk[:p]) < 0.02) and np.all(np.abs(lk[p + 1:] - 1) < 0.02)
    assert lk[p] == pytest.approx(1 - truth.delay_us / 4166, abs=0.03)
    assert sync.effective_phase_slots == (p + 1) % 16
    assert sync.recommended_camera_delay_us == pytest.approx(4166 - truth.delay_us, abs=4166 / 40)


def test_recommended_delay_opens_the_exposure_on_a_slot_boundary(calibrated):
    rig, res = calibrated[0]
    p = rig.simulated.truth.phase_slots
    with RigSession.from_rig(rig) as session:
        sync = measure_sync(session, res.homography)
        pats, band = band_patterns(res.homography, session.camera_size, session.projector_size, 16)
        session.set_camera_delay(sync.recommended_camera_delay_us)
        dark = session.capture_single_shot(np.zeros_like(pats))
        once = session.capture_single_shot(pats)
        session.show(pats)
        full = session.frames(1)[0].image
    b = np.array([(once - dark)[band == k].sum() / (full - dark)[band == k].sum() for k in range(16)])
    # Slot p is now wholly before the exposure and slot p + 1 wholly inside it: no partial slot.
    assert abs(b[p]) < 0.03 and abs(b[p + 1] - 1) < 0.03


def test_camera_not_synchronised_no_trigger():
    rig = calibration_rig(1, camera_line=TriggerSource.LINE3)
    with RigSession.from_rig(rig) as session:
        sync = measure_sync(session, rig.simulated.truth.homography)
        pats, _ = band_patterns(rig.simulated.truth.homography, session.camera_size, session.projector_size, 16)
        frames = check_frames(session, pats, 5)
    assert sync.status == "no_trigger" and "not synchronised to the projector" in sync.message
    assert sync.phase_slots is None
    assert frames.status == "no_trigger"


def test_free_running_camera_drifts():
    rig = calibration_rig(1, effects={})
    h = rig.simulated.truth.homography
    # A free-running camera at 15 Hz (66667 us) against a 16 x 4166 us = 66656 us sequence.
    with RigSession.from_rig(rig, trigger=TriggerConfig(source=TriggerSource.FREE_RUN),
                             free_run_period_us=66667) as session:
        pats, _ = band_patterns(h, session.camera_size, session.projector_size, 16)
        check = check_frames(session, pats, 20)
    assert check.status == "drifting"
    assert check.drift_us_per_frame == pytest.approx(11, abs=0.5)
    assert "slips by one slot every 25 s" in check.message


def test_dropped_frames_show_as_gaps():
    rig = calibration_rig(1, effects={"dropped_frames": {"probability": 0.2}})
    h = rig.simulated.truth.homography
    with RigSession.from_rig(rig) as session:
        pats, _ = band_patterns(h, session.camera_size, session.projector_size, 16)
        check = check_frames(session, pats, 30)
    assert check.status == "dropped_frames" and check.gaps > 0
    assert f"{check.gaps} of" in check.message and check.drift_us_per_frame == pytest.approx(0, abs=1e-6)


def test_sync_profile_round_trip_and_refusals(calibrated, tmp_path):
    rig, res = calibrated[1]
    with RigSession.from_rig(rig) as session:
        sync = measure_sync(session, res.homography)
        ident = session.identity
    path = save_sync_profile(tmp_path / "sync.json", sync, ident)
    data = load_sync_profile(path, ident)
    assert data["format"] == "flexvox-sync-profile" and data["sync"]["phase_slots"] == sync.phase_slots
    other = type(ident)(ident.name, ident.camera, ident.projector, (240, 320), ident.projector_size)
    with pytest.raises(CalibrationMismatchError, match="camera resolution of 120x160, this rig's is 240x320"):
        load_sync_profile(path, other)
    failed = type(sync)(status="no_trigger", message="x", K=16, period_us=4166)
    with pytest.raises(CalibrationError, match=r"refusing to save a failed sync measurement \(no_trigger\)"):
        save_sync_profile(tmp_path / "bad.json", failed, ident)
    with pytest.raises(CalibrationError, match="`K` must be a whole number 2..128; got 1"):
        measure_sync(None, res.homography, K=1)
