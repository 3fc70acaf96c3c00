"""DLPC350 (TI DLP LightCrafter 4500) USB HID packets, command codes and field encodings.

Sources: TI *DLPC350 Programmer's Guide*, DLPU010G (cited below as "DLPU010G §..."), and TI's
reference C API ``dlpc350_api.cpp`` / ``dlpc350_api.h`` (BSD-3; the code TI's LightCrafter 4500
GUI drives the firmware with; read in the copy bundled by jakobwilm/slstudio under
``src/projector/LC4500API/``), cited as "TI API ``Function``". Where the two disagree, the TI API
settles it: it is what the firmware has been driven by for years. Nothing of TI's code is copied;
the facts taken from it are recorded here with their function names.

Packet (DLPU010G §1.2), 64-byte HID reports, little-endian::

    byte 0   flags   bit7 = read (1) / write (0); bit6 = host wants a reply;
                     bit5 = (in replies) error / NAK; bits 2:0 destination (0 = projector)
    byte 1   sequence number (echoed in the reply)
    byte 2-3 length of what follows the header (LSB first)
    byte 4-5 command, CMD3 first then CMD2 (0x1A24 goes out as 24 1A)
    byte 6.. payload

The length counts the two command bytes plus the payload (TI API ``DLPC350_PrepWriteCmd``:
``len + 2``), so a read request has length 2. A reply is ``[flags, seq, len_lo, len_hi, data...]``
with ``len`` data bytes and no command echo. Writes here always ask for a reply (flags 0x40) so a
NAK is seen at once; reads use flags 0xC0.

Messages longer than one report (TI API ``DLPC350_SendMsg``): the first report carries the
4-byte header and the first 60 bytes of (command + payload); the rest follows in continuation
reports of 64 bytes each, with no header, zero padded; the length field counts the whole
message. The host asks for the acknowledgement once, after the last report. A whole pattern LUT
goes out this way as one 0x1A34 message (TI API ``DLPC350_SendPatLut``), and a long reply comes
back the same way (TI API ``DLPC350_GetPatLut``). :func:`message_reports` splits a message and
:class:`MessageAssembler` joins one; the transport sends and receives whole messages through them.

Sequence numbers (TI API ``DLPC350_PrepWriteCmd`` / ``DLPC350_PrepReadCmd``): each write carries
the next number of a counter that starts at 0; every read request carries 0.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from rig_drivers.errors import ProtocolError, SettingError
from rig_drivers.interfaces import MIN_DARK_US, check_int

REPORT_SIZE = 64
HEADER_SIZE = 4
MAX_PAYLOAD = REPORT_SIZE - HEADER_SIZE - 2  # 58 payload bytes in one report
FIRST_REPORT_BODY = REPORT_SIZE - HEADER_SIZE  # command + payload bytes in a message's first report
MAX_MESSAGE_BODY = 0xFFFF

FLAG_READ = 0x80
FLAG_REPLY = 0x40
FLAG_ERROR = 0x20


class Command(enum.IntEnum):
    """USB command codes (CMD2 << 8 | CMD3) used by the driver, DLPU010G chapter 2."""

    SOURCE_SELECT = 0x1A00        # TI API SetInputSource: bits 2:0 source, 5:3 parallel port width
    LED_ENABLE = 0x1A07           # TI API SetLedEnables: b0 red, b1 green, b2 blue, b3 sequencer drives
    LED_CURRENT = 0x0B01          # TI API SetLedCurrents: red, green, blue PWM 0..255
    POWER_CONTROL = 0x0200        # §2.3.1.1: 1 = standby, 0 = normal
    GET_VERSION = 0x0205          # §2.1.4: 4 x uint32 (app, API, SW config, sequencer config)
    HW_STATUS = 0x1A0A            # §2.1.1
    SYS_STATUS = 0x1A0B           # §2.1.2
    MAIN_STATUS = 0x1A0C          # §2.1.3
    VALIDATE = 0x1A1A             # §2.4.3.1, Table 2-52
    DISPLAY_MODE = 0x1A1B         # §2.4.1: 0 = video, 1 = pattern
    TRIG_OUT1 = 0x1A1D            # §2.4.3.2.2, Table 2-54
    TRIG_OUT2 = 0x1A1E            # §2.4.3.2.3, Table 2-55
    PATTERN_SOURCE = 0x1A22       # §2.4.3.4.1, Table 2-61: 0 = video port, 3 = flash
    TRIGGER_MODE = 0x1A23         # §2.4.3.2.1, Table 2-53
    START_STOP = 0x1A24           # §2.4.3.4.2, Table 2-62: 0 stop, 1 pause, 2 start
    EXPOSURE_PERIOD = 0x1A29      # §2.4.3.4.3, Table 2-63
    LUT_CONTROL = 0x1A31          # §2.4.3.4.5, Table 2-65
    MAILBOX_OFFSET = 0x1A32       # §2.4.3.4.7, Table 2-66
    MAILBOX_CONTROL = 0x1A33      # §2.4.3.4.8, Table 2-67
    MAILBOX_DATA = 0x1A34         # §2.4.3.4.9, Tables 2-68/2-69
    TRIG_IN1 = 0x1A35             # §2.4.3.2.4, Table 2-56
    TRIG_IN2 = 0x1A36             # §2.4.3.2.5, Table 2-57


WRITE_LENGTHS: dict[int, int | None] = {
    Command.SOURCE_SELECT: 1, Command.LED_ENABLE: 1, Command.LED_CURRENT: 3,
    Command.POWER_CONTROL: 1, Command.VALIDATE: 1, Command.DISPLAY_MODE: 1,
    Command.TRIG_OUT1: 3, Command.TRIG_OUT2: 2, Command.PATTERN_SOURCE: 1,
    Command.TRIGGER_MODE: 1, Command.START_STOP: 1, Command.EXPOSURE_PERIOD: 8,
    Command.LUT_CONTROL: 4, Command.MAILBOX_OFFSET: 1, Command.MAILBOX_CONTROL: 1,
    Command.MAILBOX_DATA: None, Command.TRIG_IN1: 4, Command.TRIG_IN2: 1,
}
"""Payload bytes of each writable command (None = variable: the mailbox)."""

READABLE = frozenset(WRITE_LENGTHS) | {Command.GET_VERSION, Command.HW_STATUS,
                                       Command.SYS_STATUS, Command.MAIN_STATUS}


def command_name(code: int) -> str:
    """``"START_STOP (0x1A24)"`` for a known code, ``"0x1234"`` otherwise."""
    try:
        return f"{Command(code).name} (0x{code:04X})"
    except ValueError:
        return f"0x{code:04X}"


# --------------------------------------------------------------------------- packets


def message_reports(command: int, payload: bytes = b"", *, read: bool = False, seq: int = 0) -> list[bytes]:
    """One message as the 64-byte reports that carry it (TI API ``DLPC350_SendMsg``; module docstring).

    Raises
    ------
    ValueError
        When the message is longer than the 16-bit length field allows.
    """
    body = struct.pack("<H", command) + bytes(payload)
    if len(body) > MAX_MESSAGE_BODY:
        raise ValueError(f"`payload` must be at most {MAX_MESSAGE_BODY - 2} bytes; got {len(payload)}")
    flags = (FLAG_READ if read else 0) | FLAG_REPLY
    first = struct.pack("<BBH", flags, seq & 0xFF, len(body)) + body[:FIRST_REPORT_BODY]
    rest = [body[i:i + REPORT_SIZE] for i in range(FIRST_REPORT_BODY, len(body), REPORT_SIZE)]
    return [r.ljust(REPORT_SIZE, b"\x00") for r in (first, *rest)]


def build_packet(command: int, payload: bytes = b"", *, read: bool = False, seq: int = 0) -> bytes:
    """Build a message that fits one 64-byte report (zero padded).

    Raises
    ------
    ValueError
        When the payload does not fit in one report (more than 58 bytes): use :func:`message_reports`.
    """
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"`payload` must be at most {MAX_PAYLOAD} bytes to fit one report; got {len(payload)}")
    return message_reports(command, payload, read=read, seq=seq)[0]


def continuation_reports(length: int, first_capacity: int = FIRST_REPORT_BODY) -> int:
    """How many continuation reports follow a first report whose length field is ``length``."""
    return max(0, -(-(length - first_capacity) // REPORT_SIZE))


class MessageAssembler:
    """Joins the reports of one message (the inverse of :func:`message_reports`).

    :meth:`feed` takes reports in order and returns the whole message (its first report's
    header followed by every body byte, as if it had come in one report) once the last
    report has arrived, else None.
    """

    def __init__(self):
        self._parts: list[bytes] = []
        self._needed = 0

    @property
    def pending(self) -> bool:
        """True while a message waits for continuation reports."""
        return bool(self._parts)

    def feed(self, report: bytes) -> bytes | None:
        report = bytes(report)
        if not self._parts:
            if len(report) < HEADER_SIZE:
                raise ProtocolError(f"a report must be {REPORT_SIZE} bytes; got {len(report)}")
            length = report[2] | report[3] << 8
            self._needed = continuation_reports(length)
            self._length = length
        self._parts.append(report)
        if len(self._parts) <= self._needed:
            return None
        first, *rest = self._parts
        self._parts = []
        body = first[HEADER_SIZE:HEADER_SIZE + FIRST_REPORT_BODY] + b"".join(rest)
        return first[:HEADER_SIZE] + body[:self._length]


@dataclass(frozen=True)
class Request:
    """A parsed host → device packet."""

    read: bool
    reply_wanted: bool
    seq: int
    command: int
    payload: bytes


def parse_request(message: bytes) -> Request:
    """Parse a host → device message: one report, or the reports of a long message joined by
    :class:`MessageAssembler` (used by the fake device)."""
    message = bytes(message)
    if len(message) < HEADER_SIZE + 2:
        raise ProtocolError(f"a request must hold a header and a command; got {len(message)} bytes")
    flags, seq, length, command = struct.unpack_from("<BBHH", message)
    if length < 2 or (len(message) == REPORT_SIZE and length > FIRST_REPORT_BODY) \
            or len(message) < HEADER_SIZE + length:
        raise ProtocolError(f"request length field {length} does not match the {len(message)} bytes received")
    payload = bytes(message[6:HEADER_SIZE + length])
    return Request(bool(flags & FLAG_READ), bool(flags & FLAG_REPLY), seq, command, payload)


def build_reply(seq: int, data: bytes = b"", *, read: bool = False, error: bool = False) -> list[bytes]:
    """A device → host reply as its reports (used by the fake device): one report, or a first
    report of 60 data bytes and continuation reports of 64, as a long message goes."""
    flags = (FLAG_READ if read else 0) | FLAG_REPLY | (FLAG_ERROR if error else 0)
    data = bytes(data)
    first = struct.pack("<BBH", flags, seq & 0xFF, len(data)) + data[:FIRST_REPORT_BODY]
    rest = [data[i:i + REPORT_SIZE] for i in range(FIRST_REPORT_BODY, len(data), REPORT_SIZE)]
    return [r.ljust(REPORT_SIZE, b"\x00") for r in (first, *rest)]


def parse_reply(report: bytes, *, command: int, seq: int) -> bytes:
    """Check a reply to ``command`` sent with ``seq`` and return its data bytes (``report``: one
    report, or a long reply joined by :class:`MessageAssembler`).

    Raises
    ------
    ProtocolError
        On the error flag (NAK), a wrong sequence number, or a malformed report; the
        message names the command.
    """
    name = command_name(command)
    report = bytes(report)
    if len(report) < HEADER_SIZE:
        raise ProtocolError(f"malformed reply to {name}: {len(report)} bytes, expected {REPORT_SIZE}")
    flags, rseq, length = struct.unpack_from("<BBH", report)
    if flags & FLAG_ERROR:
        raise ProtocolError(
            f"the projector refused {name} (NAK: error flag set in the reply). The command is "
            f"not allowed now or its value is out of range; stop the pattern sequence before "
            f"changing settings")
    if rseq != seq & 0xFF:
        raise ProtocolError(f"reply to {name} carries sequence number {rseq}, expected {seq & 0xFF}: "
                            f"another program (TI's GUI?) is talking to the projector; close it")
    if HEADER_SIZE + length > len(report):
        raise ProtocolError(f"malformed reply to {name}: length field {length} exceeds the report")
    return report[HEADER_SIZE:HEADER_SIZE + length]


# --------------------------------------------------------------------------- field encodings


class PatternSource(enum.IntEnum):
    """Pattern Display Data Input Source, 0x1A22 (DLPU010G §2.4.3.4.1, Table 2-61)."""

    VIDEO_PORT = 0  # 24-bit RGB / FPD-link stream: masks arrive as bit-planes of video frames
    FLASH = 3       # images pre-stored in flash


class TriggerMode(enum.IntEnum):
    """Pattern Trigger Mode, 0x1A23 (DLPU010G §2.4.3.2.1, Table 2-53)."""

    VSYNC = 0                  # video-port VSYNC triggers; exposure must equal the period
    INTERNAL_OR_EXTERNAL = 1   # internal timer or TRIG_IN_1 (patterns from flash)


class LutTrigger(enum.IntEnum):
    """Per-pattern trigger type, bits 1:0 of a LUT entry (DLPU010G Table 2-69)."""

    INTERNAL = 0
    EXTERNAL_POSITIVE = 1   # also the VSYNC trigger in trigger mode 0 (TI Table 4-2 step 6)
    EXTERNAL_NEGATIVE = 2
    NONE = 3                # continue from the previous pattern


class Mailbox(enum.IntEnum):
    """Pattern Display LUT Access Control, 0x1A33 (DLPU010G §2.4.3.4.8, Table 2-67)."""

    CLOSED = 0
    IMAGE_INDEX = 1
    PATTERN = 2   # TI's Table 4-1 example writes 1 here; Table 2-67 and Table 4-2 say 2.


LED_WHITE = 0b111  # LED select, bits 14:12 of a LUT entry: b0 red, b1 green, b2 blue
LUT_ENTRY_BYTES = 3
MAX_LUT_ENTRIES = 128
PATTERNS_PER_FRAME = 24   # 1-bit patterns in one 24-bit frame


@dataclass(frozen=True)
class LutEntry:
    """One pattern of the sequence, 3 bytes in the pattern mailbox (DLPU010G Table 2-69).

    Word layout (24 bits, LSB first): bits 1:0 trigger type, 7:2 pattern number (bit-plane,
    see :mod:`rig_drivers.dlpc350.bitplanes`), 11:8 bit depth (1..8), 14:12 LED select,
    16 invert, 17 insert black, 18 buffer swap, 19 TRIG_OUT_1 continues from previous.
    """

    pattern_number: int
    trigger: LutTrigger = LutTrigger.NONE
    bit_depth: int = 1
    led: int = LED_WHITE
    invert: bool = False
    insert_black: bool = False
    buffer_swap: bool = False
    trig_out_prev: bool = False

    def __post_init__(self):
        check_int("pattern_number", self.pattern_number, 0, 0x3F)
        check_int("bit_depth", self.bit_depth, 1, 8)
        check_int("led", self.led, 0, 7)
        if self.insert_black and self.trig_out_prev:
            raise SettingError("`insert_black` and `trig_out_prev` cannot both be set (DLPU010G Table 2-69)")

    def encode(self) -> bytes:
        """The 3 mailbox bytes."""
        word = (int(self.trigger) & 3) | (self.pattern_number << 2) | (self.bit_depth << 8) \
            | (self.led << 12) | (self.invert << 16) | (self.insert_black << 17) \
            | (self.buffer_swap << 18) | (self.trig_out_prev << 19)
        return word.to_bytes(3, "little")

    @classmethod
    def decode(cls, data: bytes) -> LutEntry:
        """Inverse of :meth:`encode`."""
        word = int.from_bytes(bytes(data[:3]), "little")
        return cls(pattern_number=(word >> 2) & 0x3F, trigger=LutTrigger(word & 3),
                   bit_depth=(word >> 8) & 0xF or 1, led=(word >> 12) & 7,
                   invert=bool(word >> 16 & 1), insert_black=bool(word >> 17 & 1),
                   buffer_swap=bool(word >> 18 & 1), trig_out_prev=bool(word >> 19 & 1))


def encode_lut_control(entries: int, repeat: bool, patterns_per_trig_out2: int, images: int) -> bytes:
    """0x1A31 payload (DLPU010G §2.4.3.4.5, Table 2-65).

    Byte 0: LUT entries − 1 (1..128); byte 1 bit 0: 1 = repeat, 0 = play once; byte 2:
    patterns per TRIG_OUT_2 − 1 (1..256); byte 3: image-index entries − 1 (1..64, used
    only with the flash source). All three counts go out as n − 1 ("0 means 1"), as in
    TI's ``DLPC350_SetPatternConfig``; some public drivers send the image count as n.
    """
    entries = check_int("entries", entries, 1, MAX_LUT_ENTRIES)
    every = check_int("patterns_per_trig_out2", patterns_per_trig_out2, 1, 256)
    images = check_int("images", images, 1, 64)
    return bytes([entries - 1, 1 if repeat else 0, every - 1, images - 1])


def check_exposure_period(exposure_us, period_us) -> tuple[int, int]:
    """The 0x1A29 rule, checked before anything is sent (DLPU010G §2.4.3.4.3).

    Exposure equals the period, or is at most period − 230 µs; both fit a uint32.
    """
    period = check_int("period_us", period_us, 1, 0xFFFFFFFF, "µs")
    exposure = check_int("exposure_us", exposure_us, 1, 0xFFFFFFFF, "µs")
    if exposure != period and exposure > period - MIN_DARK_US:
        raise SettingError(
            f"`exposure_us` must equal `period_us` or be at most period - {MIN_DARK_US} µs "
            f"(DLPC350 rule); got exposure {exposure} µs with period {period} µs")
    return exposure, period


def encode_exposure_period(exposure_us: int, period_us: int) -> bytes:
    """0x1A29 payload: exposure then period, two uint32 LE (DLPU010G Table 2-63)."""
    exposure, period = check_exposure_period(exposure_us, period_us)
    return struct.pack("<II", exposure, period)


TRIG_DELAY_STEP_NS = 107.2
"""TRIG_OUT delay step (DLPU010G Tables 2-54/2-55; TI API ``DLPC350_SetTrigOutConfig``)."""
TRIG_DELAY_ZERO = 0xBB
"""Delay code for 0 µs: codes are offset, 0x00 = −20.05 µs (DLPU010G Tables 2-54/2-55)."""
TRIG_DELAY_MAX = 0xD5
"""The largest TRIG_OUT delay code, +2.787 µs (TI API ``DLPC350_SetTrigOutConfig``: "0xD5 =
+2.787 μs"). Codes up to 0xFF belong to the LED strobe delays (0x1A1F..21), not to TRIG_OUT."""


def trig_out_delay_code(delay_us: float) -> int:
    """Delay in µs → the one-byte TRIG_OUT code (107.2 ns steps, 0xBB = 0 µs).

    The code is an offset count, not microseconds: ``code = 0xBB + round(delay / 107.2 ns)``,
    range −20.05 µs (0x00) to +2.787 µs (0xD5).
    """
    if not isinstance(delay_us, (int, float)) or isinstance(delay_us, bool):
        raise SettingError(f"`delay_us` must be a number of µs; got {delay_us!r}")
    code = TRIG_DELAY_ZERO + round(delay_us * 1000.0 / TRIG_DELAY_STEP_NS)
    if not 0 <= code <= TRIG_DELAY_MAX:
        low = -TRIG_DELAY_ZERO * TRIG_DELAY_STEP_NS / 1000
        high = (TRIG_DELAY_MAX - TRIG_DELAY_ZERO) * TRIG_DELAY_STEP_NS / 1000
        raise SettingError(f"a TRIG_OUT delay must be between {low:.2f} and +{high:.3f} µs (codes 0x00..0xD5, TI "
                           f"API DLPC350_SetTrigOutConfig); got {delay_us} µs")
    return code


TRIG_OUT_INVERT = 0x01
"""TRIG_OUT polarity: payload byte 0 is the invert flag itself, 1 = active low (TI API
``DLPC350_SetTrigOutConfig`` and the older ``LCR_SetTrigOutConfig`` write the flag as the whole
byte, i.e. bit 0). DLPU010G Tables 2-54/2-55 draw it in bit 1, and pyCrafter4500 follows the
table; the TI API settles it (module docstring)."""


def encode_trig_out(number: int, *, invert: bool = False, rising_us: float = 0.0,
                    falling_us: float = 0.0) -> tuple[int, bytes]:
    """TRIG_OUT_1 (0x1A1D, 3 bytes) or TRIG_OUT_2 (0x1A1E, 2 bytes) command and payload.

    Byte 0 = invert flag (:data:`TRIG_OUT_INVERT`, bit 0); byte 1 rising-edge delay code;
    byte 2 (TRIG_OUT_1 only) falling-edge delay code.
    """
    polarity = TRIG_OUT_INVERT if invert else 0
    if number == 1:
        return Command.TRIG_OUT1, bytes([polarity, trig_out_delay_code(rising_us),
                                         trig_out_delay_code(falling_us)])
    if number == 2:
        return Command.TRIG_OUT2, bytes([polarity, trig_out_delay_code(rising_us)])
    raise SettingError(f"`number` must be 1 (TRIG_OUT_1) or 2 (TRIG_OUT_2); got {number!r}")


# --------------------------------------------------------------------------- LEDs, source, power


def encode_led_currents(red: int, green: int, blue: int) -> bytes:
    """0x0B01 payload: the red, green and blue LED PWM values, 0..255 each (0xFF = the most
    current the LED driver gives), TI API ``DLPC350_SetLedCurrents``."""
    return bytes(check_int(name, v, 0, 255) for name, v in (("red", red), ("green", green), ("blue", blue)))


LED_SEQUENCER = 0x08
"""0x1A07 bit 3: the pattern sequence drives the LEDs (each LUT entry's LED select), and the
red/green/blue enable bits are ignored (TI API ``DLPC350_SetLedEnables``)."""


def encode_led_enables(*, automatic: bool, red: bool = True, green: bool = True, blue: bool = True) -> bytes:
    """0x1A07 payload: bit 0 red, bit 1 green, bit 2 blue, bit 3 the sequencer controls them."""
    return bytes([(LED_SEQUENCER if automatic else 0) | (1 if red else 0) | (2 if green else 0)
                  | (4 if blue else 0)])


def decode_led_enables(byte: int) -> dict[str, bool]:
    """Inverse of :func:`encode_led_enables`."""
    return {"automatic": bool(byte & LED_SEQUENCER), "red": bool(byte & 1), "green": bool(byte & 2),
            "blue": bool(byte & 4)}


class InputSource(enum.IntEnum):
    """Input Source Selection, 0x1A00 bits 2:0 (TI API ``DLPC350_SetInputSource``). The
    LightCrafter 4500's HDMI receiver feeds the parallel port."""

    PARALLEL = 0       # the parallel port (HDMI on the LightCrafter 4500)
    TEST_PATTERN = 1   # the internal test pattern generator
    FLASH = 2          # still images from flash
    FPD_LINK = 3


PORT_WIDTHS = {30: 0, 24: 1, 20: 2, 16: 3, 10: 4, 8: 5}
"""Parallel port bit depth → 0x1A00 bits 5:3 (TI API ``DLPC350_SetInputSource``)."""


def encode_input_source(source: InputSource, port_width: int = 24) -> bytes:
    """0x1A00 payload: the source in bits 2:0, the parallel port width code in bits 5:3."""
    try:
        source = InputSource(source)
    except ValueError:
        raise SettingError(f"`source` must be one of {', '.join(s.name.lower() for s in InputSource)}; "
                           f"got {source!r}") from None
    if port_width not in PORT_WIDTHS:
        raise SettingError(f"`port_width` must be one of {', '.join(map(str, PORT_WIDTHS))} bits; got {port_width!r}")
    return bytes([int(source) | PORT_WIDTHS[port_width] << 3])


def decode_input_source(byte: int) -> tuple[InputSource, int]:
    """Inverse of :func:`encode_input_source`: (source, port width in bits)."""
    widths = {code: bits for bits, code in PORT_WIDTHS.items()}
    try:
        source = InputSource(byte & 0b111)
    except ValueError:
        raise ProtocolError(f"the projector reports an unknown input source {byte & 0b111}") from None
    return source, widths.get(byte >> 3 & 0b111, 0)


TRIG_IN1_STEP_NS = 107.136
"""TRIG_IN_1 delay step (DLPU010G Table 2-56); 19 bits of counts, no offset."""


def encode_trig_in1_delay(delay_us: float) -> bytes:
    """0x1A35 payload: TRIG_IN_1 rising-edge delay, uint32 LE of 107.136 ns counts (bits 18:0)."""
    if not isinstance(delay_us, (int, float)) or isinstance(delay_us, bool):
        raise SettingError(f"`delay_us` must be a number of µs; got {delay_us!r}")
    counts = round(delay_us * 1000.0 / TRIG_IN1_STEP_NS)
    if not 0 <= counts < 1 << 19:
        raise SettingError(f"`delay_us` must be between 0 and {((1 << 19) - 1) * TRIG_IN1_STEP_NS / 1000:.0f} "
                           f"µs; got {delay_us}")
    return struct.pack("<I", counts)


# --------------------------------------------------------------------------- status words

HW_STATUS_BITS = {  # DLPU010G §2.1.1
    0: ("internal initialisation FAILED", "internal initialisation successful"),
    1: (None, "incompatible controller or DMD"),
    2: (None, "DMD reset controller error (overlapping bias/reset operations)"),
    3: (None, "forced swap error (pattern timing does not match the video VSYNC)"),
    6: (None, "sequencer abort"),
    7: (None, "sequencer error"),
}
SYS_STATUS_BITS = {0: ("internal memory test FAILED", "internal memory test passed")}  # §2.1.2
MAIN_STATUS_BITS = {  # DLPU010G §2.1.3, Table 2-3
    0: ("DMD micromirrors not parked", "DMD micromirrors parked"),
    1: ("sequencer stopped", "sequencer running"),
    2: ("video not frozen", "video frozen"),
    3: ("gamma correction disabled", "gamma correction enabled"),
}
VALIDATE_BITS = {  # DLPU010G §2.4.3.1, Table 2-52
    0: "bad timing: exposure or frame period settings are invalid",
    1: "bad pattern number: pattern numbers in the LUT are invalid",
    2: "warning: continuous TRIG_OUT_1 request or overlapping black sectors",
    3: "warning: post vector not inserted before an externally triggered vector",
    4: "warning: frame period minus exposure is less than 230 µs",
}
VALIDATE_BUSY = 0x80
VALIDATE_FAILURE_MASK = 0b00011  # bits 0 and 1 are errors; 2..4 are warnings


def decode_bits(byte: int, table: dict) -> list[str]:
    """Words for a status byte: for each bit in ``table`` the (clear, set) text that applies."""
    words = []
    for bit, (clear, set_) in table.items():
        text = set_ if byte >> bit & 1 else clear
        if text:
            words.append(text)
    return words


HW_ERROR_BITS = 0b11001110
"""Hardware-status bits that are errors (the rest: bit 0 = initialisation succeeded)."""


def hw_status_ok(byte: int) -> bool:
    """True when initialisation succeeded and no error bit is set."""
    return bool(byte & 1) and not byte & HW_ERROR_BITS


@dataclass(frozen=True)
class Status:
    """The three DLPC350 status bytes, decoded."""

    hardware: int
    system: int
    main: int

    @property
    def ok(self) -> bool:
        """No hardware error and the memory test passed."""
        return hw_status_ok(self.hardware) and bool(self.system & 1)

    @property
    def sequencer_running(self) -> bool:
        """Main status bit 1."""
        return bool(self.main & 0b10)

    def errors(self) -> list[str]:
        """The error bits only, in words (empty when none is set)."""
        errors = [] if self.hardware & 1 else [HW_STATUS_BITS[0][0]]
        errors += [HW_STATUS_BITS[b][1] for b in sorted(HW_STATUS_BITS) if b and self.hardware >> b & 1]
        if not self.system & 1:
            errors.append(SYS_STATUS_BITS[0][0])
        return errors

    def words(self) -> list[str]:
        """Every status bit in words."""
        return (decode_bits(self.hardware, HW_STATUS_BITS) + decode_bits(self.system, SYS_STATUS_BITS)
                + decode_bits(self.main, MAIN_STATUS_BITS))


@dataclass(frozen=True)
class ValidationResult:
    """The Validate Data status byte (0x1A1A), decoded."""

    byte: int

    @property
    def ok(self) -> bool:
        """No failure bit (warnings allowed)."""
        return not self.byte & VALIDATE_FAILURE_MASK

    @property
    def problems(self) -> list[str]:
        """Failures and warnings in words."""
        return [text for bit, text in VALIDATE_BITS.items() if self.byte >> bit & 1]


def decode_version(data: bytes) -> dict[str, str]:
    """0x0205 reply: four uint32 LE, bits 31:24 major, 23:16 minor, 15:0 patch."""
    if len(data) < 16:
        raise ProtocolError(f"malformed reply to {command_name(Command.GET_VERSION)}: "
                            f"{len(data)} data bytes, expected 16")
    names = ("application", "api", "software_config", "sequencer_config")
    out = {}
    for name, word in zip(names, struct.unpack_from("<4I", data), strict=True):
        out[name] = f"{word >> 24}.{word >> 16 & 0xFF}.{word & 0xFFFF}"
    return out
