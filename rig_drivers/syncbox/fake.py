"""A fake serial port with the sync box firmware behind it (same protocol as syncbox.ino).

Time is virtual: :meth:`FakeSyncBoxSerial.advance_us` moves the box's clock, so counters are
exact and nothing sleeps. Faults for tests: :attr:`corrupt_replies` (the next N replies carry
a wrong checksum), :attr:`silent` (no replies: timeouts).
"""

from __future__ import annotations

import logging
from collections import deque

from rig_drivers.interfaces import SYNC_MAX_PERIOD_US, SYNC_MAX_PULSES, SYNC_MIN_PERIOD_US
from rig_drivers.syncbox import protocol as sp

_logger = logging.getLogger(__name__)

FIRMWARE_NAME = "flexvox-syncbox"
FIRMWARE_VERSION = "1.0"


class FakeSyncBoxSerial:
    """Speaks the sync box protocol on ``write``/``readline`` like a pyserial port.

    Attributes
    ----------
    received : list of str
        Every line written to the port (terminator stripped), in order.
    silent : bool
        When True, nothing is answered (``readline`` returns ``b""`` as on a timeout).
    corrupt_replies : int
        The next this-many replies get a wrong checksum.
    """

    def __init__(self):
        self.received: list[str] = []
        self.silent = False
        self.corrupt_replies = 0
        self.timeout: float | None = None
        self.is_open = True
        self._rx = b""
        self._tx: deque[bytes] = deque()
        self.now_us = 0
        self.period_us = 1000
        self.pulses_per_frame = 1
        self.running = False
        self._start_us = 0
        self._stop_elapsed_us = 0
        self._has_run = False

    # ------------------------------------------------------------------ virtual time
    def advance_us(self, us: int) -> None:
        """Move the box's clock forward by ``us`` microseconds."""
        self.now_us += int(us)

    def elapsed_us(self) -> int:
        """Box time since START (frozen at STOP)."""
        return self.now_us - self._start_us if self.running else self._stop_elapsed_us

    def count(self) -> int:
        """Pattern pulses since START (the first fires at START)."""
        return self.elapsed_us() // self.period_us + 1 if self._has_run else 0

    # ------------------------------------------------------------------ serial API
    def write(self, data: bytes) -> int:
        self._rx += bytes(data)
        while b"\n" in self._rx:
            raw, self._rx = self._rx.split(b"\n", 1)
            self._line(raw.rstrip(b"\r"))
        return len(data)

    def readline(self) -> bytes:
        return self._tx.popleft() if self._tx else b""

    def reset_input_buffer(self) -> None:
        self._tx.clear()

    def close(self) -> None:
        self.is_open = False

    # ------------------------------------------------------------------ firmware
    def _reply(self, body: str) -> None:
        if self.silent:
            return
        line = sp.frame(body)
        if self.corrupt_replies > 0:
            self.corrupt_replies -= 1
            wrong = (sp.checksum(body) ^ 0x5A) & 0xFF
            line = f"{body}*{wrong:02X}\n".encode("ascii")
        self._tx.append(line)

    def _line(self, raw: bytes) -> None:
        text = raw.decode("ascii", errors="replace")
        self.received.append(text)
        if len(raw) + 1 > sp.MAX_LINE:
            self._reply("ERR 5 LINE TOO LONG")
            return
        try:
            body = sp.unframe(raw + b"\n")
        except Exception as exc:  # the firmware answers any bad line with ERR 1
            _logger.debug("fake sync box: bad line %r (%s)", text, exc)
            self._reply("ERR 1 BAD CHECKSUM")
            return
        self._reply(self._execute(body.split()))

    def _execute(self, words: list[str]) -> str:
        match words:
            case ["VERSION?"]:
                return f"OK VERSION {FIRMWARE_NAME} {FIRMWARE_VERSION}"
            case ["COUNT?"]:
                return f"OK COUNT {self.count()}"
            case ["TIME?"]:
                return f"OK TIME {self.elapsed_us()}"
            case ["STATE?"]:
                return f"OK STATE {'RUNNING' if self.running else 'STOPPED'} {self.period_us} {self.pulses_per_frame}"
            case ["START"]:
                if not self.running:
                    self.running, self._start_us, self._has_run = True, self.now_us, True
                return "OK RUNNING"
            case ["STOP"]:
                if self.running:
                    self._stop_elapsed_us = self.now_us - self._start_us
                    self.running = False
                return "OK STOPPED"
            case ["SET", "PERIOD" | "PULSES" as key, value]:
                if self.running:
                    return "ERR 4 NOT ALLOWED WHILE RUNNING"
                low, high = ((SYNC_MIN_PERIOD_US, SYNC_MAX_PERIOD_US) if key == "PERIOD"
                             else (1, SYNC_MAX_PULSES))
                if not value.isdigit() or not low <= int(value) <= high:
                    return f"ERR 3 BAD VALUE {key} MUST BE {low}..{high}"
                if key == "PERIOD":
                    self.period_us = int(value)
                else:
                    self.pulses_per_frame = int(value)
                return f"OK {key} {int(value)}"
        return "ERR 2 UNKNOWN COMMAND"
