"""Rig profiles: --rig mock or a TOML file naming the real devices."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from rig_drivers.dlpc350 import DLPC350
from rig_drivers.errors import DeviceNotFoundError, SettingError
from rig_drivers.genicam import GenICamCamera
from rig_drivers.interfaces import DeviceState, TriggerSource
from rig_drivers.profile import MOCK_SPEC, DeferredSerialPort, load_profile, open_rig, parse_profile, resolve_rig
from rig_drivers.simulated_camera import SimulatedCamera, VirtualClock
from rig_drivers.simulated_rig import SimulatedRig
from rig_drivers.syncbox import FakeSyncBoxSerial, SyncBox
from rig_drivers.uvc import UvcCamera

EXAMPLE = Path(__file__).resolve().parents[2] / "rig_drivers" / "examples" / "lab-rig.toml"

GOOD = {
    "projector": {"kind": "dlpc350"},
    "camera": {"kind": "genicam", "cti": "/opt/x.cti", "serial": "1"},
    "sync": {"kind": "projector-trigger"},
}


def with_(section, **table):
    return dict(GOOD, **{section: table})


def test_mock_is_the_default_and_builds_unopened_simulated_devices():
    assert resolve_rig() is MOCK_SPEC and resolve_rig("mock").simulated
    rig = open_rig(scene="static", camera_size=(16, 24), subframes=16, clock=VirtualClock())
    assert isinstance(rig.simulated, SimulatedRig) and isinstance(rig.camera, SimulatedCamera)
    assert all(d.state is DeviceState.CLOSED for d in (rig.projector, rig.camera, rig.sync))
    assert rig.trigger_line is TriggerSource.LINE0


def test_building_the_mock_rig_renders_no_scene_and_the_camera_s_open_does():
    rig = open_rig(scene="drummer", camera_size=(24, 32), subframes=32, clock=VirtualClock())
    scene = rig.truth.scene
    assert rig.camera.sensor_shape == (24, 32) and scene.shape == (32, 24, 32)
    assert not scene.rendered  # open_rig built the devices only
    rig.camera.open()
    assert scene.rendered and rig.camera.scene is scene
    assert rig.truth.video.shape == (32, 24, 32) and rig.truth.video.dtype == np.float32
    with pytest.raises(SettingError, match=r"unknown scene 'nope'; built-in scenes: fan"):
        SimulatedRig._video("nope", None, (24, 32), 32, 0)


def test_example_profile_builds_real_drivers_without_io(tmp_path):
    spec = load_profile(EXAMPLE)
    assert spec.name == "lab rig" and spec.camera.options["serial"] == "22334455"
    rig = open_rig(EXAMPLE)
    assert isinstance(rig.projector, DLPC350) and isinstance(rig.camera, GenICamCamera)
    assert rig.sync is None  # the LightCrafter's video port: TRIG_OUT_2 triggers the camera
    assert rig.camera.cti == Path("/opt/pylon/lib/gentlproducer/gtl/ProducerU3V.cti")
    copy = tmp_path / "rig.toml"
    shutil.copy(EXAMPLE, copy)
    assert load_profile(copy).name == "lab rig"
    # The example's commented sync-box variant builds a closed SyncBox, without I/O.
    text = EXAMPLE.read_text().replace('kind = "projector-trigger"\n', "")
    text = text.replace('# kind = "syncbox"', 'kind = "syncbox"').replace('# port = ', "port = ")
    boxed = tmp_path / "boxed.toml"
    boxed.write_text(text)
    rig = open_rig(boxed)
    assert isinstance(rig.sync, SyncBox) and rig.sync.state is DeviceState.CLOSED


def test_uvc_and_projector_trigger_and_relative_cti(tmp_path):
    path = tmp_path / "webcam.toml"
    path.write_text('[projector]\nkind = "dlpc350"\n[camera]\nkind = "uvc"\nindex = 1\n'
                    '[sync]\nkind = "projector-trigger"\n')
    rig = open_rig(path)
    assert isinstance(rig.camera, UvcCamera) and rig.camera.index == 1 and rig.sync is None
    assert rig.spec.name == "webcam"
    spec = parse_profile(with_("camera", kind="genicam", cti="p.cti", line="Line2"), source=tmp_path / "r.toml")
    assert spec.camera.options["cti"] == str(tmp_path / "p.cti") and spec.trigger_line is TriggerSource.LINE2


@pytest.mark.parametrize("data, message", [
    (with_("camera", kind="basler"), r"\[camera\]: unknown kind 'basler'; valid kinds: genicam, uvc"),
    (with_("sync", kind="arduino"), r"\[sync\]: unknown kind 'arduino'; valid kinds: syncbox, projector-trigger"),
    (with_("projector", kind="lcr6500"), r"\[projector\]: unknown kind 'lcr6500'; valid kinds: dlpc350"),
    (with_("camera", kind="genicam"), r"\[camera\] kind 'genicam': missing key\(s\) cti"),
    (with_("sync", kind="syncbox"), r"\[sync\] kind 'syncbox': missing key\(s\) port"),
    (with_("camera", cti="/x.cti"), r"\[camera\]: missing key `kind` \(one of genicam, uvc\)"),
    ({"projector": {"kind": "dlpc350"}, "camera": GOOD["camera"]}, r"missing \[sync\] table"),
    (with_("camera", kind="uvc", cti="/x.cti"), r"kind 'uvc': unknown key 'cti'; allowed: index, kind"),
    (with_("camera", kind="genicam", cti="/x", line="Line9"), r"line must be one of Line0, Line1, Line2, Line3"),
    (with_("camera", kind="uvc", index=-1), r"index must be a whole number 0..255; got -1"),
    (dict(GOOD, colour="red"), r"unknown key 'colour'; allowed: camera, name, projector, sync"),
])
def test_bad_profiles_are_explained(data, message):
    with pytest.raises(SettingError, match=message):
        parse_profile(data)


def test_missing_or_broken_files_are_explained(tmp_path):
    with pytest.raises(SettingError, match=r"no rig profile .*nope.toml: a rig is \"mock\" \(the simulated rig\) or "
                                          r"the path of a \.toml rig profile"):
        open_rig(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera\n")
    with pytest.raises(SettingError, match=r"bad.toml is not valid TOML"):
        load_profile(bad)
    with pytest.raises(SettingError, match=r"options scene apply to the simulated rig only"):
        open_rig(EXAMPLE, scene="static")


def test_deferred_serial_port_opens_on_first_use_with_typed_errors():
    opened = []

    def factory(name, baud, **kw):
        opened.append((name, baud))
        return FakeSyncBoxSerial()

    port = DeferredSerialPort("/dev/ttyACM7", serial_factory=factory)
    box = SyncBox(port)
    assert opened == []  # building does no I/O
    with box:
        assert "syncbox" in box.firmware_version()
    assert opened == [("/dev/ttyACM7", 115200)]

    def missing(name, baud, **kw):
        raise FileNotFoundError(2, "No such file or directory")

    with pytest.raises(DeviceNotFoundError, match=r"no serial port /dev/ttyACM9: is the sync box plugged in"):
        SyncBox(DeferredSerialPort("/dev/ttyACM9", serial_factory=missing)).open()


def test_led_settings_from_a_profile_reach_the_projector(tmp_path):
    from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
    from rig_drivers.profile import parse_profile

    spec = parse_profile({"projector": {"kind": "dlpc350", "led_current": [90, 140, 120], "led_enable": ["green"]},
                          "camera": {"kind": "uvc"}, "sync": {"kind": "projector-trigger"}})
    options = spec.projector.options
    assert options["led_current"] == (90, 140, 120) and options["led_enable"] == ("green",)
    fake = FakeDLPC350Transport()
    with DLPC350(fake, led_currents=options["led_current"], led_enable=options["led_enable"]) as lcr:
        lcr.enable()
        assert fake.led_currents == bytes([90, 140, 120]) and fake.led_enable == 0b010
    spec = parse_profile({"projector": {"kind": "dlpc350", "led_current": 200, "led_enable": "sequence"},
                          "camera": {"kind": "uvc"}, "sync": {"kind": "projector-trigger"}})
    assert spec.projector.options["led_current"] == (200, 200, 200)
    for bad, message in (({"led_current": 256}, r"led_current must be a whole number 0..255 .*; got 256"),
                         ({"led_current": [1, 2]}, r"led_current must be .*; got \[1, 2\]"),
                         ({"led_enable": "auto"}, r"led_enable must be \"sequence\" .*; got 'auto'"),
                         ({"led_enable": ["white"]}, r"led_enable must be .*; got \['white'\]")):
        with pytest.raises(SettingError, match=message):
            parse_profile({"projector": {"kind": "dlpc350", **bad}, "camera": {"kind": "uvc"},
                           "sync": {"kind": "projector-trigger"}})


def test_a_profile_declares_the_diamond_dmd():
    from rig_drivers.profile import parse_profile

    spec = parse_profile({"projector": {"kind": "dlpc350", "pixel_layout": "diamond"}, "camera": {"kind": "uvc"},
                          "sync": {"kind": "projector-trigger"}})
    assert spec.projector.options["pixel_layout"] == "diamond"
    with pytest.raises(SettingError, match=r"pixel_layout must be one of square, diamond, diamond-even .*; got 'hex'"):
        parse_profile({"projector": {"kind": "dlpc350", "pixel_layout": "hex"}, "camera": {"kind": "uvc"},
                       "sync": {"kind": "projector-trigger"}})
    from rig_drivers.dlpc350 import FakeDLPC350Transport

    assert DLPC350(FakeDLPC350Transport(), pixel_layout="diamond").pixel_layout == "diamond"
    assert DLPC350(FakeDLPC350Transport()).pixel_layout == "square"  # only when the profile declares it
