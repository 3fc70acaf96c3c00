"""The bytes TI's reference API sends to a DLPC350, rebuilt from reading it (not from flexvox).

Source: TI's ``dlpc350_api.cpp`` / ``dlpc350_api.h`` (BSD-3, the API TI's LightCrafter 4500 GUI
drives the firmware with), read in the copy bundled by jakobwilm/slstudio under
``src/projector/LC4500API/``. No TI code is copied; what each function puts on the wire is
restated here, function by function, so that ``make_fixture()`` can write the expected reports
of every command flexvox sends and of whole sessions to ``dlpc350_ti.json``, which the golden
test compares the driver with. This module imports nothing from flexvox on purpose.

Facts used (function names are TI's):

* ``DLPC350_PrepWriteCmd``: flags 0x40 (write, reply wanted, destination 0), sequence number
  from a counter that starts at 0 and counts every write; length = command bytes (2) + the
  command's data length from ``CmdList``. ``DLPC350_PrepReadCmd``: flags 0xC0, sequence 0,
  length 2. The command goes out as CMD3 then CMD2 (little-endian 0xCMD2CMD3).
* ``DLPC350_SendMsg``: the first 64-byte report holds the 4-byte header and up to 60 bytes of
  command + data; the rest follows in 64-byte reports with no header. The padding after the
  message is zeros here; TI sends whatever its buffer held there, which the device does not read.
* ``DLPC350_StartPatLutValidate`` leaves LUT_VALID's one data byte unset; flexvox sends 0, and so
  does this reference. The session's order of calls and its LUT are flexvox's choices, written
  with TI's functions: the session tests check their encoding, not the choices.
* ``CmdList`` lengths: SOURCE_SEL 0x1A00/1, LED_ENABLE 0x1A07/1, LED_CURRENT 0x0B01/3,
  POWER_CONTROL 0x0200/1, LUT_VALID 0x1A1A/1, DISP_MODE 0x1A1B/1, TRIG_OUT1_CTL 0x1A1D/3,
  TRIG_OUT2_CTL 0x1A1E/2, PAT_DISP_MODE 0x1A22/1, PAT_TRIG_MODE 0x1A23/1, PAT_START_STOP
  0x1A24/1, PAT_EXPO_PRD 0x1A29/8, PAT_CONFIG 0x1A31/4, MBOX_ADDRESS 0x1A32/1, MBOX_CONTROL
  0x1A33/1, MBOX_DATA 0x1A34/(set per call), TRIG_IN1_DELAY 0x1A35/4; reads GET_VERSION 0x0205,
  STATUS_HW 0x1A0A, STATUS_SYS 0x1A0B, STATUS_MAIN 0x1A0C.
* ``DLPC350_SetTrigOutConfig(n, invert, rising, falling)``: data = [invert (0/1), rising,
  falling] for TRIG_OUT_1, the first two for TRIG_OUT_2.
* ``DLPC350_SetLedCurrents(r, g, b)``: data = [r, g, b]. ``DLPC350_SetLedEnables(seq, r, g, b)``:
  one byte, bit 0 red, 1 green, 2 blue, 3 sequencer control.
* ``DLPC350_SetInputSource(source, portWidth)``: one byte, source | portWidth << 3.
* ``DLPC350_SetPatternConfig(entries, repeat, trigOut2, images)``: [entries − 1, repeat,
  trigOut2 − 1, images − 1].
* ``DLPC350_SetExposure_FramePeriod(e, p)``: two uint32 little-endian.
* ``DLPC350_AddToPatLut``: word = trigger | pattern << 2 | bitDepth << 8 | LED << 12 |
  invert << 16 | insertBlack << 17 | bufferSwap << 18 | trigOutPrev << 19, 3 bytes LE each.
* ``DLPC350_SendPatLut``: OpenMailbox(2), MailboxSetAddr(0), one MBOX_DATA message of 3·K bytes,
  CloseMailbox (MBOX_CONTROL 0).
* ``DLPC350_PatternDisplay(action)``: PAT_START_STOP [action] (0 stop, 1 pause, 2 start).
  ``DLPC350_SetMode(pattern)``: DISP_MODE [1]. ``DLPC350_SetPatternDisplayMode(external)``:
  PAT_DISP_MODE [0] for the video port. ``DLPC350_SetPowerMode(standby)``: POWER_CONTROL [1/0].
  ``DLPC350_SetTrigIn1Delay(d)``: uint32 LE.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

FIXTURE = Path(__file__).with_name("dlpc350_ti.json")

CMD = {  # name: (CMD2, CMD3, data length)
    "SOURCE_SEL": (0x1A, 0x00, 1), "LED_ENABLE": (0x1A, 0x07, 1), "LED_CURRENT": (0x0B, 0x01, 3),
    "POWER_CONTROL": (0x02, 0x00, 1), "GET_VERSION": (0x02, 0x05, 0), "STATUS_HW": (0x1A, 0x0A, 0),
    "STATUS_SYS": (0x1A, 0x0B, 0), "STATUS_MAIN": (0x1A, 0x0C, 0), "LUT_VALID": (0x1A, 0x1A, 1),
    "DISP_MODE": (0x1A, 0x1B, 1), "TRIG_OUT1_CTL": (0x1A, 0x1D, 3), "TRIG_OUT2_CTL": (0x1A, 0x1E, 2),
    "PAT_DISP_MODE": (0x1A, 0x22, 1), "PAT_TRIG_MODE": (0x1A, 0x23, 1), "PAT_START_STOP": (0x1A, 0x24, 1),
    "PAT_EXPO_PRD": (0x1A, 0x29, 8), "PAT_CONFIG": (0x1A, 0x31, 4), "MBOX_ADDRESS": (0x1A, 0x32, 1),
    "MBOX_CONTROL": (0x1A, 0x33, 1), "MBOX_DATA": (0x1A, 0x34, None), "TRIG_IN1_DELAY": (0x1A, 0x35, 4),
}


def _reports(flags: int, seq: int, name: str, data: bytes) -> list[str]:
    cmd2, cmd3, _ = CMD[name]
    text = bytes([cmd3, cmd2]) + data
    head = struct.pack("<BBH", flags, seq, len(text))
    chunks = [head + text[:60]] + [text[i:i + 64] for i in range(60, len(text), 64)]
    return [c.ljust(64, b"\0").hex() for c in chunks]


class TiHost:
    """TI's API on the host side: each call returns the reports it writes."""

    def __init__(self):
        self.seq = 0

    def write(self, name: str, data: bytes) -> list[str]:
        length = CMD[name][2]
        assert length is None or len(data) == length, (name, data)
        out = _reports(0x40, self.seq, name, bytes(data))
        self.seq = (self.seq + 1) & 0xFF
        return out

    def read(self, name: str) -> list[str]:
        return _reports(0xC0, 0, name, b"")

    # -- the API functions
    def SetPowerMode(self, standby):  # noqa: N802 - TI's names
        return self.write("POWER_CONTROL", bytes([1 if standby else 0]))

    def PatternDisplay(self, action):  # noqa: N802
        return self.write("PAT_START_STOP", bytes([action]))

    def SetMode(self, pattern):  # noqa: N802
        return self.write("DISP_MODE", bytes([1 if pattern else 0]))

    def SetPatternDisplayMode(self, external):  # noqa: N802
        return self.write("PAT_DISP_MODE", bytes([0 if external else 3]))

    def SetPatternConfig(self, entries, repeat, trig_out2, images):  # noqa: N802
        return self.write("PAT_CONFIG", bytes([entries - 1, 1 if repeat else 0, trig_out2 - 1, images - 1]))

    def SetPatternTriggerMode(self, mode):  # noqa: N802
        return self.write("PAT_TRIG_MODE", bytes([mode]))

    def SetExposure_FramePeriod(self, exposure, period):  # noqa: N802
        return self.write("PAT_EXPO_PRD", struct.pack("<II", exposure, period))

    def SendPatLut(self, words):  # noqa: N802
        data = b"".join(w.to_bytes(3, "little") for w in words)
        return (self.write("MBOX_CONTROL", bytes([2])) + self.write("MBOX_ADDRESS", bytes([0]))
                + self.write("MBOX_DATA", data) + self.write("MBOX_CONTROL", bytes([0])))

    def StartPatLutValidate(self):  # noqa: N802
        return self.write("LUT_VALID", bytes([0]))

    def CheckPatLutValidate(self):  # noqa: N802
        return self.read("LUT_VALID")

    def SetTrigOutConfig(self, number, invert, rising, falling=0xBB):  # noqa: N802
        if number == 1:
            return self.write("TRIG_OUT1_CTL", bytes([1 if invert else 0, rising, falling]))
        return self.write("TRIG_OUT2_CTL", bytes([1 if invert else 0, rising]))

    def SetTrigIn1Delay(self, counts):  # noqa: N802
        return self.write("TRIG_IN1_DELAY", struct.pack("<I", counts))

    def SetLedCurrents(self, red, green, blue):  # noqa: N802
        return self.write("LED_CURRENT", bytes([red, green, blue]))

    def SetLedEnables(self, seq_ctrl, red, green, blue):  # noqa: N802
        return self.write("LED_ENABLE", bytes([(8 if seq_ctrl else 0) | (1 if red else 0) | (2 if green else 0)
                                               | (4 if blue else 0)]))

    def SetInputSource(self, source, port_width_code):  # noqa: N802
        return self.write("SOURCE_SEL", bytes([source | port_width_code << 3]))


