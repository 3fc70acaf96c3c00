"""The DLP LightCrafter 4500 (DLPC350) as a :class:`~rig_drivers.interfaces.Projector`.

Patterns reach the projector as bit-planes of 24-bit frames on its video port; this driver
programs the pattern sequence over USB: which bit-plane shows when, for how long, what
triggers each group of patterns, and how often TRIG_OUT_2 pulses (once per camera frame).

The video port itself is not USB: something must put :meth:`DLPC350.frames_for` full-screen
on the screen that feeds the projector's HDMI input. That something is the **display sink**,
a plain callable injected through the constructor (or :attr:`DLPC350.display`)::

    display(frames)   # frames: (N, H, W, 3) uint8, N = ceil(K / 24), in sequence order

The driver calls it from :meth:`~rig_drivers.interfaces.Projector.load_sequence`, after the
controller has validated the sequence and before ``load_sequence`` returns, so a caller that
loads, starts and then waits for a camera frame taken after the change (the calibration
session's rule) sees the new patterns. The sink must return only once the frames are on the
screen, and within a bounded time (the app's Qt adapter, :mod:`flexvox_app.gui.projector.display`, waits
at most its ``timeout_s`` and raises otherwise); anything it raises becomes a
:class:`ProjectorDisplayError`. No Qt here: the sink is the app's business. Nothing is blanked
on stop (a stopped pattern sequence does not show the video input, and the next load replaces
the frames); without a sink (``display=None``) the frames must be shown some other way, as
before (the Capture workspace's projector output window).

Command order of a session (DLPU010G §4.2 Table 4-2; docs/real-rig.md)::

    0x1A24 = 0 (stop)  0x1A1B = 1 (pattern mode)  0x1A22 (source)  0x1A31 (LUT control)
    0x1A23 (trigger mode)  0x1A29 (exposure, period)  0x1A33 = 2, 0x1A32, 0x1A34..., 0x1A33 = 0
    0x1A1A (validate; poll until bit 7 clears)  0x1A24 = 2 (start) ... 0x1A24 = 0 (stop)
"""

from __future__ import annotations

import logging
import time

import numpy as np

from rig_drivers.dlpc350 import protocol as p
from rig_drivers.dlpc350.bitplanes import PLANES_PER_FRAME, pack_bitplanes
from rig_drivers.dlpc350.transport import Transport, receive_reply, send_message
from rig_drivers.errors import (
    DeviceError,
    DeviceTimeoutError,
    IncompatibleStateError,
    ProtocolError,
    SettingError,
)
from rig_drivers.interfaces import (
    DeviceState,
    Display,
    PatternSequence,
    Projector,
    ProjectorTrigger,
    RunState,
    check_positive_float,
    check_timeout,
)
from rig_drivers.pixel_layout import check_layout

_logger = logging.getLogger(__name__)

class ProjectorDisplayError(DeviceError):
    """The display sink could not put the pattern frames on the projector's video input."""


def check_display(display) -> Display | None:
    """Validate a display sink (a callable or None)."""
    if display is not None and not callable(display):
        raise SettingError(f"`display` must be a callable taking the (N, H, W, 3) uint8 frames, or None; "
                           f"got {type(display).__name__}")
    return display


DMD_SIZE = (1140, 912)
"""The LightCrafter 4500's DMD as its video input addresses it: 1140 rows × 912 columns."""


