"""``calibrate_rig``'s progress: the one rule of flexvox's long calls, one count over the steps with its total."""

import json
import re

import pytest

from flexvox_calibration import calibrate_rig
from flexvox_calibration.errors import CalibrationFileError
from flexvox_calibration.for_rig import step_count
from rig_drivers import open_rig
from rig_drivers.simulated_camera import VirtualClock


@pytest.fixture
def rig():
    rig = open_rig("mock", scene="balls", camera_size=(48, 64), seed=0, clock=VirtualClock())
    yield rig
    rig.close()


def test_calibrate_rig_reports_its_steps_with_their_total(rig):
    seen = []
    cal = calibrate_rig(rig, tile="4x4", progress=lambda done, total: seen.append((done, total)))
    assert step_count(rig) == 6 and cal.phase_slots is not None
    assert {t for _, t in seen} == {6} and seen[0] == (0, 6) and seen[-1] == (6, 6)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)  # never backwards
    assert {d for d, _ in seen} == set(range(7))


def test_calibrate_rig_refuses_a_progress_that_is_no_progress(rig):
    with pytest.raises(TypeError, match=r"`progress` must be True \(a bar\), False or None \(nothing\), or a "
                                        r"callable progress\(done, total\); got str 'bar'"):
        calibrate_rig(rig, progress="bar")


def test_calibrate_rig_refuses_an_existing_save_before_calibrating(rig, tmp_path):
    path = tmp_path / "cal.json"
    path.write_text("an earlier calibration\n")
    seen = []
    with pytest.raises(CalibrationFileError, match=rf"^{re.escape(str(path))} already exists; choose another path, "
                                                   r"or pass overwrite=True to replace it \(checked before "
                                                   r"calibrating, so no run is lost\)$"):
        calibrate_rig(rig, save=path, progress=lambda done, total: seen.append(done))
    assert seen == [] and path.read_text() == "an earlier calibration\n"  # no step ran, the file is as it was
    with pytest.raises(CalibrationFileError, match=r"does not exist"):
        calibrate_rig(rig, save=tmp_path / "missing" / "cal.json", progress=lambda done, total: seen.append(done))
    assert seen == []
    cal = calibrate_rig(rig, save=path, overwrite=True, progress=False)
    assert cal.sha256 and json.loads(path.read_text())["format"] == "flexvox-calibration"


def test_calibrate_rig_refuses_a_1x1_tile_before_calibrating(rig):
    from flexvox_calibration.errors import CalibrationError

    seen = []
    with pytest.raises(CalibrationError, match=r"^a 1x1 tile \(K = 1\) has nothing to shutter: .* calibrate with the "
                                               r"tile you capture with \(at least 2 slots, e\.g\. 4x4\)"):
        calibrate_rig(rig, tile="1x1", progress=lambda done, total: seen.append(done))
    assert seen == []
