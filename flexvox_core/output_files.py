"""Output files that never destroy inputs and never leave half-written results.

Every command and every GUI save that writes a file or a store goes through here:

* :func:`check_output` — before any work starts: the output must not be (or contain, or lie
  inside) one of the inputs, whatever the flags; an existing output needs ``overwrite``; an
  output another process is writing (:mod:`flexvox_core.writer_lock`) is refused; the folder
  must exist and accept a new file (probed by creating one, so it also holds for root and for
  read-only mounts).
* :func:`atomic_output` — the write itself goes to a hidden temporary sibling that keeps the
  output's suffix (``.NAME.partial-PID-XXXX.SUFFIX``: OpenCV and numpy choose the format by
  suffix), and is moved into place only when the writer returned. A failed write removes the
  sibling and leaves the old output as it was.
* :func:`write_text_atomic` — small text files (calibration files, code files, sync profiles):
  written, flushed to the disk, then renamed into place.
* :func:`classify_leftover` — what a hidden sibling that a killed writer left is (a partial output, an output
  moved aside, a lock file), with whether its writer still runs; :func:`flexvox_core.leftovers.find_leftovers`
  lists a folder's (``flexvox clean``). :func:`atomic_output` removes the partial outputs a killed writer of the
  same output left, and says so.

Replacing a file is one ``os.replace`` (atomic on POSIX and Windows). Replacing a *folder*
(a Zarr store, a folder of PNGs) takes two renames, because no portable call swaps two
folders: the old one is first renamed to a hidden ``.NAME.replaced-PID-XXXX`` sibling, the new
one takes its name, and only then is the old one deleted. A process killed between the two
renames leaves both, under their hidden names; nothing is lost.
"""

from __future__ import annotations

import contextlib
import glob
import logging
import os
import re
import secrets
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from flexvox_core.numbers import flag
from flexvox_core.output_errors import CLI_OVERWRITE_HINT, OVERWRITE_HINT, OutputError
from flexvox_core.writer_lock import WriterLock, lock_holder

_logger = logging.getLogger(__name__)

__all__ = ["CLI_OVERWRITE_HINT", "OVERWRITE_HINT", "OutputError", "atomic_output", "check_output"]


def _resolved(path) -> Path:
    return Path(path).expanduser().resolve()


def _within(inner: Path, outer: Path) -> bool:
    return inner == outer or outer in inner.parents


def refuse_output_onto_input(output, inputs: Iterable) -> None:
    """Raise :class:`OutputError` when ``output`` is one of ``inputs``, holds one, or lies inside one.

    Paths are compared after resolving symbolic links, ``..`` and ``~``, and by file identity
    where both exist (hard links, case-insensitive file systems).
    """
    out = _resolved(output)
    for source in inputs:
        if source is None:
            continue
        src = _resolved(source)
        identical = out == src
        if not identical and out.exists() and src.exists():
            with contextlib.suppress(OSError):
                identical = os.path.samefile(out, src)
        if identical:
            how = "is the input"
        elif _within(src, out):
            how = "holds the input"
        elif _within(out, src):
            how = "lies inside the input"
        else:
            continue
        raise OutputError(f"the output {output} {how} {source}: an output never replaces its input, "
                          "whatever the flags; choose another path")


def output_kind(path) -> str | None:
    """What an output path will be: "store" (``.zarr``: a Zarr folder), "file" (any other suffix),
    or None (no suffix: the command decides, e.g. a folder of PNGs)."""
    suffix = Path(path).suffix.lower()
    if not suffix:
        return None
    return "store" if suffix == ".zarr" else "file"


RECORDING_SUFFIX = ".zarr"
"""The suffix of a recording's (and any Zarr store's) folder name."""


