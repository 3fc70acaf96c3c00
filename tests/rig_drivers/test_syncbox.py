"""The sync box line protocol, the serial driver's error paths and the fake firmware."""

import pytest
import serial

from rig_drivers.errors import (
    DeviceBusyError,
    DeviceNotFoundError,
    DevicePermissionError,
    DeviceTimeoutError,
    ProtocolError,
)
from rig_drivers.interfaces import SyncSettings
from rig_drivers.syncbox import FakeSyncBoxSerial, SyncBox
from rig_drivers.syncbox import protocol as sp
from rig_drivers.syncbox.driver import map_serial_error


def test_framing_and_checksum():
    assert sp.checksum("VERSION?") == 0x65
    assert sp.frame("VERSION?") == b"VERSION?*65\n"
    assert sp.unframe(b"OK COUNT 12*" + f"{sp.checksum('OK COUNT 12'):02X}".encode() + b"\r\n") == "OK COUNT 12"
    with pytest.raises(ProtocolError, match=r"checksum error in the sync box reply 'OK\*00': computed 04, received 00"):
        sp.unframe(b"OK*00\n")
    with pytest.raises(ProtocolError, match="malformed line 'OK' \\(expected '<body>\\*XX'\\)"):
        sp.unframe(b"OK\n")
    with pytest.raises(ValueError, match=r"`body` must not contain '\*' or a newline"):
        sp.frame("A*B")


def test_reply_parsing():
    assert sp.parse_reply("OK PERIOD 4166") == sp.Reply(True, ("PERIOD", "4166"))
    assert sp.parse_reply("ERR 3 BAD VALUE").code == 3
    with pytest.raises(ProtocolError, match="neither 'OK ...' nor 'ERR <code> ...'"):
        sp.parse_reply("HELLO")


@pytest.fixture
def port():
    return FakeSyncBoxSerial()


@pytest.fixture
def box(port):
    dev = SyncBox(port, timeout_s=0.05)
    dev.open()
    yield dev
    port.silent = False
    port.corrupt_replies = 0
    dev.close()


def test_session_lines_on_the_wire(port, box):
    box.configure(SyncSettings(period_us=4166, pulses_per_frame=16))
    box.enable()
    box.start()
    port.advance_us(66656)
    assert box.pulse_count() == 17 and box.elapsed_us() == 66656
    assert port.received == [
        "VERSION?*65", "SET PERIOD 4166*" + f"{sp.checksum('SET PERIOD 4166'):02X}",
        "SET PULSES 16*" + f"{sp.checksum('SET PULSES 16'):02X}", "START*" + f"{sp.checksum('START'):02X}",
        "COUNT?*" + f"{sp.checksum('COUNT?'):02X}", "TIME?*" + f"{sp.checksum('TIME?'):02X}",
    ]
    assert (port.period_us, port.pulses_per_frame, port.running) == (4166, 16, True)


def test_one_corrupt_reply_is_retried(port, box):
    port.corrupt_replies = 1
    assert box.firmware_version() == "flexvox-syncbox 1.0"
    assert port.received[-2:] == ["VERSION?*65", "VERSION?*65"]


def test_corrupt_replies_on_every_attempt_raise(port, box):
    port.corrupt_replies = 5
    with pytest.raises(ProtocolError, match=r"checksum error in the sync box reply .* \(after 2 attempts\)"):
        box.pulse_count()
    assert len([line for line in port.received if line.startswith("COUNT?")]) == 2  # bounded


def test_silent_box_times_out(port, box):
    port.silent = True
    with pytest.raises(DeviceTimeoutError, match=r"did not answer 'COUNT\?' within 0.05 s "
                                                 r".* syncbox firmware at 115200 baud"):
        box.pulse_count()


def test_open_fails_fast_on_a_silent_port():
    port = FakeSyncBoxSerial()
    port.silent = True
    box = SyncBox(port, timeout_s=0.01)
    with pytest.raises(DeviceTimeoutError, match=r"did not answer 'VERSION\?'"):
        box.open()
    assert box.state.value == "closed"


def test_err_replies_name_command_and_meaning(port, box):
    with pytest.raises(ProtocolError, match=r"refused 'SET PERIOD 5': ERR 3 \(bad value\) "
                                            r"BAD VALUE PERIOD MUST BE 20..1000000"):
        box.command("SET PERIOD 5")
    with pytest.raises(ProtocolError, match=r"refused 'FIRE': ERR 2 \(unknown command\)"):
        box.command("FIRE")
    box.command("START")
    with pytest.raises(ProtocolError, match=r"ERR 4 \(not allowed while running\)"):
        box.command("SET PULSES 4")


def test_fake_answers_bad_checksum_and_long_lines(port):
    port.write(b"START*00\n")
    assert port.readline() == sp.frame("ERR 1 BAD CHECKSUM")
    port.write(b"X" * 80 + b"\n")
    assert port.readline() == sp.frame("ERR 5 LINE TOO LONG")
    assert not port.running


def test_box_timeout_is_set_on_ports_without_one():
    class Port(FakeSyncBoxSerial):
        """A port class of its own, so setting its timeout does not touch the fake's."""

    port = Port()
    port.timeout = None
    SyncBox(port, timeout_s=0.2).open()
    assert port.timeout == 0.2


@pytest.mark.parametrize(
    "exc, cls, message",
    [
        (serial.SerialException(13, "could not open port /dev/ttyACM0: [Errno 13] Permission denied"),
         DevicePermissionError, r"add yourself to the `dialout` group"),
        (serial.SerialException(16, "[Errno 16] Device or resource busy"), DeviceBusyError,
         r"/dev/ttyACM0 is busy: another program holds it \(the Arduino IDE's serial monitor"),
        (serial.SerialException(2, "could not open port /dev/ttyACM0: [Errno 2] No such file or directory"),
         DeviceNotFoundError, r"no serial port /dev/ttyACM0: is the sync box plugged in"),
    ],
)
def test_serial_open_errors_are_mapped(exc, cls, message):
    err = map_serial_error(exc, "/dev/ttyACM0")
    assert type(err) is cls
    with pytest.raises(cls, match=message):
        raise err


def test_from_port_name_missing_port():
    with pytest.raises(DeviceNotFoundError, match="no serial port /nonexistent/ttyFLEXVOX"):
        SyncBox.from_port_name("/nonexistent/ttyFLEXVOX")


def test_firmware_sketch_speaks_the_same_commands():
    from pathlib import Path

    import rig_drivers

    sketch = (Path(rig_drivers.__file__).parent / "firmware" / "syncbox" / "syncbox.ino").read_text()
    for token in ("VERSION?", "SET PERIOD ", "SET PULSES ", "START", "STOP", "COUNT?", "TIME?",
                  "ERR 1 BAD CHECKSUM", "ERR 2 UNKNOWN COMMAND", "ERR 4 NOT ALLOWED WHILE RUNNING",
                  "ERR 5 LINE TOO LONG", "flexvox-syncbox 1.0", "115200"):
        assert token in sketch, token
