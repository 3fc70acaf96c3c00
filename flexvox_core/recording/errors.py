"""The errors of reading and writing recordings."""

from __future__ import annotations


class RecordingError(ValueError):
    """A recording that cannot be read or is damaged; the message says what is wrong."""


class DamagedRecordingError(RecordingError):
    """Frames whose chunk is missing, cannot be decoded or fails its checksum.

    Attributes
    ----------
    rows : list of int
        The damaged rows found (the first few, for a read that stops at the first).
    """

    def __init__(self, message: str, rows=()):
        super().__init__(message)
        self.rows = list(rows)
