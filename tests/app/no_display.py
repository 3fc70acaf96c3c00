"""An X display that no server serves: for tests of what happens when Qt cannot reach its display."""

from __future__ import annotations

from pathlib import Path


def _served(number: int) -> bool:
    """Whether an X server holds display ``number`` here (its socket, its abstract socket or its lock file)."""
    socket = f"/tmp/.X11-unix/X{number}"
    if Path(socket).exists() or Path(f"/tmp/.X{number}-lock").exists():
        return True
    try:
        unix = Path("/proc/net/unix").read_text()
    except OSError:
        return False
    return f"@{socket}" in unix.split()


def unserved_display() -> str:
    """``:N`` for the highest display number below 60000 that no X server serves now.

    A ``:N`` display is reached only through the local socket ``/tmp/.X11-unix/XN`` (or its abstract twin), so a
    number without either has no server; looking at test time holds whatever displays this machine runs
    (an X server on ``:77`` included).
    """
    for number in range(59999, 59000, -1):
        if not _served(number):
            return f":{number}"
    raise RuntimeError("every X display from :59001 to :59999 is served here")
