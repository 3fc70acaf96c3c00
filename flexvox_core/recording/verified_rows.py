"""Verified reads: every row of frames (or ground truth) a reader gets has been checked.

Integrity (schema 2)
--------------------
Every frame carries the CRC-32 of its values as stored (C order, little-endian bytes of the
stored dtype; a dropped frame's zero row included), committed with the frame's journal record
and kept in ``frame_crc``. Every read of frames goes through :class:`VerifiedRows`, which checks
each row it returns against its CRC, so a deleted chunk (which zarr would read as zeros), a
truncated one (a codec error) or a changed one raises
:class:`~flexvox_core.recording.errors.DamagedRecordingError` naming the rows; nothing reads it as
data. :meth:`Recording.verify <flexvox_core.recording.reader.Recording.verify>` checks every row and
reports all the damage. Schema-1 recordings (no CRCs) are still read: there, a row whose chunk file
is missing is refused, and a chunk that decodes to changed values cannot be detected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import zarr

from flexvox_core.recording.errors import DamagedRecordingError
from flexvox_core.recording.schema import values_crc


def _read_rows(array, start: int, stop: int, label: str) -> np.ndarray:
    """Rows ``[start, stop)`` of a zarr array; a codec or I/O error becomes a :class:`DamagedRecordingError`."""
    try:
        return np.asarray(array[start:stop])
    except Exception as exc:  # noqa: BLE001 - zarr and its codecs raise many types for a damaged chunk
        raise DamagedRecordingError(f"{label} rows {start}..{stop - 1} cannot be read ({type(exc).__name__}: "
                                    f"{exc})", range(start, stop)) from None


class VerifiedRows:
    """The first ``n`` rows of a recording's zarr array, read lazily and checked row by row.

    Every row returned has been checked against its CRC (``crcs``); in a recording without CRCs
    (schema 1), rows that must hold data (``required``) are checked for a chunk file instead.
    A damaged row raises :class:`DamagedRecordingError` (never zeros). Offers what readers use
    of a ``zarr.Array``: ``shape``, ``dtype``, ``ndim``, ``chunks``, ``len`` and indexing
    (``[:]``, ``[i]``, ``[a:b]``, ``[a:b, y, x]``); dask reads it with ``da.from_array``.
    """

    def __init__(self, array: zarr.Array, n: int, *, crcs: np.ndarray | None, what: str,
                 store: Path | None = None, required: np.ndarray | None = None):
        self.array = array
        self.n = int(n)
        self.crcs = None if crcs is None else np.asarray(crcs, np.uint32)
        self.what = what
        self.label = f"{store}: {what}" if store is not None else what
        self.store = store
        self.required = required

    @property
    def shape(self) -> tuple[int, ...]:
        """``(n, *array.shape[1:])``."""
        return (self.n, *self.array.shape[1:])

    @property
    def dtype(self):
        """The array's dtype."""
        return self.array.dtype

    @property
    def ndim(self) -> int:
        """The array's dimensions."""
        return self.array.ndim

    @property
    def chunks(self):
        """The array's chunk shape."""
        return self.array.chunks

    def __len__(self) -> int:
        return self.n

    def chunk_file(self, row: int) -> Path | None:
        """The file that holds ``row`` in a local store (None when unknown)."""
        if self.store is None:
            return None
        key = self.array.metadata.encode_chunk_key((row, *([0] * (self.array.ndim - 1))))
        return self.store / self.array.basename / key

    def problems(self, start: int, stop: int, rows: np.ndarray | None = None) -> list[tuple[int, str]]:
        """``(row, what is wrong)`` for each damaged row of ``[start, stop)`` (``rows``: their values, if read)."""
        if rows is None:
            try:
                rows = _read_rows(self.array, start, stop, self.label)
            except DamagedRecordingError:
                if stop - start == 1:
                    return [(start, "its chunk cannot be decoded (truncated or garbled)")]
                return [p for r in range(start, stop) for p in self.problems(r, r + 1)]
        found = []
        for k, row in enumerate(rows):
            i = start + k
            if self.crcs is not None:
                if values_crc(row) != int(self.crcs[i]):
                    f = self.chunk_file(i)
                    if f is not None and not f.exists():
                        found.append((i, "its chunk file is missing"))
                    elif int(self.crcs[i]) == 0:
                        found.append((i, "its checksum does not match, or the checksum itself is missing (it reads "
                                         "0: see the per-frame arrays)"))
                    else:
                        found.append((i, "its checksum does not match (the chunk was changed or damaged)"))
            elif self.required is not None and self.required[i]:
                f = self.chunk_file(i)
                if f is not None and not f.exists():
                    found.append((i, "its chunk file is missing"))
            if row.dtype.kind == "f" and not np.isfinite(row.sum(dtype=np.float64)):  # one pass: a sum of finite
                # float32 values cannot overflow float64; NaN or inf in the row makes it NaN or inf
                found.append((i, "it holds NaN or infinite values (no reconstruction can use them)"))
        return found

    def _check(self, start: int, stop: int, rows: np.ndarray) -> None:
        found = self.problems(start, stop, rows)
        if found:
            first, why = found[0]
            more = f" (and {len(found) - 1} more row(s) in {start}..{stop - 1})" if len(found) > 1 else ""
            raise DamagedRecordingError(f"{self.label} row {first} is damaged: {why}{more}; `flexvox info` lists "
                                        "every damaged row", [r for r, _ in found])

    def read(self, start: int, stop: int) -> np.ndarray:
        """Rows ``[start, stop)``, checked."""
        try:
            rows = _read_rows(self.array, start, stop, self.label)
        except DamagedRecordingError as exc:
            found = self.problems(start, stop)
            if not found:
                raise
            first, why = found[0]
            raise DamagedRecordingError(f"{self.label} row {first} is damaged: {why}; `flexvox info` lists every "
                                        "damaged row", [r for r, _ in found]) from exc
        self._check(start, stop, rows)
        return rows

    def __getitem__(self, key):
        rest = ()
        if isinstance(key, tuple):
            key, rest = (key[0], key[1:]) if key else (slice(None), ())
        if key is Ellipsis:
            key, rest = slice(None), (Ellipsis, *rest)
        if isinstance(key, slice):
            start, stop, step = key.indices(self.n)
            rows = self.read(start, max(start, stop)) if step == 1 else self.read(0, self.n)[key]
            return rows[(slice(None), *rest)] if rest else rows
        if not isinstance(key, int | np.integer) or isinstance(key, bool):
            rows = self._rows_of(key)
            return rows[(slice(None), *rest)] if rest else rows
        idx = int(key)
        if not -self.n <= idx < self.n:
            raise IndexError(f"row {idx} is out of range for {self.n} rows")
        row = self.read(idx % self.n, idx % self.n + 1)[0]
        return row[rest] if rest else row

    def _rows_of(self, key) -> np.ndarray:
        """Rows by a list or an array of whole numbers, or of n booleans (as numpy indexes), read from the first
        to the last of them; anything else is an ``IndexError`` naming it (``rows[1.5]`` had been row 1, and a
        list had raised from ``int()``)."""
        idx = np.asarray(key)
        if idx.shape == (0,):  # [] is float64 to numpy
            return self.read(0, 0)
        if idx.dtype == bool and idx.shape == (self.n,):
            idx = np.flatnonzero(idx)
        elif idx.ndim != 1 or idx.dtype.kind not in "iu":
            raise IndexError(f"{self.label} rows are indexed by a whole number, a slice, a list of whole numbers or "
                             f"{self.n} booleans; got {key!r}")
        bad = idx[(idx < -self.n) | (idx >= self.n)]
        if bad.size:
            raise IndexError(f"row {int(bad[0])} is out of range for {self.n} rows")
        if not idx.size:  # a mask of no row
            return self.read(0, 0)
        idx = idx % self.n
        lo = int(idx.min())
        return self.read(lo, int(idx.max()) + 1)[idx - lo]

    def __repr__(self) -> str:
        shape = "x".join(str(v) for v in self.shape)
        return f"<{type(self).__name__} {self.label}: {shape} {self.dtype}, checked as read>"

    def __array__(self, dtype=None, copy=None):
        out = self.read(0, self.n)
        return out if dtype is None else out.astype(dtype)


RowsView = VerifiedRows
"""The name of :class:`VerifiedRows` before checksums."""


def chunk_files_missing(array: zarr.Array, store: Path) -> list[int]:
    """Indexes of a 1-D array's chunks whose file is missing (zarr would read them as zeros)."""
    n_chunks = -(-array.shape[0] // array.chunks[0]) if array.shape[0] else 0
    return [j for j in range(n_chunks)
            if not (store / array.basename / array.metadata.encode_chunk_key((j,))).exists()]

