"""The rig service (Qt-free) reads the rig through its protocol: its name, its devices, its optional capabilities."""

import pytest

from flexvox_app.capture.rig_setup import StopError, stop_rig
from flexvox_app.gui.models.holder import Holder
from flexvox_app.gui.models.live_source import stop_live
from flexvox_app.gui.models.rig_service import RigService
from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from rig_drivers.errors import DeviceError
from rig_drivers.interfaces import DeviceState, DisplayInput, LedControl
from rig_drivers.profile import MOCK_SPEC, ProfileRig
from rig_drivers.simulated import SimulatedSyncController
from rig_drivers.simulated_camera import VirtualClock
from rig_drivers.simulated_rig import SimulatedRig

from .conftest import small_rig


def test_the_name_of_either_kind_of_rig():
    sim = SimulatedRig.create("static", camera_size=(16, 24), subframes=16, seed=3, clock=VirtualClock())
    assert RigService(sim).name == "simulated rig (seed 3)"
    assert RigService(small_rig()).name == "simulated rig (mock, seed 0)"


def test_devices_by_role_and_a_role_that_is_none():
    rig = small_rig()
    service = RigService(rig)
    assert service.device("projector") is rig.projector and service.device("camera") is rig.camera
    assert service.device("sync") is rig.sync
    no_sync = RigService(ProfileRig(rig.projector, rig.camera, None, MOCK_SPEC))
    assert no_sync.device("sync") is None and not no_sync.status("sync").present
    with pytest.raises(ValueError, match=r"`role` must be one of projector, camera, sync; got 'lamp'"):
        service.device("lamp")


def test_who_holds_the_devices_is_the_holder_in_words_and_the_old_name_warns():
    service = RigService(small_rig())
    assert service.holder is Holder.IDLE and service.held_by is None
    assert service.connect("camera")
    heard = []
    service.subscribe(heard.append)
    service.begin_use("the calibration")
    assert service.holder is Holder.CALIBRATING and service.held_by == "the calibration"
    assert heard == ["projector", "camera", "sync"]  # the panel redraws each row as held
    with pytest.warns(DeprecationWarning, match=r"RigService\.in_use_by is deprecated and will be removed in the next "
                                                r"release: call RigService\.held_by$"):
        assert service.in_use_by == "the calibration"
    assert service.disconnect("camera")  # the calibration closes what it opened
    assert service.end_use("the calibration") == ["camera"]  # given back connected
    assert service.holder is Holder.IDLE and service.held_by is None
    assert service.rig.camera.state is DeviceState.ENABLED


@pytest.mark.parametrize("first_done", ["the live numbers", "the calibration"])
def test_overlapping_holders_give_the_devices_back_connected_whichever_ends_first(first_done):
    """The operator's connected devices are remembered by the first holder; when it ends while another still
    holds them, the other gives them back (they were lost: neither connected the camera again)."""
    service = RigService(small_rig())
    assert service.connect("camera")
    service.begin_use("the live numbers")
    service.begin_use("the calibration")
    assert service.disconnect("camera")
    other = "the calibration" if first_done == "the live numbers" else "the live numbers"
    assert service.end_use(first_done) == []  # still held: nothing is connected yet
    assert service.rig.camera.state is not DeviceState.ENABLED
    assert service.end_use(other) == ["camera"]
    assert service.rig.camera.state is DeviceState.ENABLED and service.holder is Holder.IDLE


def test_leds_and_the_video_input_are_declared_capabilities_none_where_absent():
    sim = small_rig()
    assert sim.projector.led_control is None and sim.projector.display_input is None
    service = RigService(sim)
    assert not service.has_led_control and service.led_currents() is None
    assert not service.set_led_currents(1, 2, 3)
    fake = FakeDLPC350Transport()
    lcr = DLPC350(fake, led_currents=(90, 140, 120), poll_interval_s=0)
    assert lcr.led_control is lcr and lcr.display_input is lcr  # the LightCrafter 4500 has both
    leds: LedControl = lcr.led_control
    video_input: DisplayInput = lcr.display_input
    assert leds.configured_led_currents == (90, 140, 120) and video_input.display is None
    service = RigService(ProfileRig(lcr, sim.camera, None, MOCK_SPEC))
    assert service.has_led_control and service.led_currents() == (90, 140, 120)  # closed: the profile's
    assert service.connect("projector")
    assert service.led_currents() == tuple(fake.led_currents)  # open: read back
    assert service.set_led_currents(30, 220, 128) and fake.led_currents == bytes([30, 220, 128])
    shown = []
    video_input.display = shown.append
    assert lcr.display == shown.append  # set through the declared video input
    service.close()


class StuckSync(SimulatedSyncController):
    """A sync box that cannot stop, with an error text that names the camera (its frame output)."""

    def _do_stop(self):
        raise DeviceError("the camera trigger output is stuck high")


def test_a_device_that_cannot_stop_is_named_by_its_role_not_by_the_words_of_its_error():
    sim = small_rig()
    sync = StuckSync()
    rig = ProfileRig(sim.projector, sim.camera, sync, MOCK_SPEC)
    service = RigService(rig)
    assert service.connect("sync")
    sync._running = True  # running, as after a recording's start
    errors = stop_rig(rig)
    assert errors == [StopError("sync", "could not stop the sync box: the camera trigger output is stuck high")]
    sync._running = True
    stop_live(service)
    assert service.status("sync").last_error == "could not stop the sync box: the camera trigger output is stuck high"
    assert service.status("camera").last_error == "" and rig.sync.state is DeviceState.ENABLED
