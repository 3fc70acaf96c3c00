"""What a simulated rig is built from: SimulatedRigSpec's defaults, its checks, and the rig it builds."""

import dataclasses

import numpy as np
import pytest

from rig_drivers.errors import SettingError
from rig_drivers.interfaces import TriggerSource
from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock
from rig_drivers.simulated_rig import SimulatedRig
from rig_drivers.simulated_rig_spec import SimulatedRigSpec


def test_the_defaults_are_the_rig_of_mock():
    spec = SimulatedRigSpec()
    assert (spec.scene, spec.camera_size, spec.projector_size, spec.homography, spec.seed, spec.effects) == (
        "drummer", None, None, None, None, None)
    assert (spec.subframes, spec.phase_slots, spec.delay_us, spec.ideal, spec.baseline) == (
        None, None, None, False, (0.0, 0.0, 0.0))
    assert (spec.target_effects, spec.wiring, spec.camera_line, spec.electrons_per_unit, spec.clock) == (
        None, "projector", TriggerSource.LINE0, None, None)
    assert (spec.buffer_frames, spec.pixel_layout) == (16, "square")
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.seed = 3


def test_values_are_checked_and_normalised_when_the_spec_is_made():
    spec = SimulatedRigSpec("balls", camera_size=[16, 24], baseline=[0, 0.1, 0], homography=2 * np.eye(3), seed=4)
    assert spec.camera_size == (16, 24) and spec.baseline == (0.0, 0.1, 0.0)
    np.testing.assert_array_equal(spec.homography, np.eye(3))  # h[2, 2] = 1
    assert spec.seed == 4


@pytest.mark.parametrize(("fields", "message"), [
    ({"scene": "nope"}, r"unknown scene 'nope'; built-in scenes: fan, balls"),
    ({"wiring": "usb"}, r"`wiring` must be one of projector, syncbox; got 'usb'"),
    ({"camera_line": TriggerSource.SOFTWARE}, r"`camera_line` must be a TriggerSource line \(Line0..Line3\)"),
    ({"camera_size": (4, 24)}, r"`camera_size\[0\]` must be"),
    ({"camera_size": 16}, r"`camera_size` must be \(H, W\); got 16"),
    ({"projector_size": (16, 9000)}, r"`projector_size\[1\]` must be"),
    ({"homography": np.zeros((3, 3))}, r"`homography` must be invertible"),
    ({"seed": -1}, r"`seed` must be"),
    ({"subframes": 0}, r"`subframes` must be"),
    ({"phase_slots": 2000}, r"`phase_slots` must be"),
    ({"delay_us": -5}, r"`delay_us` must be"),
    ({"baseline": (0, 0)}, r"`baseline` must be three finite numbers \(bx, by, bz\); got \(0, 0\)"),
    ({"electrons_per_unit": 0}, r"`electrons_per_unit` must be a number > 0; got 0"),
    ({"buffer_frames": 0}, r"`buffer_frames` must be"),
    ({"pixel_layout": "hex"}, r"`pixel_layout` must be one of square, diamond, diamond-even; got 'hex'"),
    ({"effects": ["noise"]}, r"`effects` must be Effect objects or a \{name: params\} table; got 'noise'"),
    ({"ideal": "yes"}, r"`ideal` must be True or False; got 'yes'"),
])
def test_a_bad_value_is_refused_with_its_name_and_rule(fields, message):
    with pytest.raises(SettingError, match=message):
        SimulatedRigSpec(**fields)
    with pytest.raises(SettingError, match=message):  # the keyword forms check the same
        SimulatedRig.create(**fields)


def test_build_create_and_open_rig_build_the_same_rig():
    fields = {"camera_size": (16, 24), "subframes": 8, "seed": 5}
    spec = SimulatedRigSpec("balls", **fields, clock=VirtualClock())
    built = SimulatedRig.build(spec)
    created = SimulatedRig.create("balls", **fields, clock=VirtualClock())
    profile = open_rig("mock", scene="balls", **fields, clock=VirtualClock())
    assert built.spec is spec and built.name == "simulated rig (seed 5)"
    for rig in (created, profile.simulated):
        np.testing.assert_array_equal(rig.truth.homography, built.truth.homography)
        assert (rig.truth.phase_slots, rig.truth.delay_us) == (built.truth.phase_slots, built.truth.delay_us)
        np.testing.assert_array_equal(rig.truth.video, built.truth.video)
    assert built.projector_size == (32, 48)  # twice the camera's, as per-pixel shuttering needs
    with pytest.raises(SettingError, match=r"`spec` must be a SimulatedRigSpec \(rig_drivers.simulated_rig_spec\); "
                                           r"got dict"):
        SimulatedRig.build(fields)
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'camera'"):
        SimulatedRig.create("balls", camera=(16, 24))
