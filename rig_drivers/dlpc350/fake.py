"""A fake DLPC350 behind the :class:`~rig_drivers.dlpc350.transport.Transport` protocol.

It joins the reports of every message the driver sends as TI's API sends them (a message longer
than one report continues over several; :class:`~rig_drivers.dlpc350.protocol.MessageAssembler`),
keeps the controller's state (power, input source, LED currents and enables, display mode,
pattern source, trigger mode, exposure/period, LUT control, pattern LUT, TRIG_OUT settings, run
state, validation) and answers as the controller does: acknowledgements (after a message's last
report), status bytes, long replies over several reports, the validation byte with its busy bit
and failure bits, and a NAK (error flag, bit 5) for an unknown command, a bad payload length, a
value out of range (a TRIG_OUT invert flag other than TI's bit 0, a TRIG_OUT delay code above
0xD5), a configuration change while the sequence runs, or a start without a passed validation.
Every received report is kept in :attr:`received` so tests can compare them byte for byte.

Shipped in the package so the app can run a "LightCrafter" without hardware.
"""

from __future__ import annotations

import logging
import struct
from collections import deque

from rig_drivers.dlpc350 import protocol as p
from rig_drivers.errors import DeviceError, DeviceTimeoutError

_logger = logging.getLogger(__name__)

_CONFIG_COMMANDS = {
    p.Command.DISPLAY_MODE, p.Command.PATTERN_SOURCE, p.Command.TRIGGER_MODE,
    p.Command.EXPOSURE_PERIOD, p.Command.LUT_CONTROL, p.Command.MAILBOX_CONTROL,
    p.Command.MAILBOX_OFFSET, p.Command.MAILBOX_DATA, p.Command.TRIG_OUT1, p.Command.TRIG_OUT2,
    p.Command.TRIG_IN1, p.Command.TRIG_IN2, p.Command.SOURCE_SELECT,
}
_MIN_EXPOSURE_1BIT_US = 235
_MAX_PATTERN_NUMBER_1BIT = 25  # 24 = black, 25 = white fill (DLPU010G Table 2-69/2-70)


def _version_word(major: int, minor: int, patch: int) -> int:
    return major << 24 | minor << 16 | patch