def lut_word(trigger, pattern, bit_depth=1, led=0b111, invert=0, black=0, swap=0, prev=0) -> int:
    """``DLPC350_AddToPatLut``'s 24-bit word."""
    return trigger | pattern << 2 | bit_depth << 8 | led << 12 | invert << 16 | black << 17 | swap << 18 | prev << 19


def session(K: int, period_us: int, per_vsync: int, validate_polls: int) -> list[str]:
    """A video-port pattern session as TI's API runs it: leave standby, stop, pattern mode, video
    source, pattern config (TRIG_OUT_2 once per K), VSYNC trigger mode, exposure = period, the LUT
    (entry k shows bit-plane k mod 24; every ``per_vsync``-th waits for VSYNC and swaps buffers),
    validate and poll, start, stop, standby."""
    ti = TiHost()
    out = ti.SetPowerMode(False) + ti.PatternDisplay(0) + ti.SetMode(True) + ti.SetPatternDisplayMode(True)
    out += ti.SetPatternConfig(K, True, K, -(-K // 24)) + ti.SetPatternTriggerMode(0)
    out += ti.SetExposure_FramePeriod(period_us, period_us)
    words = [lut_word(1 if k % per_vsync == 0 else 3, k % 24, swap=int(k % per_vsync == 0)) for k in range(K)]
    out += ti.SendPatLut(words) + ti.StartPatLutValidate()
    for _ in range(validate_polls):
        out += ti.CheckPatLutValidate()
    return out + ti.PatternDisplay(2) + ti.PatternDisplay(0) + ti.SetPowerMode(True)


SESSIONS = {  # K: (period µs at a 15 Hz camera, patterns per 60 Hz VSYNC)
    8: (8333, 2), 16: (4166, 4), 24: (2777, 6), 32: (2083, 8),
}
VALIDATE_POLLS = 2  # the fake answers "busy" once, then the result


def commands() -> dict:
    """Every single command flexvox sends, each as the first call of a fresh host (sequence 0)."""
    cases = {
        "SetPowerMode(standby)": ("set_standby(True)", lambda t: t.SetPowerMode(True)),
        "SetPowerMode(normal)": ("set_standby(False)", lambda t: t.SetPowerMode(False)),
        "PatternDisplay(stop)": ("write START_STOP 0", lambda t: t.PatternDisplay(0)),
        "PatternDisplay(pause)": ("write START_STOP 1", lambda t: t.PatternDisplay(1)),
        "PatternDisplay(start)": ("write START_STOP 2", lambda t: t.PatternDisplay(2)),
        "SetMode(pattern)": ("set_display_mode(True)", lambda t: t.SetMode(True)),
        "SetMode(video)": ("set_display_mode(False)", lambda t: t.SetMode(False)),
        "SetPatternDisplayMode(video port)": ("write PATTERN_SOURCE 0", lambda t: t.SetPatternDisplayMode(True)),
        "SetPatternConfig(16, repeat, 16, 1)": ("write LUT_CONTROL", lambda t: t.SetPatternConfig(16, True, 16, 1)),
        "SetPatternTriggerMode(0)": ("write TRIGGER_MODE 0", lambda t: t.SetPatternTriggerMode(0)),
        "SetExposure_FramePeriod(3936, 4166)": ("set_exposure_period(3936, 4166)",
                                                lambda t: t.SetExposure_FramePeriod(3936, 4166)),
        "StartPatLutValidate": ("write VALIDATE 0", lambda t: t.StartPatLutValidate()),
        "CheckPatLutValidate": ("read VALIDATE", lambda t: t.CheckPatLutValidate()),
        "SetTrigOutConfig(1, invert, -20.05 µs, 0 µs)": ("configure_trigger_output(1, invert=True, rising_us=-20.05)",
                                                         lambda t: t.SetTrigOutConfig(1, True, 0x00, 0xBB)),
        "SetTrigOutConfig(2, normal, +1.072 µs)": ("configure_trigger_output(2, rising_us=1.072)",
                                                   lambda t: t.SetTrigOutConfig(2, False, 0xC5)),
        "SetTrigOutConfig(2, invert, +2.787 µs)": ("configure_trigger_output(2, invert=True, rising_us=2.787)",
                                                   lambda t: t.SetTrigOutConfig(2, True, 0xD5)),
        "SetTrigIn1Delay(1000)": ("configure_trigger_input(delay_us=107.136)", lambda t: t.SetTrigIn1Delay(1000)),
        "SetLedCurrents(104, 135, 130)": ("set_led_currents(104, 135, 130)",
                                          lambda t: t.SetLedCurrents(104, 135, 130)),
        "SetLedEnables(sequencer)": ("set_led_enables(automatic=True)",
                                     lambda t: t.SetLedEnables(True, True, True, True)),
        "SetLedEnables(green only)": ("set_led_enables(automatic=False, red=False, blue=False)",
                                      lambda t: t.SetLedEnables(False, False, True, False)),
        "SetInputSource(parallel, 24 bits)": ("set_input_source(PARALLEL, 24)", lambda t: t.SetInputSource(0, 1)),
        "SetInputSource(test pattern, 24 bits)": ("set_input_source(TEST_PATTERN, 24)",
                                                  lambda t: t.SetInputSource(1, 1)),
        "GetVersion": ("version()", lambda t: t.read("GET_VERSION")),
        "GetStatus (hardware)": ("status() (1 of 3)", lambda t: t.read("STATUS_HW")),
        "GetStatus (system)": ("status() (2 of 3)", lambda t: t.read("STATUS_SYS")),
        "GetStatus (main)": ("status() (3 of 3)", lambda t: t.read("STATUS_MAIN")),
        "GetPowerMode": ("power_mode()", lambda t: t.read("POWER_CONTROL")),
        "GetLedCurrents": ("led_currents()", lambda t: t.read("LED_CURRENT")),
        "GetLedEnables": ("led_enables()", lambda t: t.read("LED_ENABLE")),
        "GetInputSource": ("input_source()", lambda t: t.read("SOURCE_SEL")),
    }
    return {name: {"flexvox": call, "reports": make(TiHost())} for name, (call, make) in cases.items()}


def make_fixture() -> dict:
    return {
        "provenance": ("Rebuilt from reading TI's dlpc350_api.cpp (BSD-3; jakobwilm/slstudio "
                       "src/projector/LC4500API/) by tests/rig_drivers/golden/ti_reference.py; no TI code copied. "
                       "Reports are 64 bytes, hex; sessions run at a 15 Hz camera and a 60 Hz video input."),
        "commands": commands(),
        "sessions": {f"K={K}": {"period_us": per, "patterns_per_vsync": n, "validate_polls": VALIDATE_POLLS,
                                "reports": session(K, per, n, VALIDATE_POLLS)}
                     for K, (per, n) in SESSIONS.items()},
    }


if __name__ == "__main__":  # regenerate: .venv/bin/python -m tests.rig_drivers.golden.ti_reference
    FIXTURE.write_text(json.dumps(make_fixture(), indent=1) + "\n")
    print(f"wrote {FIXTURE}")