class DLPC350(Projector):
    """TI DLP LightCrafter 4500 over a :class:`~rig_drivers.dlpc350.transport.Transport`.

    Parameters
    ----------
    transport : Transport
        Moves 64-byte reports: :class:`~rig_drivers.dlpc350.transport.PyUsbHidTransport`
        for the real projector, :class:`~rig_drivers.dlpc350.fake.FakeDLPC350Transport` in tests.
    vsync_hz : float
        Refresh rate of the video signal feeding the projector (default 60 Hz). Each group
        of ``patterns_per_trigger`` patterns must fit in one VSYNC period.
    reply_timeout_s : float
        How long to wait for each reply.
    validate_timeout_s : float
        How long to poll the validation busy bit before giving up.
    poll_interval_s : float
        Pause between validation polls (0 in tests).
    display : callable, optional
        The display sink ``display(frames)`` (module docstring): called with
        :meth:`frames_for` of every sequence loaded, after validation. None: nothing is shown
        by the driver.
    led_currents : (red, green, blue), optional
        LED PWM values 0..255 set whenever the projector is enabled (a rig profile's
        ``led_current``); None leaves the projector's own.
    pixel_layout : "square" or "diamond"
        How the DMD's pixels sit, for the shutter patterns and the calibration (a profile's
        ``pixel_layout``); the LightCrafter 4500's is "diamond".
    led_enable : "sequence" or sequence of colours, optional
        Set whenever the projector is enabled: "sequence" lets the pattern sequence drive the
        LEDs; a list of colours keeps those on (a profile's ``led_enable``). None leaves them.
    """

    def __init__(self, transport: Transport, *, vsync_hz: float = 60.0, reply_timeout_s: float = 1.0,
                 validate_timeout_s: float = 2.0, poll_interval_s: float = 0.01, name: str | None = None,
                 display: Display | None = None, led_currents=None, led_enable=None, pixel_layout: str = "square"):
        super().__init__(name=name or "DLP LightCrafter 4500")
        for method in ("open", "close", "write", "read"):
            if not callable(getattr(transport, method, None)):
                raise SettingError(f"`transport` must have open/close/write/read methods; "
                                   f"{type(transport).__name__} has no {method}()")
        self._transport = transport
        self.vsync_hz = check_positive_float("vsync_hz", vsync_hz, 1000.0, "Hz")
        self._reply_timeout_s = check_timeout(reply_timeout_s)
        self._validate_timeout_s = check_timeout(validate_timeout_s)
        if not isinstance(poll_interval_s, (int, float)) or not 0 <= poll_interval_s <= 1:
            raise SettingError(f"`poll_interval_s` must be between 0 and 1 s; got {poll_interval_s!r}")
        self._poll_interval_s = float(poll_interval_s)
        self._seq = 0
        self._needs_reload = False
        self._display = check_display(display)
        if led_currents is not None:
            p.encode_led_currents(*led_currents)  # checked now, not at enable
        if led_enable is not None and led_enable != "sequence" and (
                not led_enable or not set(led_enable) <= {"red", "green", "blue"}):
            raise SettingError(f"`led_enable` must be \"sequence\" or colours among red, green, blue; "
                               f"got {led_enable!r}")
        self.led_settings = (None if led_currents is None else tuple(led_currents), led_enable)
        self.pixel_layout = check_layout(pixel_layout)
        """How the DMD's pixels sit, as the rig profile declares (:mod:`rig_drivers.pixel_layout`): the
        DLP4500 staggers every other row by half a pixel ("diamond")."""
        """What :meth:`enable` sets: (LED currents or None, LED enable or None)."""

    size = DMD_SIZE
    """Pattern size (rows, columns), as every projector driver reports it."""
    video_port = True
    """Patterns arrive on the video input, sequences from :meth:`video_sequence`."""

    @property
    def led_control(self) -> DLPC350:
        """Itself: it sets its LED currents (:class:`~rig_drivers.interfaces.LedControl`)."""
        return self

    @property
    def configured_led_currents(self) -> tuple[int, int, int] | None:
        """The LED PWM values :meth:`enable` sets (the profile's ``led_current``), or None."""
        return self.led_settings[0]

    @property
    def display_input(self) -> DLPC350:
        """Itself: its video input takes a display sink (:attr:`display`,
        :class:`~rig_drivers.interfaces.DisplayInput`)."""
        return self

    @property
    def display(self) -> Display | None:
        """The display sink (None: none); settable, e.g. once the app's projector window exists."""
        return self._display

    @display.setter
    def display(self, display: Display | None) -> None:
        self._display = check_display(display)

    # ------------------------------------------------------------------ lifecycle hooks
    def _do_open(self) -> None:
        self._seq = 0
        self._transport.open()

    def _do_close(self) -> None:
        self._transport.close()

    def _do_enable(self) -> None:
        self.set_standby(False)
        currents, enable = self.led_settings
        if currents is not None:
            self.set_led_currents(*currents)
        if enable is not None:
            if enable == "sequence":
                self.set_led_enables(automatic=True)
            else:
                self.set_led_enables(automatic=False, **{c: c in enable for c in ("red", "green", "blue")})

    def summary(self) -> dict:
        """What an operator checks at the rig: firmware, power, input source, LEDs and errors (reads only)."""
        source, width = self.input_source()
        return {"firmware": self.version()["application"], "power": self.power_mode(),
                "input_source": source.name.lower().replace("_", " ") + (f" ({width} bit)" if source == 0 else ""),
                "led_current": dict(zip(("red", "green", "blue"), self.led_currents(), strict=True)),
                "led_enable": self.led_enables(), "errors": self.errors()}

    def _do_disable(self) -> None:
        try:
            super()._do_disable()  # stop the sequence
        finally:
            self.set_standby(True)

    # ------------------------------------------------------------------ transactions
    def _transact(self, command: int, payload: bytes = b"", *, read: bool = False) -> bytes:
        # TI API DLPC350_PrepWriteCmd / PrepReadCmd: writes count up, reads carry 0.
        seq = 0 if read else self._seq
        if not read:
            self._seq = (self._seq + 1) & 0xFF
        send_message(self._transport, command, payload, read=read, seq=seq)
        try:
            reply = receive_reply(self._transport, self._reply_timeout_s)
        except DeviceTimeoutError as exc:
            raise DeviceTimeoutError(
                f"no reply to {p.command_name(command)} within {self._reply_timeout_s:g} s: check the "
                f"USB cable, close TI's LightCrafter GUI, and power-cycle the projector if it "
                f"stays silent") from exc
        except ProtocolError as exc:
            raise ProtocolError(f"malformed reply to {p.command_name(command)}: {exc}") from None
        return p.parse_reply(reply, command=command, seq=seq)

    def write_command(self, command: int, payload: bytes) -> None:
        """Send one write command and check its acknowledgement (raises on NAK)."""
        self._require(f"send {p.command_name(command)}", DeviceState.OPEN, DeviceState.ENABLED)
        self._transact(command, payload)

    def read_command(self, command: int) -> bytes:
        """Send one read command and return the reply's data bytes."""
        self._require(f"read {p.command_name(command)}", DeviceState.OPEN, DeviceState.ENABLED)
        return self._transact(command, read=True)

    def _read_byte(self, command: int) -> int:
        data = self.read_command(command)
        if not data:
            raise ProtocolError(f"malformed reply to {p.command_name(command)}: no data bytes")
        return data[0]

    # ------------------------------------------------------------------ queries
    def version(self) -> dict[str, str]:
        """Firmware component versions ("major.minor.patch"), DLPU010G §2.1.4."""
        return p.decode_version(self.read_command(p.Command.GET_VERSION))

    def status(self) -> p.Status:
        """Hardware, system and main status bytes, decoded (``.words()``), DLPU010G §2.1."""
        return p.Status(self._read_byte(p.Command.HW_STATUS), self._read_byte(p.Command.SYS_STATUS),
                        self._read_byte(p.Command.MAIN_STATUS))

    # ------------------------------------------------------------------ simple settings
    def set_standby(self, standby: bool) -> None:
        """Standby (True: DMD interface powered down) or normal operation, 0x0200."""
        self.write_command(p.Command.POWER_CONTROL, bytes([1 if standby else 0]))

    def power_mode(self) -> str:
        """"standby" or "normal" (0x0200 read back)."""
        return "standby" if self._read_byte(p.Command.POWER_CONTROL) & 0x03 else "normal"  # TI GetPowerMode: bits 1:0

    def errors(self) -> list[str]:
        """The controller's error bits in words (hardware and system status); empty when none."""
        return self.status().errors()

    def set_led_currents(self, red: int, green: int, blue: int) -> None:
        """LED currents as PWM values 0..255 (0xFF: the most the LED driver gives), 0x0B01.

        They set how much light each open slot gets, and so the capture's signal-to-noise.
        """
        self.write_command(p.Command.LED_CURRENT, p.encode_led_currents(red, green, blue))

    def led_currents(self) -> tuple[int, int, int]:
        """(red, green, blue) PWM values read back."""
        data = self.read_command(p.Command.LED_CURRENT)
        if len(data) < 3:
            raise ProtocolError(f"malformed reply to {p.command_name(p.Command.LED_CURRENT)}: {len(data)} bytes")
        return data[0], data[1], data[2]

    def set_led_enables(self, *, automatic: bool = True, red: bool = True, green: bool = True,
                        blue: bool = True) -> None:
        """Which LEDs light (0x1A07). ``automatic``: the pattern sequence drives them (each LUT
        entry's LED select; the flags are then ignored), as a pattern-mode capture needs."""
        self.write_command(p.Command.LED_ENABLE, p.encode_led_enables(automatic=automatic, red=red, green=green,
                                                                      blue=blue))

    def led_enables(self) -> dict[str, bool]:
        """``automatic``, ``red``, ``green``, ``blue`` read back."""
        return p.decode_led_enables(self._read_byte(p.Command.LED_ENABLE))

    def set_input_source(self, source: p.InputSource, port_width: int = 24) -> None:
        """Video-mode input (0x1A00): the parallel port (the HDMI receiver, 24 bits), the test
        pattern generator, flash or FPD-link. Stop the sequence first."""
        payload = p.encode_input_source(source, port_width)
        self._require_stopped("select the input source")
        self.write_command(p.Command.SOURCE_SELECT, payload)

    def input_source(self) -> tuple[p.InputSource, int]:
        """(source, parallel port width in bits) read back."""
        return p.decode_input_source(self._read_byte(p.Command.SOURCE_SELECT))

    def set_display_mode(self, pattern: bool) -> None:
        """Pattern display mode (True) or video mode (False), 0x1A1B."""
        self.write_command(p.Command.DISPLAY_MODE, bytes([1 if pattern else 0]))

    def set_exposure_period(self, exposure_us: int, period_us: int) -> None:
        """0x1A29, after checking the 230 µs rule (nothing is sent when it fails)."""
        self.write_command(p.Command.EXPOSURE_PERIOD, p.encode_exposure_period(exposure_us, period_us))

    def configure_trigger_output(self, number: int, *, invert: bool = False, rising_us: float = 0.0,
                                 falling_us: float = 0.0) -> None:
        """Polarity and edge delays of TRIG_OUT_1 or TRIG_OUT_2 (stop the sequence first).

        Delays in µs relative to the pattern on the DMD, −20.05 .. +2.787 µs in 107.2 ns steps
        (codes 0x00..0xD5); invert = active low, sent in bit 0 as TI's API does.
        """
        command, payload = p.encode_trig_out(number, invert=invert, rising_us=rising_us,
                                             falling_us=falling_us)
        self._require_stopped("configure a trigger output")
        self.write_command(command, payload)
        self._needs_reload = True

    def configure_trigger_input(self, *, delay_us: float = 0.0) -> None:
        """TRIG_IN_1 rising-edge delay in µs (107.136 ns steps), 0x1A35."""
        payload = p.encode_trig_in1_delay(delay_us)
        self._require_stopped("configure the trigger input")
        self.write_command(p.Command.TRIG_IN1, payload)
        self._needs_reload = True

    def _require_stopped(self, action: str) -> None:
        self._require(action, DeviceState.OPEN, DeviceState.ENABLED)
        if self._run_state is not RunState.STOPPED:
            raise IncompatibleStateError(
                f"cannot {action} while the sequence is {self._run_state.value}: stop it first")

    # ------------------------------------------------------------------ pattern sequence
    def lut_entries_for(self, sequence: PatternSequence) -> list[p.LutEntry]:
        """The pattern LUT for ``sequence`` (video-port source, trigger mode 0).

        Entry k shows bit-plane ``k % 24`` (DLPU010G Table 2-70) for one 1-bit exposure, white
        LEDs. Every ``patterns_per_trigger``-th entry waits for VSYNC (trigger type "external
        positive") and swaps the frame buffer (DLPU010G Table 4-2 step 6); the rest continue.

        Raises
        ------
        SettingError
            When the sequence cannot run from the video port (see the message).
        """
        self.check_sequence(sequence)
        ppt = sequence.patterns_per_trigger
        entries = []
        for k in range(sequence.K):
            starts_group = k % ppt == 0
            entries.append(p.LutEntry(
                pattern_number=k % PLANES_PER_FRAME,
                trigger=p.LutTrigger.EXTERNAL_POSITIVE if starts_group else p.LutTrigger.NONE,
                bit_depth=1, led=p.LED_WHITE, buffer_swap=starts_group))
        return entries

    def check_sequence(self, sequence: PatternSequence) -> None:
        """Raise :class:`SettingError` when this projector cannot show ``sequence``."""
        if sequence.trigger is not ProjectorTrigger.VSYNC:
            raise SettingError(
                f"`trigger` must be VSYNC for the LightCrafter 4500: patterns arrive on the video "
                f"port, which runs in trigger mode 0 (DLPU010G Table 2-53); got {sequence.trigger.value}")
        if sequence.exposure_us != sequence.period_us:
            raise SettingError(
                f"`exposure_us` must equal `period_us` with video-port patterns (DLPU010G Table 2-63 "
                f"note); got exposure {sequence.exposure_us} µs, period {sequence.period_us} µs")
        ppt = sequence.patterns_per_trigger
        vsync_us = 1e6 / self.vsync_hz
        if ppt * sequence.period_us > vsync_us:
            fit = max(1, int(vsync_us // sequence.period_us))
            raise SettingError(
                f"`patterns_per_trigger` x `period_us` must fit one VSYNC period of {vsync_us:.0f} µs "
                f"at {self.vsync_hz:g} Hz; got {ppt} x {sequence.period_us} µs = "
                f"{ppt * sequence.period_us} µs (at most {fit} patterns per VSYNC)")
        if ppt > PLANES_PER_FRAME or (sequence.K > PLANES_PER_FRAME and PLANES_PER_FRAME % ppt):
            raise SettingError(
                f"`patterns_per_trigger` must divide 24 when K > 24 (each VSYNC frame holds 24 "
                f"bit-planes); got {ppt} with K = {sequence.K}")

    def frames_for(self, sequence: PatternSequence) -> np.ndarray:
        """The ``(F, H, W, 3)`` uint8 frames to show on the video port for ``sequence``.

        With K <= 24 one static frame serves every VSYNC; with K > 24 the app shows frame
        ``g * ppt // 24`` during trigger group g.
        """
        return pack_bitplanes(sequence.patterns)

    def configure_sequence(self, sequence: PatternSequence) -> None:
        """Send the pattern-mode set-up for ``sequence`` (no validation, no start).

        Everything is checked before the first packet goes out.
        """
        if not isinstance(sequence, PatternSequence):
            raise SettingError(f"`sequence` must be a PatternSequence; got {type(sequence).__name__}")
        entries = self.lut_entries_for(sequence)
        lut_control = p.encode_lut_control(sequence.K, sequence.repeat, sequence.trigger_out_every,
                                           -(-sequence.K // PLANES_PER_FRAME))
        exposure_period = p.encode_exposure_period(sequence.exposure_us, sequence.period_us)
        self._require("configure a pattern sequence", DeviceState.OPEN, DeviceState.ENABLED)

        self.write_command(p.Command.START_STOP, bytes([0]))
        self._run_state = RunState.STOPPED
        self.set_display_mode(True)
        self.write_command(p.Command.PATTERN_SOURCE, bytes([p.PatternSource.VIDEO_PORT]))
        self.write_command(p.Command.LUT_CONTROL, lut_control)
        self.write_command(p.Command.TRIGGER_MODE, bytes([p.TriggerMode.VSYNC]))
        self.write_command(p.Command.EXPOSURE_PERIOD, exposure_period)
        self.write_pattern_lut(entries)
        self._needs_reload = True

    def write_pattern_lut(self, entries: list[p.LutEntry]) -> None:
        """Open the pattern mailbox, set offset 0, send every entry in one 0x1A34 message (it
        continues over several reports when K > 19), close the mailbox: TI API ``DLPC350_SendPatLut``."""
        if not 1 <= len(entries) <= p.MAX_LUT_ENTRIES:
            raise SettingError(f"`entries` must hold 1..{p.MAX_LUT_ENTRIES} LUT entries; got {len(entries)}")
        self.write_command(p.Command.MAILBOX_CONTROL, bytes([p.Mailbox.PATTERN]))
        try:
            self.write_command(p.Command.MAILBOX_OFFSET, bytes([0]))
            self.write_command(p.Command.MAILBOX_DATA, b"".join(e.encode() for e in entries))
        finally:
            self.write_command(p.Command.MAILBOX_CONTROL, bytes([p.Mailbox.CLOSED]))

    def read_pattern_lut(self, entries: int) -> list[p.LutEntry]:
        """Read ``entries`` pattern LUT entries back (mailbox open, offset 0, one long read, close;
        TI API ``DLPC350_GetPatLut``)."""
        if not 1 <= entries <= p.MAX_LUT_ENTRIES:
            raise SettingError(f"`entries` must be 1..{p.MAX_LUT_ENTRIES}; got {entries!r}")
        self.write_command(p.Command.MAILBOX_CONTROL, bytes([p.Mailbox.PATTERN]))
        try:
            self.write_command(p.Command.MAILBOX_OFFSET, bytes([0]))
            data = self.read_command(p.Command.MAILBOX_DATA)
        finally:
            self.write_command(p.Command.MAILBOX_CONTROL, bytes([p.Mailbox.CLOSED]))
        if len(data) < 3 * entries:
            raise ProtocolError(f"the projector returned {len(data) // 3} LUT entries, expected {entries}")
        return [p.LutEntry.decode(data[3 * i:3 * i + 3]) for i in range(entries)]

    def validate(self, timeout_s: float | None = None) -> p.ValidationResult:
        """Ask the controller to validate the set-up; poll bit 7 (busy) until it clears.

        Polling is bounded by ``timeout_s`` (default: the constructor's) and by a maximum
        number of polls. Warnings (bits 2..4) are logged; failures raise.

        Raises
        ------
        ProtocolError
            When bit 0 (bad timing) or bit 1 (bad pattern number) is set; the message lists
            every problem in words.
        DeviceTimeoutError
            When the busy bit does not clear in time.
        """
        timeout_s = self._validate_timeout_s if timeout_s is None else check_timeout(timeout_s)
        self.write_command(p.Command.VALIDATE, bytes([0]))
        deadline = time.monotonic() + timeout_s
        max_polls = 1 + int(timeout_s / max(self._poll_interval_s, 1e-3))
        for _ in range(max_polls):
            byte = self._read_byte(p.Command.VALIDATE)
            if not byte & p.VALIDATE_BUSY:
                result = p.ValidationResult(byte)
                if not result.ok:
                    raise ProtocolError("the projector rejected the pattern sequence: "
                                        + "; ".join(result.problems))
                for warning in result.problems:
                    _logger.warning("DLPC350 validation: %s", warning)
                self._needs_reload = False
                return result
            if time.monotonic() > deadline:
                break
            if self._poll_interval_s:
                time.sleep(self._poll_interval_s)
        raise DeviceTimeoutError(
            f"the projector was still validating (busy bit set) after {timeout_s:g} s: "
            f"power-cycle it if this repeats")

    # ------------------------------------------------------------------ the video input
    def show_frames(self, frames: np.ndarray) -> None:
        """Hand ``frames`` ``(N, H, W, 3)`` uint8 to the display sink (no-op without one).

        Raises
        ------
        ProjectorDisplayError
            When the sink raises (its timeout included); the message names the cause.
        """
        display = self._display
        if display is None:
            return
        try:
            display(frames)
        except Exception as exc:  # the sink is the app's code: any failure becomes a device error
            n, h, w = frames.shape[:3]
            raise ProjectorDisplayError(
                f"could not show the {n} pattern frame(s) of {w}x{h} on the projector's video input: "
                f"{type(exc).__name__}: {exc}") from exc

    def video_sequence(self, patterns, period_us: int, *, repeat: bool = True) -> PatternSequence:
        """A sequence of ``patterns`` this projector runs from its video port.

        VSYNC-triggered, exposure = ``period_us``, with the largest ``patterns_per_trigger``
        that divides K and fits one VSYNC period (and divides 24 when K > 24); TRIG_OUT_2
        once per K patterns (once per camera exposure).

        Raises
        ------
        SettingError
            When not even one pattern fits a VSYNC period.
        """
        K = int(np.shape(patterns)[0]) if np.ndim(patterns) == 3 else 0
        vsync_us = 1e6 / self.vsync_hz
        fits = [n for n in range(1, K + 1)
                if K % n == 0 and n * int(period_us) <= vsync_us
                and (K <= PLANES_PER_FRAME or PLANES_PER_FRAME % n == 0)]
        if not fits:
            raise SettingError(f"`period_us` must fit one VSYNC period of {vsync_us:.0f} µs at "
                               f"{self.vsync_hz:g} Hz; got {period_us} µs with K = {K}")
        return PatternSequence(patterns, period_us, period_us, trigger=ProjectorTrigger.VSYNC,
                               patterns_per_trigger=max(fits), repeat=repeat)

    # ------------------------------------------------------------------ Projector hooks
    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        self.configure_sequence(sequence)
        self.validate()
        self.show_frames(self.frames_for(sequence))

    def _do_start(self) -> None:
        # After a stop the LUT must be sent again and validated before start (DLPU010G
        # Table 2-62 note); after a pause a plain start resumes.
        if self._needs_reload and self._run_state is RunState.STOPPED:
            self.configure_sequence(self._sequence)
            self.validate()
        self.write_command(p.Command.START_STOP, bytes([2]))

    def _do_pause(self) -> None:
        self.write_command(p.Command.START_STOP, bytes([1]))

    def _do_stop(self) -> None:
        self.write_command(p.Command.START_STOP, bytes([0]))
        self._needs_reload = True

