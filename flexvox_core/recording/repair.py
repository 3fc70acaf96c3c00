"""Repair: an interrupted capture finalised in place."""

from __future__ import annotations

import logging

import zarr

from flexvox_core.recording.journal import JOURNAL
from flexvox_core.recording.reader import open_recording
from flexvox_core.recording.schema import WRITTEN_PER_FRAME, utc_now

_logger = logging.getLogger(__name__)


def recover_recording(path) -> int:
    """Finalise an interrupted capture in place; return the frames it holds.

    Writes the journal's per-frame values into the arrays, trims every array to the
    committed count and removes the journal, so the store becomes an ordinary recording.
    A finished recording is left as it is.

    Raises
    ------
    RecordingError
        When the store is not a readable recording.
    OutputBusyError
        When a writer still holds the recording (a capture that is running, not interrupted).
    """
    from flexvox_core.writer_lock import WriterLock

    with WriterLock(path):
        rec = open_recording(path)
        if not rec.interrupted:
            return rec.n_frames
        n = rec.n_frames
        group = zarr.open_group(str(rec.path), mode="r+")
        frames = group["frames"]
        for name in WRITTEN_PER_FRAME:
            values = rec.journal.get(name)
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
