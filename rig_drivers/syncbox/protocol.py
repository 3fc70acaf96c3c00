"""The sync box line protocol: framing, checksums and reply parsing (see PROTOCOL.md).

A line is ASCII ``<body>*<XX>\\n``: ``XX`` is the XOR of every byte of ``body`` as two
upper-case hex digits (NMEA style). Replies are ``OK <words>`` or ``ERR <code> <words>``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from rig_drivers.errors import ProtocolError

MAX_LINE = 64
"""Longest line either side sends, terminator included."""

PROTOCOL_VERSION = 1

ERROR_CODES = {
    1: "bad checksum",
    2: "unknown command",
    3: "bad value",
    4: "not allowed while running",
    5: "line too long",
}

_LINE_RE = re.compile(r"^([\x20-\x29\x2b-\x7e]*)\*([0-9A-F]{2})$")


def checksum(body: str) -> int:
    """XOR of the bytes of ``body`` (ASCII)."""
    value = 0
    for byte in body.encode("ascii"):
        value ^= byte
    return value


def frame(body: str) -> bytes:
    """``body`` framed as a line: ``b"<body>*XX\\n"``."""
    if "*" in body or "\n" in body:
        raise ValueError(f"`body` must not contain '*' or a newline; got {body!r}")
    line = f"{body}*{checksum(body):02X}\n".encode("ascii")
    if len(line) > MAX_LINE:
        raise ValueError(f"`body` must frame to at most {MAX_LINE} bytes; got {len(line)}")
    return line


def unframe(line: bytes) -> str:
    """The body of a received line, after checking its form and checksum.

    Raises
    ------
    ProtocolError
        On a non-ASCII or malformed line, or a checksum mismatch.
    """
    try:
        text = bytes(line).decode("ascii").rstrip("\r\n")
    except UnicodeDecodeError:
        raise ProtocolError(f"sync box sent non-ASCII bytes {bytes(line)!r}: check the baud rate") from None
    match = _LINE_RE.match(text)
    if match is None:
        raise ProtocolError(f"sync box sent a malformed line {text!r} (expected '<body>*XX'): "
                            f"check the baud rate and that the firmware is flexvox's syncbox.ino")
    body, sent = match.group(1), int(match.group(2), 16)
    if checksum(body) != sent:
        raise ProtocolError(f"checksum error in the sync box reply {text!r}: computed "
                            f"{checksum(body):02X}, received {sent:02X} (electrical noise or a "
                            f"wrong baud rate; check the USB cable)")
    return body


@dataclass(frozen=True)
class Reply:
    """A parsed reply: ``ok`` with its words, or an error code and text."""

    ok: bool
    words: tuple[str, ...]
    code: int = 0

    @property
    def text(self) -> str:
        """The words joined by spaces."""
        return " ".join(self.words)


def parse_reply(body: str) -> Reply:
    """Parse a reply body (``OK ...`` or ``ERR <code> ...``)."""
    parts = body.split()
    if parts and parts[0] == "OK":
        return Reply(True, tuple(parts[1:]))
    if len(parts) >= 2 and parts[0] == "ERR" and parts[1].isdigit():
        return Reply(False, tuple(parts[2:]), int(parts[1]))
    raise ProtocolError(f"sync box reply {body!r} is neither 'OK ...' nor 'ERR <code> ...'")
