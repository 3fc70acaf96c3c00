"""What killed writers left in a folder, and which of it may go (``flexvox clean``, ``flexvox info``'s notes).

Each hidden sibling is named by :mod:`flexvox_core.output_files` (a partial output, an output moved aside, a lock
file; whether its writer still runs). An earlier recording that an overwriting capture moved aside
(``.NAME.replaced-PID-XXXX.zarr``) is looked at further here: while the recording in its place holds no committed
frame (the capture was killed before its first one, or the store is not a readable recording), the earlier one is
the only copy of its data and is never removable; :func:`~flexvox_core.recording.repair.repair_recording` puts it
back by the rule a capture that closes with no frame follows.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from flexvox_core.output_files import Leftover, classify_leftover


def find_leftovers(folder: str | os.PathLike[str]) -> list[Leftover]:
    """Every leftover of an unfinished write in ``folder`` (not recursive), sorted by name.

    A leftover whose writer still runs (its output's lock is held, or the process named in its name runs) has
    ``writer`` set and is never ``removable``; nor is an earlier output that is now its only copy (its output is
    missing, or is a recording that holds no committed frame).
    """
    found = [leftover(p) for p in sorted(Path(folder).iterdir()) if p.name.startswith(".")]
    return [f for f in found if f is not None]


def leftover(path: str | os.PathLike[str]) -> Leftover | None:
    """What the hidden sibling ``path`` is (see :func:`find_leftovers`), or None when it is no leftover of
    flexvox's."""
    item = classify_leftover(Path(path))
    if item is None or item.kind != "replaced" or not item.removable or not _is_recording(item.path):
        return item
    return _only_copy(item) or item


def _is_recording(path: Path) -> bool:
    """Whether ``path`` looks like a recording (a Zarr folder with a ``frames`` array), whether or not it is sound."""
    return path.is_dir() and (path / "zarr.json").is_file() and (path / "frames").is_dir()


def _only_copy(item: Leftover) -> Leftover | None:
    """``item`` (an earlier recording moved aside) made unremovable, with the reason and how to restore it, when
    the recording in its place holds no committed frame; None when that one holds frames."""
    from flexvox_core.recording import RecordingError, moved_aside_by, open_recording

    output = item.output
    try:
        rec = open_recording(output)
        frames, interrupted = rec.n_frames, rec.interrupted
    except (RecordingError, OSError, ValueError):
        frames, interrupted = None, False
    if frames:
        return None
    state = "holds no frame" if frames == 0 else "is not a readable recording"
    aside = moved_aside_by(output) if interrupted else None
    if aside is not None and aside.name == item.path.name:
        how = f"`flexvox info --repair {output}` puts it back"
    else:
        how = f"to keep it, delete {output.name} and rename this back to {output.name}"
    why = (f"the earlier {output.name}, moved aside when a capture began to replace it; {output.name} {state} "
           f"(that capture stopped before its first frame), so this is the only copy; {how}")
    return dataclasses.replace(item, removable=False, why=why)
