"""`flexvox devices`, driven through a parser built from the module's own register()."""

import json
from types import SimpleNamespace

import pytest

from flexvox_app.cli import devices
from flexvox_app.cli.errors import OneLineParser


def parse(*argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    devices.register(sub)
    return parser.parse_args(["devices", *argv])


def no_backend(**kwargs):
    import usb.core

    raise usb.core.NoBackendError("No backend available")


NO_HARDWARE = {"list_usb": no_backend, "comports": lambda: [], "environ": {}}


def test_register_sets_run(capsys):
    args = parse("--json")
    assert args.func is devices.run and args.json is True


def test_no_hardware_exits_0_and_says_why(capsys):
    code = devices.run(parse(), probes=NO_HARDWARE)
    out = capsys.readouterr().out
    assert code == 0
    assert "pyusb found no USB backend: install libusb-1.0" in out
    assert "no serial ports found" in out
    assert "GENICAM_GENTL64_PATH is not set" in out
    assert "simulated projector" in out
    assert "no rig hardware found on this machine; the simulated rig is available" in out


def test_json_lists_what_is_found(capsys, tmp_path):
    (tmp_path / "viky.cti").write_bytes(b"")
    (tmp_path / "readme.txt").write_text("x")

    class Dev:
        bus, address = 3, 9

    port = SimpleNamespace(device="/dev/ttyACM0", description="Arduino Uno", vid=0x2341, pid=0x0043)
    probes = {"list_usb": lambda **kw: [Dev()], "comports": lambda: [port],
              "environ": {"GENICAM_GENTL64_PATH": str(tmp_path)}, "open_projector": _busy_projector}
    code = devices.run(parse("--json"), probes=probes)
    payload = json.loads(capsys.readouterr().out)
    assert code == 0 and payload["hardware_found"] is True
    assert payload["projectors"]["devices"] == [{"bus": 3, "address": 9, "vid_pid": "0451:6401",
                                                 "settings": {"error": "the projector is busy (TI's GUI?)"}}]
    assert payload["serial_ports"]["devices"][0] == {"port": "/dev/ttyACM0", "description": "Arduino Uno",
                                                     "vid_pid": "2341:0043"}
    assert payload["gentl_producers"]["devices"] == [{"producer": str(tmp_path / "viky.cti")}]
    assert payload["simulated"]["available"] is True


def test_gentl_path_without_producers_says_so(capsys, tmp_path):
    probes = dict(NO_HARDWARE, environ={"GENICAM_GENTL64_PATH": str(tmp_path)})
    devices.run(parse("--json"), probes=probes)
    payload = json.loads(capsys.readouterr().out)
    assert payload["gentl_producers"]["reason"] == f"no .cti files in GENICAM_GENTL64_PATH ({tmp_path})"
    assert payload["hardware_found"] is False


def test_runs_on_this_machine_for_real(capsys):
    # Whatever this machine has, the command answers and exits 0.
    assert devices.run(parse("--json")) == 0
    payload = json.loads(capsys.readouterr().out)
    assert set(payload) >= {"projectors", "serial_ports", "gentl_producers", "simulated", "hardware_found"}


def test_unknown_option_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        parse("--bogus")
    assert exc.value.code == 2 and "unrecognized arguments: --bogus" in capsys.readouterr().err


def test_builtin_uart_is_listed_but_is_not_rig_hardware(capsys):
    uart = SimpleNamespace(device="/dev/ttyS0", description="n/a", vid=None, pid=None)
    devices.run(parse("--json"), probes=dict(NO_HARDWARE, comports=lambda: [uart]))
    payload = json.loads(capsys.readouterr().out)
    assert payload["serial_ports"]["devices"] == [{"port": "/dev/ttyS0", "description": "n/a", "vid_pid": None}]
    assert payload["hardware_found"] is False


def test_simulated_rig_lists_the_camera_and_the_genicam_simulated_producer(capsys, tmp_path):
    viky = tmp_path / "viky.cti"
    devices.run(parse(), probes=dict(NO_HARDWARE, sim_producer=lambda: viky))
    out = capsys.readouterr().out
    assert "name simulated camera" in out
    assert f"name simulated GenICam camera (genicam wheel), producer {viky}" in out
    assert "pick a rig with --rig mock (the default) or --rig FILE.toml" in out
    devices.run(parse("--json"), probes=dict(NO_HARDWARE, sim_producer=lambda: None))
    payload = json.loads(capsys.readouterr().out)
    assert [d["name"] for d in payload["simulated"]["devices"]] == [
        "simulated projector", "simulated camera", "simulated sync box"]
    assert payload["hardware_found"] is False  # a simulated producer is not rig hardware


def _busy_projector():
    from rig_drivers.errors import DeviceBusyError

    class Busy:
        def __enter__(self):
            raise DeviceBusyError("the projector is busy (TI's GUI?)")

        def __exit__(self, *exc):
            return False

    return Busy()


def test_a_found_lightcrafter_shows_its_leds_source_power_and_errors(capsys):
    from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport

    class Dev:
        bus, address = 1, 4

    fake = FakeDLPC350Transport()
    fake.led_currents = bytes([104, 135, 130])
    probes = dict(NO_HARDWARE, list_usb=lambda **kw: [Dev()], open_projector=lambda: DLPC350(fake))
    assert devices.run(parse(), probes=probes) == 0
    out = capsys.readouterr().out
    assert "  - bus 1, address 4, vid_pid 0451:6401\n    firmware 3.0.0, normal, input parallel (24 bit)" in out
    assert "LED current (PWM 0..255): red 104, green 135, blue 130; LEDs driven by the pattern sequence" in out
    assert "    errors: none" in out
