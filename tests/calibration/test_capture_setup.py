"""The sync timing a calibration or sync profile hands to capture: taken as written, or refused."""

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
