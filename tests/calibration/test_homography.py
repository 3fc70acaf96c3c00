"""Homography calibration on the simulated rig: targets, hard cases, files."""

import datetime as dt
import json

import numpy as np
import pytest

from flexvox_calibration import geometry
from flexvox_calibration.errors import CalibrationError, CalibrationFileError, CalibrationMismatchError
from flexvox_calibration.files import load_calibration, save_calibration
from flexvox_calibration.homography import calibrate_homography
from flexvox_calibration.session import RigIdentity, RigSession
from rig_drivers.interfaces import TriggerSource
from rig_drivers.simulated_target import fine_homography
from tests.rig_drivers.mock_rigs import calibration_rig

from .conftest import SEEDS


@pytest.mark.parametrize("seed", SEEDS)
def test_targets_with_noise_defocus_and_ambient(calibrated, seed):
    rig, res = calibrated[seed]
    assert set(rig.simulated.effects_in_view) == {"photon_noise", "read_noise", "pattern_blur", "ambient"}
    assert res.status == "ok", res.message
    err = geometry.homography_error_px(res.homography, rig.simulated.truth.homography, (120, 160))
    assert err <= 0.1  # target 0.25 px, aim 0.1
    assert res.rms_px < 0.3 and res.coverage > 0.99 and res.inliers > 0.99 * 120 * 160
    assert np.nanmax(res.residual_map) <= 1.0 and res.residual_map.shape == (120, 160)
    assert not res.geometry.mirrored and not res.warnings


def _run(**kw):
    rig = calibration_rig(kw.pop("seed", 3), **kw)
    with RigSession.from_rig(rig) as session:
        return rig, session, calibrate_homography(session)


def test_a_scene_too_dark_to_decode_is_reported_not_fitted():
    _, _, res = _run(albedo=(0.005, 0.01))
    assert res.status == "too_dark" and not res.success and res.homography is None
    assert "the scene is too dark to decode" in res.message and "brighter" in res.message


def test_a_projector_that_shows_nothing_is_reported():
    away = np.array([[1.0, 0, 5000], [0, 1, 5000], [0, 0, 1]])  # its image misses the camera entirely
    _, _, res = _run(homography=away)
    assert res.status == "no_projector_light" and res.homography is None
    assert "the projector's light does not reach the camera" in res.message


def test_a_camera_not_synchronised_gives_no_frames_status():
    _, _, res = _run(camera_line=TriggerSource.LINE2)  # TRIG_OUT_2 wired to another line
    assert res.status == "no_frames"
    assert "not synchronised to the projector" in res.message and "no frame within" in res.message


def test_half_the_image_in_shadow_is_partial_and_names_the_half():
    rig, _, res = _run(shadow="right")
    assert res.status == "partial" and not res.success
    assert "the right half of the frame is almost undecoded: in shadow?" in res.message
    assert 0.4 < res.coverage < 0.55
    # The fit itself is still good where it was decoded; it is flagged, not hidden.
    assert np.isnan(res.residual_map[:, 100:]).all()


def test_a_mirrored_rig_calibrates_and_says_so():
    h0 = fine_homography((120, 160), (240, 320), 3)
    flip = np.array([[-1.0, 0, 319], [0, 1, 0], [0, 0, 1]])  # projector mirrored left-right
    rig, _, res = _run(homography=h0 @ flip)
    assert res.status == "ok", res.message
    assert res.geometry.mirrored and any("mirrored (left-right)" in w for w in res.warnings)
    assert geometry.homography_error_px(res.homography, rig.simulated.truth.homography, (120, 160)) < 0.1


def test_a_nearly_singular_homography_is_degenerate():
    h0 = fine_homography((120, 160), (240, 320), 3)
    squash = np.diag([1.0, 0.12, 1.0]) @ h0  # the projector's rows squashed into a strip
    squash[1, 2] += 50
    _, _, res = _run(homography=squash)
    assert res.status == "degenerate" and not res.success
    assert "nearly singular" in res.message and ":1 in the camera" in res.message