def check_store_suffix(path) -> Path:
    """``path`` if its name ends in ``.zarr``; :class:`OutputError` otherwise. A recording is a Zarr store, a folder;
    under another suffix every command would take it for a file of that kind (``.npy``: an array), and without one
    for a folder of pictures."""
    path = Path(path)
    if path.suffix.lower() != RECORDING_SUFFIX:
        got = f"ends in {path.suffix}" if path.suffix else "has no suffix"
        raise OutputError(f"a recording (a Zarr store) is a folder whose name ends in .zarr: {path} {got}; write "
                          f"{path.with_suffix(RECORDING_SUFFIX)}")
    return path


def check_overwrite(overwrite) -> None:
    """``overwrite`` must be True or False: a string (``overwrite="no"``) is true, and had replaced the output."""
    flag("`overwrite`", overwrite)


def check_path(path, name: str = "path", *, call: str = "") -> Path:
    """``path`` as a :class:`~pathlib.Path`, an output's or an input's: a ``str`` or an ``os.PathLike``. Bytes, an
    array, a result object or a number is a ``TypeError`` in words (pathlib said "argument should be a str object
    or an os.PathLike object returning str"). ``call``: the call with its arguments in order
    (``fv.write_video(path, video)``), named when something that is no path stands in the path's place: the
    arguments swapped, most likely."""
    if isinstance(path, str | os.PathLike):
        return Path(path)
    if isinstance(path, bytes | bytearray):
        what = f"bytes {bytes(path)!r}: give the path as text, {bytes(path).decode(errors='replace')!r}"
    else:
        shape = getattr(path, "shape", None)
        what = type(path).__name__
        if shape is not None:
            what += f" of shape {tuple(shape)}"
        elif path is None or isinstance(path, int | float):
            what += f" {path!r}"
        if call:
            what += f": the path comes first, {call}" if "," in call else f" ({call} takes a path)"
    raise TypeError(f"`{name}` must be a file path (str or pathlib.Path); got {what}")


def check_output(path, *, overwrite: bool = False, inputs: Iterable = (), hint: str = OVERWRITE_HINT,
                 kind: str | None = "auto") -> Path:
    """Check, before any work, that ``path`` may be written; return it.

    Parameters
    ----------
    path : str or Path
        The output file or folder.
    overwrite : bool
        Whether an existing output may be replaced.
    inputs : iterable of paths
        The command's inputs: the output may not be, hold or lie inside any of them.
    hint : str
        How the user allows overwriting, in the caller's words: Python's ``overwrite=True`` by default
        (:data:`~flexvox_core.output_errors.OVERWRITE_HINT`), the command line's ``--overwrite``
        (:data:`~flexvox_core.output_errors.CLI_OVERWRITE_HINT`).
    kind : "file", "store", "folder", None or "auto"
        What will be written (default: :func:`output_kind` of the path); a ``store``'s name must end in ``.zarr``.
        ``overwrite`` replaces only
        the same kind: a file with a file, a Zarr store with a Zarr store (a folder holding
        ``zarr.json``), never a folder of other things with a file or a store. A ``.zarr`` of kind
        ``auto`` (a video, or a file under that name) never replaces a recording (:func:`is_recording`);
        writers of recordings say ``store``.

    Raises
    ------
    OutputError
        Onto an input; an existing output without ``overwrite``, or of another kind; an output
        another process is writing; a missing folder; a folder that refuses new files; a ``store`` whose name
        does not end in ``.zarr`` (:func:`check_store_suffix`).
    """
    check_overwrite(overwrite)
    path = Path(path).expanduser()
    refuse_output_onto_input(path, inputs)
    if kind == "store":
        check_store_suffix(path)
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputError(f"{path} already exists; {hint}")
        holder = lock_holder(path)
        if holder is not None:
            raise OutputError(f"{path} is being written by {holder}; it cannot be replaced until that ends")
        refuse_other_kind(path, output_kind(path) if kind == "auto" else kind)
        if kind == "auto" and output_kind(path) == "store" and is_recording(path):
            raise OutputError(f"{path} is a recording (camera frames); overwriting replaces a recording only with a "
                              "recording, never with a video or another file: choose another path")
    folder = path.parent
    if not folder.is_dir():
        raise OutputError(f"cannot write {path}: the folder {folder} does not exist")
    check_writable(folder, path)
    return path


