"""Live alignment numbers and the parallax test (depth emulated by plane homographies)."""

import pytest

from flexvox_calibration import geometry
from flexvox_calibration.colocation import capture_view, live_alignment, measure_alignment, parallax_test
from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.session import RigSession
from tests.rig_drivers.mock_rigs import calibration_rig


def _views(baseline, seed=0):
    views = []
    for depth in (1.0, 2.0):
        with RigSession.from_rig(calibration_rig(seed, baseline=baseline, depth=depth)) as session:
            views.append(capture_view(session))
    return views, session.projector_size


def test_alignment_numbers_match_the_truth():
    rig = calibration_rig(2)
    with RigSession.from_rig(rig) as session:
        a = measure_alignment(session)
        again = list(live_alignment(session, 2))
    truth = geometry.describe(rig.simulated.truth.homography, (120, 160), (240, 320))
    assert a.status == "ok", a.message
    assert a.offset_px == pytest.approx(truth.offset_px, abs=0.3)
    assert a.rotation_deg == pytest.approx(truth.rotation_deg, abs=0.1)
    assert a.scale == pytest.approx(truth.scale, rel=0.01) and a.lit_fraction > 0.99
    assert "offset (" in a.message and len(again) == 2 and all(r.success for r in again)


def test_co_located_rig_passes_the_parallax_test():
    views, psize = _views((0.0, 0.0, 0.0))
    res = parallax_test(views, psize)
    assert res.status == "ok" and "co-located" in res.message
    assert max(res.disagreement_px) < 0.1 and res.advice == ""
    assert len(res.residual_maps) == 2 and res.residual_maps[0].shape == (120, 160)


@pytest.mark.parametrize("baseline, words", [
    ((0.01, 0.0, 0.0), "image moves left on near targets"),
    ((0.0, -0.01, 0.0), "image moves down on near targets"),
    ((0.0, 0.0, 0.1), "along its optical axis away from the beam splitter"),
])
def test_displaced_projector_fails_and_says_which_way(baseline, words):
    views, psize = _views(baseline)
    res = parallax_test(views, psize)
    assert res.status == "not_co_located" and not res.success
    assert res.message.startswith("NOT co-located") and words in res.message
    assert max(res.disagreement_px) > 0.5


def test_parallax_needs_two_views():
    with pytest.raises(CalibrationError, match="`views` must be at least two Correspondences"):
        parallax_test([], (4, 4))