def test_describe_flags_folded_and_singular_matrices():
    # camera -> projector has its horizon at camera x = 50: inside the frame
    folded = np.linalg.inv(np.array([[1.0, 0, 0], [0, 1, 0], [-0.02, 0, 1]]))
    rep = geometry.describe(folded, (120, 160), (120, 160))
    assert rep.folded and "folds the camera frame" in rep.problems[0]
    flat = geometry.describe(np.diag([1.0, 0.01, 1.0]), (120, 160), (120, 160))
    assert any("nearly singular" in p for p in flat.problems)
    good = geometry.describe(np.eye(3), (120, 160), (120, 160))
    assert good.problems == [] and good.scale == pytest.approx(1) and good.offset_px == (0.0, 0.0)
    with pytest.raises(CalibrationError, match=r"`homography` must be a finite 3x3 matrix; got shape \(2, 2\)"):
        geometry.check_matrix(np.eye(2))


def test_save_and_load_refuse_another_rig_or_resolution(calibrated, tmp_path):
    rig, res = calibrated[0]
    ident = RigIdentity("simulated rig (mock)", "simulated camera", "simulated projector", (120, 160), (240, 320))
    when = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.UTC)
    path = save_calibration(tmp_path / "cal.json", res, ident, now=when)
    data = load_calibration(path, ident)
    np.testing.assert_allclose(data["H"], res.homography)
    assert data["version"] == 1 and data["created"] == "2026-01-02T03:04:05+00:00"
    assert data["rig"]["camera_size"] == [120, 160] and data["quality"]["status"] == "ok"
    other_res = RigIdentity("simulated rig (mock)", "simulated camera", "simulated projector", (480, 640), (240, 320))
    with pytest.raises(CalibrationMismatchError, match=r"made for a camera resolution of 120x160, this rig's is "
                                                       r"480x640: calibrate this rig"):
        load_calibration(path, other_res)
    other_rig = RigIdentity("lab rig", "simulated camera", "simulated projector", (120, 160), (240, 320))
    with pytest.raises(CalibrationMismatchError, match=r"made for rig 'simulated rig \(mock\)', not 'lab rig'"):
        load_calibration(path, other_rig)
    newer = json.loads(path.read_text())
    newer["version"] = 99
    (tmp_path / "new.json").write_text(json.dumps(newer))
    with pytest.raises(CalibrationFileError, match="version 99 is newer than this flexvox reads"):
        load_calibration(tmp_path / "new.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(CalibrationFileError, match="not valid JSON"):
        load_calibration(tmp_path / "bad.json")
    with pytest.raises(CalibrationFileError, match="no such file"):
        load_calibration(tmp_path / "missing.json")


def test_a_failed_calibration_is_never_saved(tmp_path):
    _, session, res = _run(shadow="right")
    with pytest.raises(CalibrationError, match=r"refusing to save a failed calibration \(partial\)"):
        save_calibration(tmp_path / "cal.json", res, session.identity)
    assert not (tmp_path / "cal.json").exists()
    path = save_calibration(tmp_path / "cal.json", res, session.identity, allow_partial=True)
    assert load_calibration(path)["quality"]["status"] == "partial"


def test_session_counts_only_frames_taken_after_the_pattern_change():
    rig = calibration_rig(4, effects={})
    with RigSession.from_rig(rig, settle_frames=0) as session:
        white = session.capture(np.ones(session.projector_size, bool))
        first = session.frames_read
        black = session.capture(np.zeros(session.projector_size, bool))
        assert session.frames_read == first + 1
        assert white.mean() > 0.5 and black.max() == 0.0  # no stale white frame counted as black
    with pytest.raises(CalibrationError, match=r"`patterns` must be \(K, 240, 320\) projector pixels"):
        with RigSession.from_rig(calibration_rig(4, effects={})) as session:
            session.show(np.zeros((2, 10, 10), bool))


def test_a_diamond_dmd_is_fitted_in_mirror_coordinates():
    """The decoded columns of a staggered-row DMD average its rows' offsets: fitted as square, the
    homography is 0.15 camera px off (and its RMS does not show it); in mirror coordinates it is exact."""
    from flexvox_calibration.homography import fit_homography
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    rig = open_rig("mock", scene="static", camera_size=(120, 160), seed=3, subframes=16, pixel_layout="diamond",
                   clock=VirtualClock())
    rig.simulated.show_target()
    with RigSession.from_rig(rig) as session:
        assert session.pixel_layout == "diamond"
        res = calibrate_homography(session)
    truth = rig.simulated.truth.homography
    assert res.status == "ok" and geometry.homography_error_px(res.homography, truth, (120, 160)) < 0.02
    square = fit_homography(res.details["correspondences"], session.projector_size, layout="square")
    assert geometry.homography_error_px(square.homography, truth, (120, 160)) > 0.1
    assert abs(square.rms_px - res.rms_px) < 0.01  # the residual cannot tell the two apart
