"""One writer per output: an OS file lock beside the path being written.

A capture (or any :class:`~flexvox_core.recording.RecordingWriter`) holds an exclusive lock on
``.NAME.lock`` in the recording's folder for as long as it writes. The lock is the operating
system's (``flock`` on POSIX, ``msvcrt.locking`` on Windows), so it dies with the process: a
killed capture never leaves a stale lock, only a small file that the next writer reuses. The
file holds the holder's process id and command line, which is how a refused writer names it.

The lock file lives beside the recording, not inside it, so that it also guards the moment a
recording is replaced (``--overwrite`` renames folders).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from pathlib import Path

from flexvox_core.output_errors import OutputBusyError, OutputError

_logger = logging.getLogger(__name__)

try:  # POSIX
    import fcntl

    def _try_lock(fd: int) -> bool:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        return True

    def _unlock(fd: int) -> None:
        fcntl.flock(fd, fcntl.LOCK_UN)

except ImportError:  # pragma: no cover - Windows
    import msvcrt

    def _try_lock(fd: int) -> bool:
        os.lseek(fd, 0, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        return True

    def _unlock(fd: int) -> None:
        os.lseek(fd, 0, os.SEEK_SET)
        msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)


def lock_path(path) -> Path:
    """The lock file that guards ``path``: ``.NAME.lock`` beside it, after resolving links and ``..``
    (a symbolic link to a recording shares the recording's lock)."""
    path = Path(path).expanduser().resolve()
    return path.with_name(f".{path.name}.lock")


def _describe(raw: bytes) -> str:
    text = raw.decode("utf-8", "replace").strip()
    pid, _, command = text.partition(" ")
    if not pid.isdigit():
        return "another process"
    return f"process {pid}" + (f" ({command})" if command else "")


class WriterLock:
    """An exclusive, non-blocking lock on an output path (see the module docstring).

    ``with WriterLock(path):`` holds it; :meth:`acquire` raises :class:`OutputBusyError` naming
    the holder when another process (or another writer in this one) has it.
    """

    def __init__(self, path):
        self.path = Path(path).expanduser()
        self.file = lock_path(self.path)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        """True while this object holds the lock."""
        return self._fd is not None

    def acquire(self) -> WriterLock:
        """Take the lock, or raise :class:`OutputBusyError` at once (never waits)."""
        if self._fd is not None:
            return self
        for _ in range(10):
            try:
                fd = os.open(self.file, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise OutputError(f"cannot write {self.path}: cannot create its lock file {self.file} "
                                  f"({exc.strerror or exc})") from None
            if not _try_lock(fd):
                holder = _describe(os.pread(fd, 4096, 0) if hasattr(os, "pread") else b"")
                os.close(fd)
                raise OutputBusyError(f"{self.path} is being written by {holder}; wait for it to end or stop it, "
                                      "or choose another path", holder)
            # The holder before us may have removed the file after we opened it: then our lock is on
            # a file nobody else will find. Keep the lock only if the name still leads to our file.
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.file))
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()} {' '.join(sys.argv)[:300]}\n".encode())
                self._fd = fd
                return self
            os.close(fd)
        raise OutputBusyError(f"{self.path}: its lock file {self.file} keeps changing; another process is "
                              "starting and stopping writes to it")

    def release(self) -> None:
        """Give the lock back and remove the lock file."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        with contextlib.suppress(OSError):
            os.unlink(self.file)  # while still locked: a waiting process re-checks the name
        with contextlib.suppress(OSError):
            _unlock(fd)
        os.close(fd)

    def __enter__(self) -> WriterLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def lock_holder(path) -> str | None:
    """Who is writing ``path`` now ("process 123 (flexvox capture ...)"), or None when nobody is.

    Only probes the lock: it never writes the lock file, so a writer starting meanwhile is not
    told that the prober holds it.
    """
    file = lock_path(path)
    try:
        fd = os.open(file, os.O_RDONLY)
    except OSError:
        return None
    try:
        if _try_lock(fd):
            _unlock(fd)
            return None
        return _describe(os.pread(fd, 4096, 0) if hasattr(os, "pread") else b"")
    finally:
        os.close(fd)
