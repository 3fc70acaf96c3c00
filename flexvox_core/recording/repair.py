"""Repair: an interrupted capture finalised in place, or the recording it was replacing put back."""

from __future__ import annotations

import glob
import logging
from dataclasses import dataclass
from pathlib import Path

import zarr

from flexvox_core.recording.journal import JOURNAL, journal_writer_pid
from flexvox_core.recording.reader import Recording, open_recording
from flexvox_core.recording.schema import WRITTEN_PER_FRAME, utc_now
from flexvox_core.recording.writer import restore_if_empty

_logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Repair:
    """What :func:`repair_recording` did to a recording."""

    path: Path
    frames: int
    """The frames the recording at ``path`` holds now."""
    finalised: bool
    """An interrupted capture was finalised (False: the recording at ``path`` needed nothing)."""
    restored: tuple[str, ...] = ()
    """The earlier recordings put back in ``path``'s place (``.NAME.replaced-PID-XXXX.zarr``), each moved aside by
    an overwriting capture that was killed before its first frame; the last is the one at ``path`` now."""

    def describe(self) -> str:
        """One line: what changed (or that nothing needed it) and the frames the recording holds."""
        if self.restored:
            done = (f"put back {self.restored[-1]}, the earlier {self.path.name} that an overwriting capture killed "
                    "before its first frame had moved aside")
            return done + (", and finalised it" if self.finalised else "") + f"; {self.frames} frames"
        if self.finalised:
            return f"finalised, {self.frames} frames"
        return f"nothing to repair: a finished recording of {self.frames} frames; nothing was changed"


def moved_aside_by(path) -> Path | None:
    """The earlier recording that the interrupted capture at ``path`` moved aside when it began to replace it.

    That is the ``.NAME.replaced-PID-XXXX.zarr`` sibling whose PID is the writer's process id that the capture's
    journal names. None when ``path`` has no journal, or no such sibling (a capture that replaced nothing), or more
    than one (then none is chosen).
    """
    path = Path(path)
    pid = journal_writer_pid(path / JOURNAL)
    if pid is None:
        return None
    pattern = f".{glob.escape(path.stem)}.replaced-{pid}-*{glob.escape(path.suffix)}"
    found = [p for p in path.parent.glob(pattern) if p.is_dir() and not p.is_symlink()]
    return found[0] if len(found) == 1 else None


def repair_recording(path) -> Repair:
    """Repair the recording at ``path`` in place; :class:`Repair` says what was done.

    * An interrupted capture (one with a journal) is finalised: the journal's per-frame values are written into the
      arrays, every array is trimmed to the committed count and the journal is removed, so the store becomes an
      ordinary recording.
    * An interrupted capture that holds no committed frame, and that had moved an earlier recording aside to
      replace it (``--overwrite``), is deleted and the earlier recording put back, by the rule a capture that
      closes with no frame follows (:func:`~flexvox_core.recording.writer.restore_if_empty`); what comes back is
      repaired in turn.
    * A finished recording is left as it is.

    Raises
    ------
    RecordingError
        When the store is not a readable recording.
    OutputBusyError
        When a writer still holds the recording (a capture that is running, not interrupted).
    """
    from flexvox_core.writer_lock import WriterLock

    path = Path(path)
    restored: list[str] = []
    with WriterLock(path):
        while True:
            rec = open_recording(path)
            if not rec.interrupted:
                return Repair(path, rec.n_frames, False, tuple(restored))
            aside = moved_aside_by(path) if rec.n_frames == 0 else None
            if aside is None or not restore_if_empty(path, aside, rec.n_frames):
                break
            restored.append(aside.name)
            _logger.info("%s: the overwriting capture was killed before its first frame; put back %s, the "
                            "recording it had moved aside", path, aside.name)
        n = _finalise(rec)
    return Repair(path, n, True, tuple(restored))


def recover_recording(path) -> int:
    """Finalise an interrupted capture in place (:func:`repair_recording`); return the frames it holds.

    Raises
    ------
    RecordingError
        When the store is not a readable recording.
    OutputBusyError
        When a writer still holds the recording (a capture that is running, not interrupted).
    """
    return repair_recording(path).frames


def _finalise(rec: Recording) -> int:
    """Write an interrupted capture's journal into its arrays, trim them to the count and remove the journal."""
    n = rec.n_frames
    group = zarr.open_group(str(rec.path), mode="r+")
    frames = group["frames"]
    for name in WRITTEN_PER_FRAME:
        values = rec.journal.get(name) if rec.journal is not None else None
        if values is None or name not in group:
            continue
        arr = group[name]
        arr.resize((n,))
        arr[:] = values[:n]
    if frames.shape[0] != n:
        frames.resize((n, *frames.shape[1:]))
    attrs = dict(group.attrs)["flexvox"]
    group.attrs["flexvox"] = {**attrs, "recovered_utc": utc_now()}
    (rec.path / JOURNAL).unlink()
    _logger.info("%s: recovered an interrupted capture of %d frames", rec.path, n)
    return n
