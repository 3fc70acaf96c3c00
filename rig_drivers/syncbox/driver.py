"""The sync box (a microcontroller trigger box on a serial port) as a
:class:`~rig_drivers.interfaces.SyncController`."""

from __future__ import annotations

import logging
from typing import Protocol, runtime_checkable

from rig_drivers.errors import (
    SERIAL_BUSY_HINT,
    SERIAL_PERMISSION_HINT,
    DeviceBusyError,
    DeviceError,
    DeviceNotFoundError,
    DevicePermissionError,
    DeviceTimeoutError,
    ProtocolError,
    SettingError,
)
from rig_drivers.interfaces import SyncController, SyncSettings, check_int, check_timeout
from rig_drivers.syncbox import protocol as sp

_logger = logging.getLogger(__name__)

BAUD_RATE = 115200


@runtime_checkable
class SerialLike(Protocol):
    """What the driver needs from a port: pyserial's ``write`` and ``readline``.

    ``readline`` must return within the port's timeout, with ``b""`` or a partial line
    (no ``\\n``) when nothing complete arrived, as pyserial does.
    """

    def write(self, data: bytes) -> int | None: ...

    def readline(self) -> bytes: ...


class SyncBox(SyncController):
    """Drives the flexvox sync box firmware (``rig_drivers/firmware/syncbox/syncbox.ino``).

    Parameters
    ----------
    port : SerialLike
        An open serial port (``serial.Serial``) or :class:`~rig_drivers.syncbox.fake.FakeSyncBoxSerial`.
        Use :meth:`from_port_name` to open a named port with typed errors.
    timeout_s : float
        Read timeout, applied to ports whose ``timeout`` is unset (never block forever).
    attempts : int
        How many times one command is sent when the reply is corrupt (bounded retry; every
        command of the protocol is idempotent).
    """

    def __init__(self, port: SerialLike, *, timeout_s: float = 0.5, attempts: int = 2,
                 name: str | None = None):
        super().__init__(name=name or "sync box")
        if not (callable(getattr(port, "write", None)) and callable(getattr(port, "readline", None))):
            raise SettingError(f"`port` must have write() and readline(); got {type(port).__name__}")
        self._port = port
        self._timeout_s = check_timeout(timeout_s)
        self._attempts = check_int("attempts", attempts, 1, 5)
        self._version: str | None = None

    @classmethod
    def from_port_name(cls, port_name: str, **kwargs) -> SyncBox:
        """Open ``port_name`` (e.g. ``/dev/ttyACM0``, ``COM3``) with pyserial at 115200 baud.

        Raises
        ------
        DeviceNotFoundError, DevicePermissionError, DeviceBusyError
            With what to do about it.
        """
        import serial

        timeout_s = kwargs.get("timeout_s", 0.5)
        try:
            port = serial.Serial(port_name, BAUD_RATE, timeout=timeout_s, exclusive=True)
        except serial.SerialException as exc:
            raise map_serial_error(exc, port_name) from exc
        return cls(port, **kwargs)

    # ------------------------------------------------------------------ transactions
    def command(self, body: str) -> sp.Reply:
        """Send one command line and return its ``OK`` reply.

        Raises
        ------
        DeviceTimeoutError
            When no complete line arrives within the timeout.
        ProtocolError
            On an ``ERR`` reply, or a corrupt reply on every attempt.
        """
        line = sp.frame(body)
        last: ProtocolError | None = None
        for attempt in range(1, self._attempts + 1):
            self._port.write(line)
            raw = self._port.readline()
            if not raw.endswith(b"\n"):
                raise DeviceTimeoutError(
                    f"the sync box did not answer {body!r} within {self._timeout_s:g} s "
                    f"(got {raw!r}): check that it is plugged in, that the port is right, and "
                    f"that it runs the flexvox syncbox firmware at {BAUD_RATE} baud")
            try:
                reply = sp.parse_reply(sp.unframe(raw))
            except ProtocolError as exc:
                last = exc
                _logger.warning("sync box: corrupt reply to %r (attempt %d of %d): %s",
                                body, attempt, self._attempts, exc)
                continue
            if not reply.ok:
                if reply.code == 1 and attempt < self._attempts:  # our line was corrupted on the way
                    last = ProtocolError(f"the sync box reported a checksum error for {body!r}")
                    continue
                meaning = sp.ERROR_CODES.get(reply.code, "unknown error")
                raise ProtocolError(f"the sync box refused {body!r}: ERR {reply.code} ({meaning}) {reply.text}")
            return reply
        raise ProtocolError(f"{last} (after {self._attempts} attempts)")

    def _query_int(self, body: str, key: str) -> int:
        reply = self.command(body)
        if len(reply.words) != 2 or reply.words[0] != key or not reply.words[1].isdigit():
            raise ProtocolError(f"the sync box answered {body!r} with 'OK {reply.text}', "
                                f"expected 'OK {key} <number>'")
        return int(reply.words[1])

    # ------------------------------------------------------------------ hooks
    def _do_open(self) -> None:
        if getattr(self._port, "timeout", 0) is None:
            self._port.timeout = self._timeout_s
        reset = getattr(self._port, "reset_input_buffer", None)
        if callable(reset):
            reset()
        self._version = self._do_firmware_version()
        _logger.info("sync box firmware: %s", self._version)

    def _do_close(self) -> None:
        close = getattr(self._port, "close", None)
        if callable(close):
            close()

    def _do_configure(self, settings: SyncSettings) -> None:
        self.command(f"SET PERIOD {settings.period_us}")
        self.command(f"SET PULSES {settings.pulses_per_frame}")

    def _do_start(self) -> None:
        self.command("START")

    def _do_stop(self) -> None:
        self.command("STOP")

    def _do_pulse_count(self) -> int:
        return self._query_int("COUNT?", "COUNT")

    def _do_elapsed_us(self) -> int:
        return self._query_int("TIME?", "TIME")

    def _do_firmware_version(self) -> str:
        reply = self.command("VERSION?")
        if len(reply.words) < 2 or reply.words[0] != "VERSION":
            raise ProtocolError(f"the sync box answered 'VERSION?' with 'OK {reply.text}', "
                                f"expected 'OK VERSION <name> <version>'")
        return " ".join(reply.words[1:])


def map_serial_error(exc: Exception, port_name: str) -> DeviceError:
    """Translate a ``serial.SerialException`` into a typed error with a fix."""
    text = str(exc)
    code = getattr(exc, "errno", None)
    if code == 13 or "Permission denied" in text or "Access is denied" in text:
        return DevicePermissionError(SERIAL_PERMISSION_HINT.format(port=port_name))
    if code == 16 or "busy" in text.lower() or "exclusively lock" in text:
        return DeviceBusyError(SERIAL_BUSY_HINT.format(port=port_name))
    if code == 2 or "No such file" in text or "could not open port" in text or "FileNotFound" in text:
        return DeviceNotFoundError(f"no serial port {port_name}: is the sync box plugged in? "
                                   f"`flexvox devices` lists the ports it can see")
    return DeviceError(f"cannot open {port_name}: {text}")
