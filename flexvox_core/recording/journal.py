"""The capture journal: a small append-only binary file that commits each frame a capture writes.

It lives at ``frames/capture.journal`` while a capture writes (and after one was killed); a closed
recording has none. Layout (little-endian)::

    header   8 bytes  magic "FLXVJRN2"
             4 bytes  record size (28)
             4 bytes  the writer's process id
    record   8 bytes  frame id (int64)
             8 bytes  timestamp, seconds (float64)
             1 byte   dropped flag, then 3 bytes of padding
             4 bytes  CRC-32 of the frame's values as stored (:func:`~flexvox_core.recording.schema.values_crc`)
             4 bytes  CRC-32 of the record's first 24 bytes

A record is appended only after the frame's chunk was written, so a complete record is the frame's
commit point. A kill tears at most the last record, which :func:`read_journal` ignores. Journals of
schema 1 (magic "FLXVJRN1") have 24-byte records with no frame CRC (the record's own CRC covers its
first 17 bytes) and are still read.
"""

from __future__ import annotations

import logging
import struct
import zlib
from pathlib import Path

import numpy as np

from flexvox_core.recording.errors import RecordingError

_logger = logging.getLogger(__name__)

JOURNAL = "frames/capture.journal"
"""The per-frame journal of a capture being written (absent once the writer closed). It lives in
the ``frames`` array's folder, where zarr never looks for members (a file in the group's own
folder makes zarr warn when it lists the group)."""
_JOURNAL_MAGIC_V1 = b"FLXVJRN1"
_RECORD_V1 = struct.Struct("<qd?3xI")  # frame id, timestamp, dropped, pad, CRC-32 of the first 17 bytes
_JOURNAL_MAGIC = b"FLXVJRN2"
_RECORD_HEAD = struct.Struct("<qd?3xI")  # frame id, timestamp, dropped, pad, the frame's CRC-32
_RECORD = struct.Struct("<qd?3xII")  # ..., CRC-32 of the first 24 bytes
_HEADER = struct.Struct("<II")  # record size, writer's process id
JOURNAL_HEADER_SIZE = len(_JOURNAL_MAGIC) + _HEADER.size


def journal_header(pid: int) -> bytes:
    """The bytes that open a new journal written by process ``pid``."""
    return _JOURNAL_MAGIC + _HEADER.pack(_RECORD.size, pid & 0xFFFFFFFF)


def journal_record(frame_id: int, timestamp: float, dropped: bool, crc: int) -> bytes:
    """One frame's record: its per-frame values and CRC, closed by the record's own CRC-32."""
    head = _RECORD_HEAD.pack(int(frame_id), float(timestamp), bool(dropped), crc)
    return head + struct.pack("<I", zlib.crc32(head))


def journal_writer_pid(path) -> int | None:
    """The process id a capture journal's header names (the writer that made it), or None when the file is
    missing, too short or not a flexvox journal."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(JOURNAL_HEADER_SIZE)
    except OSError:
        return None
    if len(head) < JOURNAL_HEADER_SIZE or head[:len(_JOURNAL_MAGIC)] not in (_JOURNAL_MAGIC, _JOURNAL_MAGIC_V1):
        return None
    return _HEADER.unpack_from(head, len(_JOURNAL_MAGIC))[1]


def read_journal(path) -> dict:
    """The committed records of a capture journal: ``frame_id``, ``timestamp``, ``dropped`` and
    ``frame_crc`` (None in a schema-1 journal, which has no frame CRCs).

    A kill mid-write leaves at most one torn record, at the end: a partial record, or a last
    complete record that fails its CRC. Both are ignored. A failing record with complete
    records after it is damage, not a kill, and is refused.

    Raises
    ------
    RecordingError
        When the file is not a flexvox journal, or a record before the last fails its CRC.
    """
    path = Path(path)
    data = path.read_bytes()
    magic = data[:len(_JOURNAL_MAGIC)]
    if magic == _JOURNAL_MAGIC:
        record, checked, has_crc = _RECORD, 24, True
    elif magic == _JOURNAL_MAGIC_V1:
        record, checked, has_crc = _RECORD_V1, 17, False
    else:
        raise RecordingError(f"{path}: not a flexvox capture journal")
    body = memoryview(data)[JOURNAL_HEADER_SIZE:]
    n_full = len(body) // record.size
    ids, stamps, drops, crcs = [], [], [], []
    for k in range(n_full):
        fields = record.unpack_from(body, k * record.size)
        if zlib.crc32(bytes(body[k * record.size: k * record.size + checked])) != fields[-1]:
            if k < n_full - 1:
                raise RecordingError(
                    f"{path}: the capture journal is damaged: record {k} of {n_full} fails its checksum and "
                    f"{n_full - k - 1} complete record(s) follow it (a kill can tear only the last one); nothing "
                    "was changed: copy the recording before trying to recover it")
            _logger.info("%s: the last record (%d) fails its checksum: torn by the kill, ignored", path, k)
            break
        ids.append(fields[0])
        stamps.append(fields[1])
        drops.append(fields[2])
        if has_crc:
            crcs.append(fields[3])
    if len(body) % record.size:
        _logger.info("%s: a torn last record (%d bytes) is ignored", path, len(body) % record.size)
    return {"frame_id": np.asarray(ids, np.int64), "timestamp": np.asarray(stamps, np.float64),
            "dropped": np.asarray(drops, bool), "frame_crc": np.asarray(crcs, np.uint32) if has_crc else None}
