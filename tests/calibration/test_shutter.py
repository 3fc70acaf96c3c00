"""Shutter masks through the calibrated homography, verified on the simulated rig."""

import numpy as np
import pytest

from flexvox_calibration.errors import CalibrationError
from flexvox_calibration.homography import calibrate_homography
from flexvox_calibration.session import RigSession
from flexvox_calibration.shutter import make_shutter_patterns, verify_shutter
from flexvox_core.codes import code_from_order
from flexvox_core.design import design_code
from flexvox_core.forward import tiled_order
from rig_drivers.dlpc350.bitplanes import unpack_bitplanes
from rig_drivers.simulated_target import coarse_homography
from tests.rig_drivers.mock_rigs import calibration_rig

from .conftest import SEEDS

CODE = design_code((4, 4)).code


@pytest.mark.parametrize("seed", SEEDS)
def test_slot_accuracy_target_on_the_simulated_rig(calibrated, seed):
    rig, res = calibrated[seed]
    with RigSession.from_rig(rig) as session:
        shutter = make_shutter_patterns(CODE, res.homography, session.camera_size, session.projector_size)
        ver = verify_shutter(session, shutter)
    assert ver.status == "ok", ver.message
    assert ver.accuracy >= 0.999 and ver.decodable_fraction > 0.99
    assert ver.wrong.sum() <= 0.001 * ver.decodable.sum()
    assert shutter.addressable == 1.0 and shutter.notes == []


def test_patterns_follow_the_homography_and_the_phase():
    order = np.arange(4).reshape(2, 2)
    code = code_from_order(order)
    h = np.array([[0.5, 0, 0], [0, 0.5, 0], [0, 0, 1]])  # projector pixel (x, y) -> camera (x/2, y/2)
    sp = make_shutter_patterns(code, h, (6, 8), (12, 16))
    slot = np.argmax(sp.patterns, axis=0)
    ys, xs = np.mgrid[0:12, 0:16]
    cy, cx = np.rint(ys / 2).astype(int), np.rint(xs / 2).astype(int)
    inside = (cy < 6) & (cx < 8)  # mirrors whose nearest camera pixel is off the sensor stay dark
    cam_slot = tiled_order(code, 6, 8)[cy.clip(0, 5), cx.clip(0, 7)]
    np.testing.assert_array_equal(slot[inside], cam_slot[inside])
    np.testing.assert_array_equal(sp.patterns.sum(axis=0), inside)  # one slot per mirror (identity code)
    np.testing.assert_array_equal(unpack_bitplanes(sp.packed, 4), sp.patterns)
    rolled = make_shutter_patterns(code, h, (6, 8), (12, 16), phase_slots=3)
    np.testing.assert_array_equal(rolled.patterns, np.roll(sp.patterns, 3, axis=0))
    with pytest.raises(CalibrationError, match=r"`phase_slots` must be a whole number 0..3; got 4"):
        make_shutter_patterns(code, h, (6, 8), (12, 16), phase_slots=4)
    with pytest.raises(CalibrationError, match="`code`:"):
        make_shutter_patterns(np.zeros((2, 2)), h, (6, 8), (12, 16))


def test_a_projector_coarser_than_the_camera_is_reported_and_fails_verification():
    # The simulator's default homography: projector pixels 1.05-1.10 camera pixels wide.
    h = coarse_homography((120, 160), (120, 160), 1)
    rig = calibration_rig(1, projector_size=(120, 160), homography=h, effects={})
    with RigSession.from_rig(rig) as session:
        res = calibrate_homography(session)
        shutter = make_shutter_patterns(CODE, res.homography, session.camera_size, session.projector_size)
        ver = verify_shutter(session, shutter)
    assert 0.75 < shutter.addressable < 0.95
    assert "hold no projector pixel centre" in shutter.notes[0]
    assert ver.status == "inaccurate" and ver.accuracy < 0.999
    assert "see another slot" in ver.message and shutter.notes[0] in ver.warnings


def test_defocus_shows_as_crosstalk_warning():
    rig = calibration_rig(2, effects={"pattern_blur": {"sigma": 0.6}})
    with RigSession.from_rig(rig) as session:
        shutter = make_shutter_patterns(CODE, rig.simulated.truth.homography, session.camera_size,
                                        session.projector_size)
        ver = verify_shutter(session, shutter)
    assert ver.crosstalk > 0.1
    assert any("defocused" in w for w in ver.warnings)


def test_the_whole_calibration_on_a_diamond_dmd_models_its_stagger():
    """On the simulated rig with a staggered-row DMD, calibrating with the layout keeps the shutter
    near a square DMD's (100 %, 0.2 % crosstalk there); ignoring it lets odd rows shutter the wrong slot."""
    from flexvox_calibration.pipeline import run_calibration
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    results = {}
    for model in ("diamond", "square"):
        rig = open_rig("mock", scene="static", camera_size=(120, 160), seed=0, subframes=16,
                       pixel_layout="diamond", clock=VirtualClock())
        session = RigSession.from_rig(rig)
        session.pixel_layout = model  # "square": what a rig profile without pixel_layout would do
        results[model] = run_calibration(rig, session, tile=(4, 4)).report["shutter"]
    modelled, ignored = results["diamond"], results["square"]
    assert modelled["accuracy"] >= 0.97 and modelled["crosstalk"] < 0.05
    assert ignored["accuracy"] < modelled["accuracy"] - 0.01 and ignored["crosstalk"] > 2 * modelled["crosstalk"]


def test_a_one_slot_code_verifies_without_a_neighbour_slot(calibrated):
    """K = 1 (a 1x1 tile; calibrate refuses it up front): every pixel sees its one slot, and none a neighbour's."""
    rig, res = calibrated[SEEDS[0]]
    with RigSession.from_rig(rig) as session:
        shutter = make_shutter_patterns(design_code((1, 1)).code, res.homography, session.camera_size,
                                        session.projector_size)
        ver = verify_shutter(session, shutter)
    assert ver.status == "ok" and ver.accuracy == 1.0 and ver.crosstalk == 0.0