def is_recording(path) -> bool:
    """Whether ``path`` is a recording's store (a Zarr store with a ``frames`` array: the camera frames, which
    nothing can make again), not a video's."""
    path = Path(path)
    return (path / "zarr.json").is_file() and (path / "frames" / "zarr.json").is_file()


def refuse_other_kind(path: Path, kind: str | None) -> None:
    """Refuse to replace a folder with a file, a file with a folder, or a non-store folder with a store."""
    is_folder = path.is_dir()
    if kind == "file" and is_folder:
        raise OutputError(f"{path} is a folder; overwriting replaces a file with a file, never a folder: choose "
                          "another path")
    if kind in ("store", "folder") and not is_folder:
        raise OutputError(f"{path} is a file, not a folder; overwriting never replaces a file with a folder: "
                          "choose another path")
    if kind == "store" and not (path / "zarr.json").is_file():
        raise OutputError(f"{path} is a folder but not a Zarr store; overwriting replaces only a Zarr store: "
                          "choose another path")


def check_writable(folder, path=None) -> None:
    """Raise :class:`OutputError` unless a new file can be created in ``folder`` (a probe file is
    created and removed: permissions, read-only mounts and quotas all answer)."""
    folder = Path(folder)
    try:
        fd, probe = tempfile.mkstemp(prefix=".flexvox-probe-", dir=folder)
    except OSError as exc:
        target = path if path is not None else folder
        raise OutputError(f"cannot write {target}: the folder {folder} does not accept new files "
                          f"({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def temporary_sibling(path, tag: str = "partial") -> Path:
    """A hidden, unused name beside ``path`` that keeps its suffix: ``.STEM.TAG-PID-XXXX.SUFFIX``."""
    path = Path(path)
    return path.with_name(f".{path.stem}.{tag}-{os.getpid()}-{secrets.token_hex(3)}{path.suffix}")


def remove_path(path) -> None:
    """Delete a file, link or folder (no error when it is already gone)."""
    path = Path(path)
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def fsync_folder(folder) -> None:
    """Flush a folder's entries (renames, new files) to the disk where the OS allows it."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # Windows cannot open folders
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def move_into_place(new, path) -> None:
    """Move the finished ``new`` onto ``path``, replacing what is there (see the module docstring)."""
    new, path = Path(new), Path(path)
    old_is_folder = path.is_dir() and not path.is_symlink()
    if not (new.is_dir() or old_is_folder):
        os.replace(new, path)
    else:
        aside = None
        if path.exists() or path.is_symlink():
            aside = temporary_sibling(path, "replaced")
            os.rename(path, aside)
        try:
            os.rename(new, path)
        except OSError:
            if aside is not None:
                os.rename(aside, path)
            raise
        if aside is not None:
            remove_path(aside)
    fsync_folder(path.parent)


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False, hint: str = OVERWRITE_HINT) -> Iterator[Path]:
    """Write an output through a temporary sibling: ``with atomic_output(p) as tmp: write(tmp)``.

    ``tmp`` does not exist yet; the writer creates it (a file or a folder). When the block
    ends normally, ``tmp`` replaces ``path``; when it raises, ``tmp`` is removed and ``path``
    is untouched. ``overwrite`` is checked again here (another process may have created
    ``path`` since :func:`check_output`).
    """
    check_overwrite(overwrite)
    path = Path(path).expanduser()
    tmp = temporary_sibling(path)
    # One writer per output: a capture (or another command) cannot start on it while this one
    # writes, and this one cannot replace what a capture is writing.
    with WriterLock(path):
        remove_dead_partials(path)
        try:
            yield tmp
            if not (tmp.exists() or tmp.is_symlink()):
                raise OutputError(f"nothing was written for {path}")
            if (path.exists() or path.is_symlink()) and not overwrite:
                raise OutputError(f"{path} appeared while it was being written; {hint}")
            move_into_place(tmp, path)
        except BaseException:
            remove_path(tmp)
            raise
    _logger.debug("wrote %s", path)


def write_text_atomic(path, text: str, *, overwrite: bool = True, encoding: str = "utf-8") -> Path:
    """Write a small text file atomically and durably (flushed to the disk before the rename)."""
    path = Path(path).expanduser()
    with atomic_output(path, overwrite=overwrite) as tmp:
        with open(tmp, "w", encoding=encoding) as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
    return path


_LEFTOVER = re.compile(r"^\.(?P<stem>.+)\.(?P<tag>partial|replaced)-(?P<pid>\d+)-[0-9a-f]+(?P<suffix>(\.[^.]+)?)$")
_LOCK = re.compile(r"^\.(?P<name>.+)\.lock$")


@dataclass(frozen=True)
class Leftover:
    """What an unfinished write left in a folder: a partial output, an output moved aside, or a lock file."""

    path: Path
    kind: str
    """"partial" (``.NAME.partial-PID-XXXX.SUFFIX``), "replaced" (``.NAME.replaced-PID-XXXX.SUFFIX``) or "lock"
    (``.NAME.lock``)."""
    output: Path
    """The output it belongs to."""
    writer: str | None
    """Who writes ``output`` now ("process 123 (...)"), or None when its writer no longer runs."""
    removable: bool
    why: str
    """What it is and what removing it means, in words."""


def _process_runs(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def classify_leftover(path: Path, *, lock_held_here: bool = False) -> Leftover | None:
    """What the hidden sibling ``path`` is by its name and its writer alone, or None when it is no leftover.

    :func:`flexvox_core.leftovers.find_leftovers` looks further at an earlier recording moved aside (whether the
    one in its place holds frames); ask it, not this, whether a leftover may go.
    """
    m = _LEFTOVER.match(path.name)
    if m:
        output = path.with_name(m["stem"] + m["suffix"])
        pid = int(m["pid"])
        writer = None if lock_held_here else lock_holder(output)
        if writer is None and pid != os.getpid() and _process_runs(pid):
            writer = f"process {pid}"
        if m["tag"] == "partial":
            why = f"the unfinished output of {output.name} by process {pid}"
            return Leftover(path, "partial", output, writer, writer is None, why)
        if output.exists():
            why = f"the earlier {output.name}, moved aside by process {pid} when it replaced it"
            return Leftover(path, "replaced", output, writer, writer is None, why)
        why = (f"the earlier {output.name}, moved aside by process {pid}, which stopped before the new one took its "
               f"place: the only copy; rename it back to {output.name} to keep it")
        return Leftover(path, "replaced", output, writer, False, why)
    m = _LOCK.match(path.name)
    if m and path.is_file():
        try:
            head = path.read_bytes()[:64].decode("utf-8", "replace")
        except OSError:
            return None
        if head and not re.match(r"^\d+ ", head):
            return None  # another program's lock file
        output = path.with_name(m["name"])
        writer = lock_holder(output)
        return Leftover(path, "lock", output, writer, writer is None, f"the lock file of {output.name}")
    return None


def remove_dead_partials(path) -> list[str]:
    """Remove the partial outputs of ``path`` that a killed writer left; return their names.

    Called with ``path``'s writer lock held (:func:`atomic_output`), so no other writer of ``path`` runs.
    """
    path = Path(path)
    removed: list[str] = []
    if not path.parent.is_dir():
        return removed
    for p in sorted(path.parent.glob(f".{glob.escape(path.stem)}.partial-*")):
        item = classify_leftover(p, lock_held_here=True)  # the lock is this process's: only the process id can tell
        if item is not None and item.kind == "partial" and item.output == path and item.writer is None:
            remove_path(item.path)
            removed.append(item.path.name)
            _logger.warning("found and removed %s, the unfinished output of a writer of %s that no longer runs "
                            "(a killed write)", item.path.name, path.name)
    return removed
