"""The sync timing a calibration or sync profile hands to capture: taken as written, or refused."""

import re

import pytest

from flexvox_calibration.capture_setup import CalibrationRefused, SyncTiming

GOOD = {"status": "ok", "K": 16, "period_us": 4000, "phase_slots": 4, "delay_us": 30.0,
        "recommended_camera_delay_us": 220.0, "effective_phase_slots": 5}


def test_a_sound_summary_gives_its_timing():
    t = SyncTiming.from_summary(GOOD)
    assert (t.phase_slots, t.trigger_delay_us, t.K, t.period_us, t.raw_phase_slots) == (5, 220.0, 16, 4000, 4)
    older = {k: v for k, v in GOOD.items() if k != "effective_phase_slots"}  # derived as the sync step does
    assert SyncTiming.from_summary(older).phase_slots in range(16)
    assert SyncTiming.from_summary({**GOOD, "status": "failed"}) is None


@pytest.mark.parametrize(("edit", "message"), [
    # hand edits that int() used to round into range (a phase of 2.5 recorded at phase 2: 0 % of slots right)
    ({"effective_phase_slots": 2.5}, r"`phase_slots` must be a whole number 0..15; got 2.5"),
    ({"effective_phase_slots": 7.9}, r"`phase_slots` must be a whole number 0..15; got 7.9"),
    ({"effective_phase_slots": True}, r"`phase_slots` must be a whole number 0..15; got True"),
    ({"phase_slots": "6"}, r"`raw_phase_slots` must be a whole number 0..15; got '6'"),
    ({"K": "16"}, r"`K` must be a whole number >= 1; got '16'"),
    ({"recommended_camera_delay_us": None}, r"incomplete: no `recommended_camera_delay_us` \(the phase and the "
                                            r"camera trigger delay go together"),
    ({"recommended_camera_delay_us": "220"}, r"`trigger_delay_us` must be at least 0 and below the period"),
])
def test_a_hand_edited_summary_is_refused_not_rounded(edit, message):
    with pytest.raises(CalibrationRefused, match=message):
        SyncTiming.from_summary({**GOOD, **edit})


def _identity():
    from flexvox_calibration.session import RigIdentity

    return RigIdentity("lab rig", "cam", "proj", (48, 64), (96, 128))


def _write(path, edit=None, *, body=None):
    """A calibration file for :func:`_identity`'s rig, with ``edit(data)`` applied to its JSON."""
    import json

    from flexvox_calibration.files import CALIBRATION_FORMAT, CALIBRATION_VERSION, write_versioned

    body = body or {"homography": {"projector_to_camera": [[0.5, 0, 0], [0, 0.5, 0], [0, 0, 1]]},
                    "quality": {"status": "ok", "rms_px": 0.2, "residual": float("nan")},
                    "sync": {**GOOD, "residual_leakage": float("nan"), "slip_s": float("inf")}}
    write_versioned(path, CALIBRATION_FORMAT, CALIBRATION_VERSION, _identity(), body, overwrite=True)
    if edit is not None:
        data = json.loads(path.read_text())
        edit(data)
        path.write_text(json.dumps(data))
    return path


def test_a_calibration_file_is_strict_json_with_null_for_what_is_not_finite_and_loads_back(tmp_path):
    import json

    from flexvox_calibration.capture_setup import load_for_capture

    path = _write(tmp_path / "cal.json")

    def refuse(constant):
        raise ValueError(f"not strict JSON: {constant}")

    data = json.loads(path.read_text(), parse_constant=refuse)
    assert data["quality"]["residual"] is None and data["sync"]["residual_leakage"] is None
    assert data["sync"]["slip_s"] is None
    cal = load_for_capture(path, _identity())
    assert (cal.phase_slots, cal.trigger_delay_us, cal.rms_px) == (5, 220.0, 0.2)
    assert cal.rig == _identity().as_dict()
    nulled = _write(tmp_path / "null.json", lambda d: d["quality"].__setitem__("rms_px", None))
    assert load_for_capture(nulled, _identity()).rms_px is None  # a step that measured nothing


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d.__setitem__("quality", "ok"),
     r"q.json: `quality` must be an object \(the homography step's summary\) or null; got 'ok'$"),
    (lambda d: d.__setitem__("sync", "ok"),
     r"q.json: `sync`: the sync measurement must be an object \(the sync step's summary\) or null; got 'ok'$"),
    (lambda d: d["sync"].__setitem__("K", "16"), r"q.json: `sync`: the sync measurement is out of range: `K` must "),
    (lambda d: d["rig"].__setitem__("camera_size", None),
     r"q.json: `rig.camera_size` must be \[rows, columns\] in pixels, the camera resolution it was made for; got "
     r"None$"),
    (lambda d: d["rig"].__setitem__("camera_size", "48x64"),
     r"q.json: `rig.camera_size` must be \[rows, columns\] in pixels, the camera resolution it was made for; got "
     r"'48x64'$"),
    (lambda d: d["rig"].__setitem__("projector_size", [96.0, 128]),
     r"q.json: `rig.projector_size` must be \[rows, columns\] in pixels, the projector resolution it was made "
     r"for; got \[96.0, 128\]$"),
    (lambda d: d["quality"].__setitem__("rms_px", "small"),
     r"q.json: `quality.rms_px` must be a number \(the homography's RMS reprojection error in pixels\) or null; "
     r"got 'small'$"),
])
def test_a_hand_edited_calibration_file_is_refused_naming_the_file_and_the_field(tmp_path, edit, message):
    from flexvox_calibration.capture_setup import load_for_capture

    path = _write(tmp_path / "q.json", edit)
    with pytest.raises(CalibrationRefused, match=message):
        load_for_capture(path, _identity())


def test_a_sync_profile_alone_ties_the_calibration_to_its_rig_and_is_named_by_its_file(tmp_path):
    import dataclasses

    from flexvox_calibration.capture_setup import load_sync_for_capture
    from flexvox_calibration.files import write_versioned
    from flexvox_calibration.sync import SYNC_FORMAT, SYNC_VERSION

    path = tmp_path / "sync.json"
    write_versioned(path, SYNC_FORMAT, SYNC_VERSION, _identity(), {"sync": GOOD})
    cal = load_sync_for_capture(path, _identity())
    assert cal.rig == _identity().as_dict() and cal.phase_slots == 5
    other = dataclasses.replace(_identity(), camera_size=(40, 64))
    with pytest.raises(CalibrationRefused, match=rf"^{re.escape(str(path))} \(sha256 [0-9a-f]{{16}}\), made "
                                                 r".* was made for a camera resolution of 48x64, this rig's is 40x64"):
        cal.check_rig(other)