class FakeDLPC350Transport:
    """A DLPC350 that lives in memory.

    Parameters
    ----------
    validate_busy_polls : int
        How many validation reads answer "busy" (bit 7) before the result.
    firmware : tuple of int
        ``(major, minor, patch)`` reported for the application firmware.

    Attributes
    ----------
    received : list of bytes
        Every report written to the fake, in order.
    silent : bool
        When True the fake records requests but never answers (timeouts).
    """

    def __init__(self, *, validate_busy_polls: int = 1, firmware: tuple[int, int, int] = (3, 0, 0)):
        self.validate_busy_polls = int(validate_busy_polls)
        self.firmware = firmware
        self.received: list[bytes] = []
        self.silent = False
        self.is_open = False
        self._replies: deque[bytes] = deque()
        self._injected: deque[bytes] = deque()
        self._assembler = p.MessageAssembler()
        self.reset()

    # ------------------------------------------------------------------ device state
    def reset(self) -> None:
        """Power-on state (DLPU010G reset values: flash source, trigger mode 1, video mode)."""
        self.standby = False
        self.input_source = bytes([p.InputSource.PARALLEL | p.PORT_WIDTHS[24] << 3])
        self.led_currents = bytes([0x68, 0x87, 0x82])  # the fake's power-on values
        self.led_enable = p.LED_SEQUENCER | 0b111
        self.display_mode = 0
        self.source = p.PatternSource.FLASH
        self.trigger_mode = p.TriggerMode.INTERNAL_OR_EXTERNAL
        self.exposure_us = 8333
        self.period_us = 8333
        self.lut_control = bytes([0, 1, 0, 0])
        self.mailbox = p.Mailbox.CLOSED
        self.mailbox_offset = 0
        self.pattern_lut: dict[int, bytes] = {}
        self.image_lut: dict[int, int] = {}
        self.trig_out = {1: bytes([0, p.TRIG_DELAY_ZERO, p.TRIG_DELAY_ZERO]), 2: bytes([0, p.TRIG_DELAY_ZERO])}
        self.trig_in1 = bytes(4)
        self.run_state = 0  # 0 stopped, 1 paused, 2 running
        self.validated = False
        self.validation_byte = 0
        self._busy_left = 0

    @property
    def lut_entries(self) -> int:
        """Number of LUT entries set by 0x1A31."""
        return self.lut_control[0] + 1

    @property
    def running(self) -> bool:
        """True while the sequence runs."""
        return self.run_state == 2

    def pattern_entries(self) -> list[p.LutEntry]:
        """The pattern LUT as decoded entries, in display order."""
        return [p.LutEntry.decode(self.pattern_lut[i]) for i in sorted(self.pattern_lut)]

    # ------------------------------------------------------------------ test helpers
    def messages(self) -> list[bytes]:
        """:attr:`received` joined into whole messages (continuation reports attached to their first)."""
        assembler, out = p.MessageAssembler(), []
        for report in self.received:
            message = assembler.feed(report)
            if message is not None:
                out.append(message)
        return out

    def requests(self) -> list[p.Request]:
        """:attr:`received`, parsed message by message."""
        return [p.parse_request(m) for m in self.messages()]

    def inject_reply(self, report: bytes) -> None:
        """Answer the next request with ``report`` instead of the computed reply."""
        self._injected.append(bytes(report))

    # ------------------------------------------------------------------ Transport
    def open(self) -> None:
        self.is_open = True
        self._replies.clear()
        self._assembler = p.MessageAssembler()

    def close(self) -> None:
        self.is_open = False

    def write(self, report: bytes) -> None:
        if not self.is_open:
            raise DeviceError("the fake DLPC350 transport is closed: open() it first")
        report = bytes(report)
        self.received.append(report)
        if self.silent:
            return
        try:
            message = self._assembler.feed(report)
        except Exception:  # noqa: BLE001 - a malformed report gets a NAK, as the controller does
            self._assembler = p.MessageAssembler()
            self._replies.extend(p.build_reply(report[1] if len(report) > 1 else 0, error=True))
            return
        if message is None:
            return  # continuation reports follow; the controller answers after the last one
        reply = self._handle(message)
        if self._injected:
            reply = [self._injected.popleft()]
        if reply is not None:
            self._replies.extend(reply)

    def read(self, timeout_s: float) -> bytes:
        if not self.is_open:
            raise DeviceError("the fake DLPC350 transport is closed: open() it first")
        if not self._replies:
            raise DeviceTimeoutError(f"no report from the fake DLPC350 within {timeout_s:g} s")
        return self._replies.popleft()

    # ------------------------------------------------------------------ protocol
    def _handle(self, message: bytes) -> list[bytes] | None:
        try:
            req = p.parse_request(message)
        except Exception as exc:  # a malformed request gets a NAK, as the controller does
            _logger.debug("fake DLPC350: malformed request (%s)", exc)
            return p.build_reply(message[1] if len(message) > 1 else 0, error=True)
        if req.read:
            data = self._read(req.command)
            if data is None:
                return p.build_reply(req.seq, read=True, error=True)
            return p.build_reply(req.seq, data, read=True)
        ok = self._write(req.command, req.payload)
        return p.build_reply(req.seq, error=not ok) if req.reply_wanted else None

    def _read(self, command: int) -> bytes | None:
        C = p.Command
        if command == C.GET_VERSION:
            app = _version_word(*self.firmware)
            return struct.pack("<4I", app, _version_word(2, 0, 0), _version_word(1, 0, 0),
                               _version_word(1, 0, 0))
        if command == C.HW_STATUS:
            return bytes([0x01])
        if command == C.SYS_STATUS:
            return bytes([0x01])
        if command == C.MAIN_STATUS:
            return bytes([(0x01 if self.standby else 0) | (0x02 if self.running else 0)])
        if command == C.VALIDATE:
            if self._busy_left > 0:
                self._busy_left -= 1
                return bytes([p.VALIDATE_BUSY])
            return bytes([self.validation_byte])
        if command == C.LED_CURRENT:
            return self.led_currents
        simple = {C.POWER_CONTROL: [int(self.standby)], C.DISPLAY_MODE: [self.display_mode],
                  C.SOURCE_SELECT: list(self.input_source), C.LED_ENABLE: [self.led_enable],
                  C.PATTERN_SOURCE: [self.source], C.TRIGGER_MODE: [self.trigger_mode],
                  C.START_STOP: [self.run_state], C.MAILBOX_CONTROL: [self.mailbox],
                  C.MAILBOX_OFFSET: [self.mailbox_offset]}
        if command in simple:
            return bytes(simple[command])
        if command == C.EXPOSURE_PERIOD:
            return struct.pack("<II", self.exposure_us, self.period_us)
        if command == C.LUT_CONTROL:
            return self.lut_control
        if command in (C.TRIG_OUT1, C.TRIG_OUT2):
            return self.trig_out[1 if command == C.TRIG_OUT1 else 2]
        if command == C.TRIG_IN1:
            return self.trig_in1
        if command == C.MAILBOX_DATA and self.mailbox == p.Mailbox.PATTERN:
            return b"".join(self.pattern_lut.get(i, bytes(3)) for i in range(self.mailbox_offset, self.lut_entries))
        return None

    def _write(self, command: int, payload: bytes) -> bool:
        C = p.Command
        if command not in p.WRITE_LENGTHS:
            _logger.debug("fake DLPC350: unknown command 0x%04X", command)
            return False
        expected = p.WRITE_LENGTHS[command]
        if expected is not None and len(payload) != expected:
            return False
        if command in _CONFIG_COMMANDS and self.run_state != 0:
            return False  # the controller wants the sequence stopped first
        if command in _CONFIG_COMMANDS:
            self.validated = False
        value = payload[0] if payload else 0
        if command == C.POWER_CONTROL:
            if value > 1:
                return False
            self.standby = bool(value)
        elif command == C.DISPLAY_MODE:
            if value > 1:
                return False
            self.display_mode = value
        elif command == C.PATTERN_SOURCE:
            if value not in (p.PatternSource.VIDEO_PORT, p.PatternSource.FLASH):
                return False
            self.source = p.PatternSource(value)
        elif command == C.TRIGGER_MODE:
            if value > 4:
                return False
            self.trigger_mode = value
        elif command == C.EXPOSURE_PERIOD:
            self.exposure_us, self.period_us = struct.unpack("<II", payload)
        elif command == C.LUT_CONTROL:
            if payload[0] >= p.MAX_LUT_ENTRIES or payload[1] > 1 or payload[3] > 63:
                return False
            self.lut_control = bytes(payload)
        elif command == C.MAILBOX_CONTROL:
            if value > 3:
                return False
            self.mailbox = p.Mailbox(value) if value < 3 else value
        elif command == C.MAILBOX_OFFSET:
            if value >= p.MAX_LUT_ENTRIES:
                return False
            self.mailbox_offset = value
        elif command == C.MAILBOX_DATA:
            return self._mailbox_data(payload)
        elif command in (C.TRIG_OUT1, C.TRIG_OUT2):
            # TI's API sends the invert flag as the whole byte (bit 0); the delay codes end at 0xD5.
            if payload[0] not in (0, p.TRIG_OUT_INVERT) or any(code > p.TRIG_DELAY_MAX for code in payload[1:]):
                return False
            self.trig_out[1 if command == C.TRIG_OUT1 else 2] = bytes(payload)
        elif command == C.TRIG_IN1:
            if struct.unpack("<I", payload)[0] >= 1 << 19:
                return False
            self.trig_in1 = bytes(payload)
        elif command == C.START_STOP:
            return self._start_stop(value)
        elif command == C.LED_CURRENT:
            self.led_currents = bytes(payload)
        elif command == C.LED_ENABLE:
            if value & ~0b1111:
                return False
            self.led_enable = value
        elif command == C.SOURCE_SELECT:
            if value & 0b111 > 3 or value >> 3 > 5:
                return False
            self.input_source = bytes(payload)
        elif command == C.VALIDATE:
            self.validation_byte = self._validate()
            self.validated = not self.validation_byte & p.VALIDATE_FAILURE_MASK
            self._busy_left = self.validate_busy_polls
        return True

    def _mailbox_data(self, payload: bytes) -> bool:
        if self.mailbox == p.Mailbox.PATTERN:
            if not payload or len(payload) % p.LUT_ENTRY_BYTES:
                return False
            n = len(payload) // p.LUT_ENTRY_BYTES
            if self.mailbox_offset + n > p.MAX_LUT_ENTRIES:
                return False
            for i in range(n):
                self.pattern_lut[self.mailbox_offset + i] = bytes(payload[3 * i:3 * i + 3])
            self.mailbox_offset += n
            return True
        if self.mailbox == p.Mailbox.IMAGE_INDEX:
            for i, index in enumerate(payload):
                self.image_lut[self.mailbox_offset + i] = index
            return True
        return False  # no mailbox open

    def _start_stop(self, value: int) -> bool:
        if value > 2:
            return False
        if value == 2:
            if not self.validated or self.display_mode != 1:
                return False
            self.run_state = 2
        elif value == 1:
            if self.run_state == 0:
                return False
            self.run_state = 1
        else:
            if self.run_state != 0:
                # After a stop the LUT must be sent again before the next start (DLPU010G
                # Table 2-62 note).
                self.validated = False
            self.run_state = 0
        return True

    def _validate(self) -> int:
        byte = 0
        exposure, period = self.exposure_us, self.period_us
        if exposure > period or exposure < _MIN_EXPOSURE_1BIT_US:
            byte |= 0b1
        elif exposure != period and period - exposure < 230:
            byte |= 0b1 | 0b1_0000
        if (self.source == p.PatternSource.VIDEO_PORT and self.trigger_mode == p.TriggerMode.VSYNC
                and exposure != period):
            byte |= 0b1
        entries = self.lut_entries
        if any(i not in self.pattern_lut for i in range(entries)):
            byte |= 0b10
        for i in range(entries):
            if i in self.pattern_lut:
                entry = p.LutEntry.decode(self.pattern_lut[i])
                if entry.bit_depth == 1 and entry.pattern_number > _MAX_PATTERN_NUMBER_1BIT:
                    byte |= 0b10
        return byte
