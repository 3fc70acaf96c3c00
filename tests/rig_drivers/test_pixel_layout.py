"""The diamond DMD's staggered rows, in the simulated rig and in the shutter patterns."""

import numpy as np
import pytest

from flexvox_calibration.shutter import make_shutter_patterns
from flexvox_core.design import design_code
from flexvox_core.forward import tiled_code
from rig_drivers.errors import SettingError
from rig_drivers.pixel_layout import mirror_at, mirror_centres
from rig_drivers.simulated_rig import SimulatedRig, warp_patterns


def test_mirror_centres_and_lookup_agree():
    c = mirror_centres((4, 3), "diamond")
    assert c[0, 0].tolist() == [0.0, 0.0] and c[1, 0].tolist() == [0.5, 1.0] and c[3, 2].tolist() == [2.5, 3.0]
    row, col, inside = mirror_at(c[..., 0], c[..., 1], (4, 3), "diamond")
    assert inside.all() and (row == np.arange(4)[:, None]).all() and (col == np.arange(3)[None]).all()
    row, col, inside = mirror_at(np.array([3.1, -0.6, 0.2]), np.array([1.0, 0.0, 7.0]), (4, 3), "diamond")
    assert inside.tolist() == [False, False, False]  # past the staggered row's end; left of row 0; below
    assert mirror_centres((2, 2))[1, 1].tolist() == [1.0, 1.0]  # square: no offset
    with pytest.raises(SettingError, match=r"`pixel_layout` must be one of square, diamond, diamond-even; got 'hex'"):
        mirror_centres((2, 2), "hex")


def test_the_warp_follows_the_stagger(rng):
    pats = rng.random((3, 10, 12)) < 0.5
    eye = np.eye(3)
    square = warp_patterns(pats, eye, (10, 12))
    assert np.array_equal(square, pats.astype(np.float32))  # the identity reproduces the patterns
    diamond = warp_patterns(pats, eye, (10, 12), layout="diamond")
    assert np.array_equal(diamond[:, 0::2], square[:, 0::2])  # even rows sit as on a square grid
    # odd rows: a camera pixel over mirror column c straddles columns c - 1 and c (half each)
    expected = 0.5 * (pats[:, 1::2, :].astype(np.float32) + np.pad(pats[:, 1::2, :-1], ((0, 0), (0, 0), (1, 0))))
    np.testing.assert_allclose(diamond[:, 1::2], expected, atol=1e-6)


def _shutter(model: str, rig: str, columns_per_camera_px: float = 0.667):
    """(slot accuracy, own-slot light) of a 4x4 code through the true homography, inside the frame.

    The projector's rows are at half its column pitch, as on the DLP4500; 0.667 camera pixels per
    projector column is a LightCrafter 4500 seen by a 640x480 camera.
    """
    code = design_code((4, 4)).code
    sx = columns_per_camera_px
    cam = (64, 96)
    proj = (int(cam[0] / sx * 2) + 8, int(cam[1] / sx) + 8)
    h = np.array([[sx, 0.0113, -3.13], [0.0041, sx / 2, -2.87], [0, 0, 1.0]])
    own = np.argmax(tiled_code(code, *cam), axis=0)
    light = warp_patterns(make_shutter_patterns(code, h, cam, proj, layout=model).patterns, h, cam, layout=rig)
    inner = np.zeros(cam, bool)
    inner[6:-6, 6:-6] = True
    total = light.sum(axis=0)
    lit = inner & (total > 0.5)
    own_light = np.take_along_axis(light, own[None], 0)[0] / np.maximum(total, 1e-9)
    return float((np.argmax(light, axis=0) == own)[lit].mean()), float(own_light[lit].mean())


def test_modelling_the_stagger_restores_slot_accuracy():
    square = _shutter("square", "square")
    ignored = _shutter("square", "diamond")
    modelled = _shutter("diamond", "diamond")
    assert square[0] == 1.0 and modelled[0] == 1.0
    assert ignored[0] < 0.99 and ignored[1] < square[1] - 0.05  # odd rows land half a mirror off
    assert modelled[1] == pytest.approx(square[1], abs=1e-3)  # as good as a square DMD


def test_a_simulated_rig_with_a_diamond_dmd():
    rig = SimulatedRig.create("static", camera_size=(24, 32), pixel_layout="diamond", seed=1)
    assert rig.projector.pixel_layout == "diamond"
    with pytest.raises(SettingError, match=r"`pixel_layout` must be one of square, diamond"):
        SimulatedRig.create("static", camera_size=(24, 32), pixel_layout="staggered")


def test_the_other_stagger_is_the_same_up_to_a_shift():
    even = mirror_centres((4, 3), "diamond-even")
    odd = mirror_centres((4, 3), "diamond")
    assert even[0, 0].tolist() == [0.5, 0.0] and even[1, 0].tolist() == [0.0, 1.0]
    shift = np.broadcast_to(np.where(np.arange(4)[:, None] % 2, -0.5, 0.5), (4, 3))
    np.testing.assert_allclose(even[..., 0] - odd[..., 0], shift)  # odd rows the other way, all shifted by ½


def test_a_calibration_made_in_another_layout_is_refused(tmp_path):
    from flexvox_calibration.errors import CalibrationMismatchError
    from flexvox_calibration.files import check_identity
    from flexvox_calibration.session import RigIdentity

    square = RigIdentity("lab rig", "cam", "LightCrafter", (480, 640), (1140, 912))
    diamond = RigIdentity("lab rig", "cam", "LightCrafter", (480, 640), (1140, 912), "diamond")
    with pytest.raises(CalibrationMismatchError, match=r"made with the projector's pixel layout 'square', this rig "
                                                       r"declares 'diamond'.*calibrate again"):
        check_identity({"rig": square.as_dict()}, diamond, tmp_path / "cal.json")
    check_identity({"rig": diamond.as_dict()}, diamond, tmp_path / "cal.json")
    old = {k: v for k, v in square.as_dict().items() if k != "pixel_layout"}  # files from before layouts: square
    check_identity({"rig": old}, square, tmp_path / "cal.json")
