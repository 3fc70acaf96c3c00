"""The driver sends the bytes TI's own API sends: every command and whole K = 8, 16, 24, 32 sessions.

The expected reports are the fixture ``golden/dlpc350_ti.json``, rebuilt from reading TI's
``dlpc350_api.cpp`` by ``golden/ti_reference.py`` (its docstring lists the facts and their TI
functions); that module imports nothing from flexvox.
"""

import json

import numpy as np
import pytest

from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from rig_drivers.dlpc350 import protocol as p
from rig_drivers.errors import ProtocolError
from rig_drivers.interfaces import PatternSequence, ProjectorTrigger

from .golden import ti_reference

GOLDEN = json.loads(ti_reference.FIXTURE.read_text())


def _nak_ok(lcr, command, payload):
    with pytest.raises(ProtocolError, match=r"refused START_STOP"):
        lcr.write_command(command, payload)


CALLS = {  # the fixture's TI call -> the same request through the driver
    "SetPowerMode(standby)": lambda d: d.set_standby(True),
    "SetPowerMode(normal)": lambda d: d.set_standby(False),
    "PatternDisplay(stop)": lambda d: d.write_command(p.Command.START_STOP, bytes([0])),
    # a fresh controller NAKs pause and start (nothing validated): the request's bytes are what is compared
    "PatternDisplay(pause)": lambda d: _nak_ok(d, p.Command.START_STOP, bytes([1])),
    "PatternDisplay(start)": lambda d: _nak_ok(d, p.Command.START_STOP, bytes([2])),
    "SetMode(pattern)": lambda d: d.set_display_mode(True),
    "SetMode(video)": lambda d: d.set_display_mode(False),
    "SetPatternDisplayMode(video port)": lambda d: d.write_command(p.Command.PATTERN_SOURCE,
                                                                   bytes([p.PatternSource.VIDEO_PORT])),
    "SetPatternConfig(16, repeat, 16, 1)": lambda d: d.write_command(p.Command.LUT_CONTROL,
                                                                     p.encode_lut_control(16, True, 16, 1)),
    "SetPatternTriggerMode(0)": lambda d: d.write_command(p.Command.TRIGGER_MODE, bytes([p.TriggerMode.VSYNC])),
    "SetExposure_FramePeriod(3936, 4166)": lambda d: d.set_exposure_period(3936, 4166),
    "StartPatLutValidate": lambda d: d.write_command(p.Command.VALIDATE, bytes([0])),
    "CheckPatLutValidate": lambda d: d.read_command(p.Command.VALIDATE),
    "SetTrigOutConfig(1, invert, -20.05 µs, 0 µs)": lambda d: d.configure_trigger_output(1, invert=True,
                                                                                         rising_us=-20.05),
    "SetTrigOutConfig(2, normal, +1.072 µs)": lambda d: d.configure_trigger_output(2, rising_us=1.072),
    "SetTrigOutConfig(2, invert, +2.787 µs)": lambda d: d.configure_trigger_output(2, invert=True, rising_us=2.787),
    "SetTrigIn1Delay(1000)": lambda d: d.configure_trigger_input(delay_us=107.136),
    "SetLedCurrents(104, 135, 130)": lambda d: d.set_led_currents(104, 135, 130),
    "SetLedEnables(sequencer)": lambda d: d.set_led_enables(automatic=True),
    "SetLedEnables(green only)": lambda d: d.set_led_enables(automatic=False, red=False, blue=False),
    "SetInputSource(parallel, 24 bits)": lambda d: d.set_input_source(p.InputSource.PARALLEL, 24),
    "SetInputSource(test pattern, 24 bits)": lambda d: d.set_input_source(p.InputSource.TEST_PATTERN, 24),
    "GetVersion": lambda d: d.version(),
    "GetStatus (hardware)": lambda d: d.read_command(p.Command.HW_STATUS),
    "GetStatus (system)": lambda d: d.read_command(p.Command.SYS_STATUS),
    "GetStatus (main)": lambda d: d.read_command(p.Command.MAIN_STATUS),
    "GetPowerMode": lambda d: d.power_mode(),
    "GetLedCurrents": lambda d: d.led_currents(),
    "GetLedEnables": lambda d: d.led_enables(),
    "GetInputSource": lambda d: d.input_source(),
}


def test_the_fixture_is_what_the_reference_rebuilds():
    assert GOLDEN == json.loads(json.dumps(ti_reference.make_fixture()))


def test_every_command_is_in_the_fixture():
    assert set(CALLS) == set(GOLDEN["commands"]) and len(CALLS) == 30


@pytest.mark.parametrize("name", sorted(GOLDEN["commands"]))
def test_each_command_byte_for_byte(name):
    fake = FakeDLPC350Transport()
    with DLPC350(fake, poll_interval_s=0, reply_timeout_s=0.01) as lcr:
        CALLS[name](lcr)
        sent = [r.hex() for r in fake.received]
    assert sent == GOLDEN["commands"][name]["reports"]


@pytest.mark.parametrize("K", [8, 16, 24, 32])
def test_whole_sessions_byte_for_byte(K, rng):
    golden = GOLDEN["sessions"][f"K={K}"]
    fake = FakeDLPC350Transport(validate_busy_polls=golden["validate_polls"] - 1)
    masks = rng.random((K, 6, 8)) < 0.5
    seq = PatternSequence(masks, golden["period_us"], golden["period_us"], trigger=ProjectorTrigger.VSYNC,
                          patterns_per_trigger=golden["patterns_per_vsync"])
    with DLPC350(fake, poll_interval_s=0) as lcr:
        assert lcr.video_sequence(masks, golden["period_us"]).patterns_per_trigger == golden["patterns_per_vsync"]
        lcr.enable()
        lcr.load_sequence(seq)
        lcr.start()
        lcr.stop()
    sent = [r.hex() for r in fake.received]
    assert sent == golden["reports"]
    assert [e.pattern_number for e in fake.pattern_entries()] == [k % 24 for k in range(K)]
    continued = len(fake.received) - len(fake.messages())  # reports that continue a message
    assert continued == (1 if K >= 20 else 0)  # the LUT message, 3·K + 2 bytes: one report up to K = 19
    assert np.array_equal(lcr.frames_for(seq).shape[0:1], [-(-K // 24)])
