"""Recordings: a Zarr v3 store (a directory) readable by anyone with zarr, dask or napari.

Layout (schema version 2)::

    REC.zarr/
      zarr.json            group attributes under "flexvox": schema_version, software_version,
                           created_utc, kind (simulated | captured), tile, K, code (m×n×K 0/1),
                           order (identity codes), multiplexed, placement_order, rates
                           {camera_hz, subframe_hz}, effects {name: params}, seed, source,
                           storage {kind: float | counts, ...}, calibration, rig;
                           and under "ome" an OME-Zarr (NGFF 0.5) image description of `frames`
                           (axes t, y, x; t scale = one camera frame in seconds), so generic
                           OME-Zarr readers open the raw frames (flexvox reads only "flexvox")
      frames/              (F, H, W) float32 (relative units) or uint16 counts; one frame per chunk;
                           dimension_names ("t", "y", "x")
      frame_id/            (F,) int64
      timestamp/           (F,) float64, seconds
      dropped/             (F,) bool; a dropped frame is a zero row with its flag set
      frame_crc/           (F,) uint32: CRC-32 of each frame's values (schema 2; see Integrity)
      ground_truth/        (S, H, W) float32, S = F·K — simulated recordings only
      ground_truth_crc/    (S,) uint32: CRC-32 of each ground-truth sub-frame (schema 2)
      frames/capture.journal   only while a capture writes (or after it was killed): see below

Frames are written as they arrive (:class:`RecordingWriter`); every completed frame is a
chunk of its own, so a capture that stops early still leaves the frames it wrote.

Crash safety (a writer killed at any instruction, SIGKILL included)
-------------------------------------------------------------------
Zarr keeps an array's shape in its ``zarr.json``; growing four arrays by one row per frame
rewrites four metadata files per frame, and a process killed between two of them leaves
arrays of different lengths (a damaged recording), or a frame's row allocated before its
chunk is written (a silent black frame). So, while it writes, :class:`RecordingWriter`

1. *allocates in blocks*: the arrays grow by ``block_frames`` rows at a time (metadata is
   rewritten once per block, never per frame); rows past the true count are unwritten
   chunks (zarr's fill value);
2. writes each frame's chunk, *then* appends one 24-byte record (frame id, timestamp,
   dropped flag, CRC-32) to a small append-only journal, ``frames/capture.journal``.
   The record is the commit point: a frame counts once its record is complete. A record
   torn by the kill fails its length or CRC and is ignored, with everything after it;
3. copies the per-frame values into the ``frame_id`` / ``timestamp`` / ``dropped`` arrays
   once per block (so plain zarr readers of a live capture see them, a block late).

:meth:`RecordingWriter.close` writes the remaining per-frame values, trims every array to
the true count, and deletes the journal: a closed recording is plain Zarr with exact
shapes (what older readers and napari expect). A store that still has a journal is an
*interrupted* capture: :func:`open_recording` takes the count and the per-frame values from
the journal (``Recording.interrupted`` is True, ``n_frames`` is the true count and
``frames`` shows exactly those rows), and :func:`recover_recording` finalises it in place.
A reader beside a running capture looks at the frames' rows before and after looking for the
journal, so a capture starting or finishing meanwhile is never seen as a finished recording whose
capacity rows are frames; each array is looked up by name, never by listing the folders, where
zarr's temporary files come and go.

Integrity (schema 2)
--------------------
Every frame carries the CRC-32 of its values as stored (C order, little-endian bytes of the
stored dtype; a dropped frame's zero row included), committed with the frame's journal record
and kept in ``frame_crc``. Every read of frames goes through :class:`VerifiedRows`, which checks
each row it returns against its CRC, so a deleted chunk (which zarr would read as zeros), a
truncated one (a codec error) or a changed one raises :class:`DamagedRecordingError` naming the
rows; nothing reads it as data. :meth:`Recording.verify` checks every row and reports all the
damage. Schema-1 recordings (no CRCs) are still read: there, a row whose chunk file is missing
is refused, and a chunk that decodes to changed values cannot be detected.

One writer (:mod:`flexvox_core.writer_lock`)
--------------------------------------------
A writer holds an OS lock beside the recording for as long as it writes; a second writer, or a
command that would replace the recording, is refused and told which process holds it.

Zarr's own ``LocalStore`` writes every key through a temporary file and a rename (zarr
3.1), so a kill never leaves a torn ``zarr.json`` or chunk; the journal does not depend on
that beyond "a file is old or new". What survives a *power loss* depends on the OS flushing
its page cache: pass ``fsync=True`` (``flexvox capture --durable``) to flush every frame's
chunk, its folders and its journal record to the disk before the next frame (slower; see
``bench/bench_durable.py``).
"""

from __future__ import annotations

import datetime as _dt
import errno
import logging
import os
import struct
import zlib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import zarr

from flexvox_core._version import __version__
from flexvox_core.codes import is_identity_code, order_from_code, validate_code
from flexvox_core.ngff import image_compressor
from flexvox_core.rates import rate_problems

_logger = logging.getLogger(__name__)

SCHEMA_VERSION = 2
"""Bumped when the layout changes in a way older readers cannot follow (2: per-frame CRCs)."""

PER_FRAME = ("frame_id", "timestamp", "dropped")
"""The per-frame arrays every schema has."""
_PER_FRAME_DTYPES = {"frame_id": "int64", "timestamp": "float64", "dropped": "bool", "frame_crc": "uint32"}
_WRITTEN_PER_FRAME = (*PER_FRAME, "frame_crc")
_REQUIRED_ATTRS = ("schema_version", "tile", "K", "code", "rates", "storage")

JOURNAL = "frames/capture.journal"
"""The per-frame journal of a capture being written (absent once the writer closed). It lives in
the ``frames`` array's folder, where zarr never looks for members (a file in the group's own
folder makes zarr warn when it lists the group)."""
_JOURNAL_MAGIC_V1 = b"FLXVJRN1"
_RECORD_V1 = struct.Struct("<qd?3xI")  # frame id, timestamp, dropped, pad, CRC-32 of the first 17 bytes
_JOURNAL_MAGIC = b"FLXVJRN2"
_RECORD = struct.Struct("<qd?3xII")  # ..., the frame's CRC-32, CRC-32 of the first 24 bytes
_JOURNAL_HEADER_SIZE = len(_JOURNAL_MAGIC) + 8  # magic, record size, writer's process id
DEFAULT_BLOCK_FRAMES = 64


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


def values_crc(values: np.ndarray, dtype=None) -> int:
    """CRC-32 of an array's values as stored: C order, little-endian bytes of ``dtype``."""
    arr = np.asarray(values)
    dt = np.dtype(dtype or arr.dtype).newbyteorder("<")
    return zlib.crc32(np.ascontiguousarray(arr, dtype=dt).data) & 0xFFFFFFFF


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def recording_attrs(code, *, rate_hz: float, kind: str, storage: dict, effects: dict | None = None,
                    seed: int | None = None, source: str = "", multiplexed: bool = False,
                    placement=None, calibration=None, rig=None) -> dict:
    """The ``flexvox`` attribute block of a recording."""
    code = validate_code(code)
    m, n, K = code.shape
    identity = is_identity_code(code)
    return {
        "schema_version": SCHEMA_VERSION,
        "software_version": __version__,
        "created_utc": _now(),
        "kind": kind,
        "tile": [m, n],
        "K": K,
        "code": code.astype(int).tolist(),
        "order": order_from_code(code).tolist() if identity else None,
        "multiplexed": bool(multiplexed),
        "placement_order": None if placement is None else np.asarray(placement).tolist(),
        "rates": {"camera_hz": float(rate_hz), "subframe_hz": float(rate_hz) * K},
        "effects": effects or {},
        "seed": seed,
        "source": source,
        "storage": storage,
        "calibration": calibration,
        "rig": rig or {"kind": "simulated" if kind == "simulated" else "unknown"},
    }


FRAME_AXES = ("t", "y", "x")
"""The ``dimension_names`` of ``frames`` (NGFF's axes; recordings written before they were added have none)."""


def frames_ngff(attrs: dict) -> dict:
    """The group's ``ome`` attribute: ``frames`` as an OME-Zarr image whose t step is one camera frame."""
    from flexvox_core import ngff

    rate = (attrs.get("rates") or {}).get("camera_hz")
    return ngff.image_attrs("frames", time_step=1.0 / float(rate) if rate else None, name="frames")


class RecordingWriter:
    """Append frames to a new recording as they arrive, crash-safely (see the module docstring).

    Each :meth:`append` writes the frame's chunk, then commits it with a journal record that
    carries the frame's CRC, so a recording interrupted at any point (an exception, SIGKILL, a
    full disk) holds every completed frame and opens with :func:`open_recording`. Call
    :meth:`close` (or use the writer as a context manager) to finalise: exact array shapes,
    journal removed. The writer holds the recording's :class:`~flexvox_core.writer_lock.WriterLock`
    from its creation until :meth:`close` or :meth:`discard`.

    Parameters
    ----------
    path : str or Path
        The store (a directory) to create.
    height, width : int
        Frame size.
    dtype : {"float32", "uint16"}
        Frame storage type.
    attrs : dict
        The ``flexvox`` attribute block (:func:`recording_attrs`).
    overwrite : bool
        Replace an existing store. The old store is moved aside (a hidden sibling) and deleted
        only when this one closes with frames in it; a writer that ends with none puts it back.
    block_frames : int
        Rows allocated at a time (metadata writes per frame: 1 / block_frames).
    fsync : bool
        Durable writes: every frame's chunk, its folders and its journal record are flushed to
        the disk before :meth:`append` returns (a power cut loses at most the frame in flight).
    atomic : bool
        Write the whole store in a hidden temporary sibling and move it into place at
        :meth:`close` (recordings written at once, such as simulations): readers never see a
        partial store, and a failed write (:meth:`discard`) leaves the old one untouched.
        Default False: a capture writes in place, so that what it wrote is there if it is killed.
    lock : WriterLock, optional
        The recording's lock, already held by the caller (a capture takes it before it sets up
        the devices); the caller keeps it and releases it. Default: the writer takes its own.

    Raises
    ------
    RecordingError
        For a bad argument, or a path that exists (without ``overwrite``).
    OSError
        When the store cannot be created (a full disk, a file-size limit): what the writer had
        made of it is removed and a store it was to replace is put back, so nothing is left that
        would read as a damaged recording.
    """

    def __init__(self, path, *, height: int, width: int, dtype, attrs: dict, overwrite: bool = False,
                 block_frames: int = DEFAULT_BLOCK_FRAMES, fsync: bool = False, atomic: bool = False,
                 lock=None):
        from flexvox_core.output_files import refuse_other_kind, temporary_sibling
        from flexvox_core.writer_lock import WriterLock

        self.path = Path(path)
        dtype = np.dtype(dtype)
        if dtype not in (np.dtype("float32"), np.dtype("uint16")):
            raise RecordingError(f"frames must be float32 or uint16; got {dtype}")
        if isinstance(block_frames, bool) or not isinstance(block_frames, int) or not 1 <= block_frames <= 65536:
            raise RecordingError(f"`block_frames` must be a whole number 1..65536; got {block_frames!r}")
        if lock is not None:
            if not (lock.held and lock.path.resolve() == self.path.expanduser().resolve()):
                raise RecordingError(f"`lock` must be the held lock of {self.path}")
            self._lock, self._own_lock = lock, False
        else:  # OutputBusyError (a ValueError) names the holder
            self._lock, self._own_lock = WriterLock(self.path).acquire(), True
        self._fd = None
        self._replaced: Path | None = None
        self._atomic = bool(atomic)
        self.store: Path | None = None
        try:
            if (self.path.exists() or self.path.is_symlink()) and not overwrite:
                raise RecordingError(f"{self.path} already exists; choose another path or allow overwriting")
            if self.path.exists():
                refuse_other_kind(self.path, "store")  # never a file, or a folder that is not a Zarr store
            if self._atomic:
                store = temporary_sibling(self.path)
            else:
                if self.path.exists() or self.path.is_symlink():
                    self._replaced = temporary_sibling(self.path, "replaced")
                    os.rename(self.path, self._replaced)
                store = self.path
            if store.exists() or store.is_symlink():  # appeared since the check (another program): not ours
                raise RecordingError(f"{store} already exists; choose another path or allow overwriting")
            self.store = store  # from here on the store is this writer's own: a failed start removes it
            # The frames are also an OME-Zarr image (NGFF 0.5: axes t, y, x; t = one camera frame), so
            # generic OME-Zarr readers open the raw coded frames; flexvox's own block stays under "flexvox".
            self.group = zarr.open_group(str(self.store), mode="w-", zarr_format=3,
                                         attributes={"flexvox": attrs, "ome": frames_ngff(attrs)})
            self.frames = self.group.create_array("frames", shape=(0, height, width), chunks=(1, height, width),
                                                  dtype=dtype, fill_value=0, dimension_names=FRAME_AXES)
            self.per_frame = {
                name: self.group.create_array(name, shape=(0,), chunks=(4096,), dtype=_PER_FRAME_DTYPES[name],
                                              fill_value=0)
                for name in _WRITTEN_PER_FRAME
            }
            self.count = 0
            self.capacity = 0
            self.closed = False
            self._block = block_frames
            self._fsync = bool(fsync)
            self._hw = (height, width)
            self._dtype = dtype
            self._zero_crc = values_crc(np.zeros((height, width), dtype))
            self._flushed = 0
            self._pending = {name: [] for name in _WRITTEN_PER_FRAME}
            self._root_id = _identity(self.store)
            self._journal_path = self.store / JOURNAL
            self._fd = os.open(self._journal_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
            self._write_all(_JOURNAL_MAGIC + struct.pack("<II", _RECORD.size, os.getpid() & 0xFFFFFFFF))
            if self._fsync:
                self._sync_metadata()
        except BaseException:
            # Nothing was committed: the store this writer made goes (a folder left half-made would read as a
            # damaged recording), and a replaced one is put back.
            self._abandon(remove_store=True)
            raise

    # -- writing
    def _write_all(self, data: bytes) -> None:
        written = os.write(self._fd, data)
        if written != len(data):  # a short write: the disk is full
            raise OSError(errno.ENOSPC, f"short write to {self._journal_path} ({written} of {len(data)} bytes)")
        if self._fsync:
            os.fsync(self._fd)

    def _sync_file(self, path: Path, folders: int = 1) -> None:
        """Flush a file and the ``folders`` folders above it (their new entries) to the disk."""
        from flexvox_core.output_files import fsync_folder

        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        for parent in list(path.parents)[:folders]:
            fsync_folder(parent)

    def _sync_metadata(self) -> None:
        """Durable mode: flush every array's metadata (its shape) and the store's folders."""
        self._sync_file(self.store / "zarr.json", folders=2)
        for name in ("frames", *_WRITTEN_PER_FRAME):
            self._sync_file(self.store / name / "zarr.json", folders=1)
        self._sync_file(self._journal_path, folders=1)

    def _check_root(self) -> None:
        if _identity(self.store) != self._root_id:
            raise FileNotFoundError(errno.ENOENT, f"the recording folder {self.store} vanished (deleted, or its "
                                                  "disk was unmounted)")

    def _flush_per_frame(self) -> None:
        """Copy pending per-frame values into the zarr arrays (rows ``[flushed, count)``)."""
        if self.count == self._flushed:
            return
        for name in _WRITTEN_PER_FRAME:
            values = np.asarray(self._pending[name], dtype=_PER_FRAME_DTYPES[name])
            self.per_frame[name][self._flushed:self.count] = values
            self._pending[name] = []
        self._flushed = self.count

    def _grow(self, rows: int) -> None:
        self._flush_per_frame()
        self.frames.resize((rows, *self._hw))
        for arr in self.per_frame.values():
            arr.resize((rows,))
        self.capacity = rows
        if self._fsync:
            self._sync_metadata()

    def append(self, frame, *, frame_id: int, timestamp: float, dropped: bool = False) -> None:
        """Write one camera frame ``(H, W)`` and commit it with its per-frame values and CRC.

        A dropped frame is a zero row: pass ``frame=None`` (nothing is written but its record).

        Raises
        ------
        RecordingError
            For a frame of the wrong shape, or a closed writer.
        OSError
            When the disk refuses the write (full disk, vanished folder); every frame
            committed before it stays readable.
        """
        if self.closed:
            raise RecordingError(f"{self.path}: the writer is closed")
        if frame is not None:
            frame = np.asarray(frame)
            if frame.shape != self._hw:
                raise RecordingError(f"frame must have shape {self._hw}; got {frame.shape}")
        self._check_root()
        i = self.count
        if i >= self.capacity:
            self._grow(self.capacity + self._block)
        crc = self._zero_crc
        if frame is not None and not (dropped and not frame.any()):
            stored = frame.astype(self._dtype, copy=False)
            self.frames[i] = stored
            crc = values_crc(stored)
            if self._fsync and crc != self._zero_crc:  # zarr writes no chunk for an all-zero frame
                # the chunk, and every folder that names it: c/i/0, c/i, c and frames
                self._sync_file(self.store / "frames" / self.frames.metadata.encode_chunk_key((i, 0, 0)), folders=4)
        head = struct.pack("<qd?3xI", int(frame_id), float(timestamp), bool(dropped), crc)
        self._write_all(head + struct.pack("<I", zlib.crc32(head)))
        self._pending["frame_id"].append(int(frame_id))
        self._pending["timestamp"].append(float(timestamp))
        self._pending["dropped"].append(bool(dropped))
        self._pending["frame_crc"].append(crc)
        self.count = i + 1

    def write_ground_truth(self, video: np.ndarray) -> None:
        """Store the simulated ground truth ``(S, H, W)`` float32 (with a CRC per sub-frame)."""
        video = np.asarray(video, dtype=np.float32)
        gt, crc = self._ground_truth_arrays(video.shape[0])
        gt[:] = video
        crc[:] = np.asarray([values_crc(v) for v in video], np.uint32)

    def _ground_truth_arrays(self, S: int):
        shape = (S, *self._hw)
        # Compressed as the reconstructions are (read 3x faster than zarr's default Zstd at the same size: the
        # PSNR of every `flexvox reconstruct` reads it whole).
        gt = self.group.create_array("ground_truth", shape=shape, chunks=(1, *self._hw), dtype="float32",
                                     fill_value=0, compressors=image_compressor())
        crc = self.group.create_array("ground_truth_crc", shape=(S,), chunks=(max(1, min(S, 65536)),),
                                      dtype="uint32", fill_value=0)
        return gt, crc

    def write_ground_truth_frames(self, rows) -> None:
        """Store the ground truth one camera frame at a time: ``rows`` yields ``(K, H, W)``
        blocks, one per recorded frame (so a long capture never holds it all in memory)."""
        K = int(dict(self.group.attrs)["flexvox"]["K"])
        gt, crc = self._ground_truth_arrays(self.count * K)
        done = 0
        crcs = []
        for block in rows:
            block = np.asarray(block, dtype=np.float32)
            if block.shape != (K, *self._hw):
                raise RecordingError(f"ground-truth rows must have shape {(K, *self._hw)}; got {block.shape}")
            gt[done * K:(done + 1) * K] = block
            crcs.extend(values_crc(v) for v in block)
            done += 1
        if done != self.count:
            raise RecordingError(f"ground truth for {done} frames; the recording holds {self.count}")
        crc[:] = np.asarray(crcs, np.uint32)

    def close(self, *, attrs_update: dict | None = None) -> None:
        """Finalise: per-frame arrays written, arrays trimmed to the count, journal removed.

        ``attrs_update`` is merged into the ``flexvox`` attributes first. An atomic writer then
        moves the store into place; an overwriting one deletes the store it replaced (or puts it
        back when no frame was written). No-op when closed. On an error (a full disk) the journal
        stays and the recording remains valid (an atomic writer's store is removed instead, and
        the old one stays).
        """
        if self.closed:
            return
        from flexvox_core.output_files import move_into_place, remove_path

        try:
            self._check_root()
            if attrs_update:
                self.group.attrs["flexvox"] = {**dict(self.group.attrs)["flexvox"], **attrs_update}
            self._flush_per_frame()
            if self.capacity != self.count:
                self.frames.resize((self.count, *self._hw))
                for arr in self.per_frame.values():
                    arr.resize((self.count,))
                self.capacity = self.count
            os.close(self._fd)
            self._fd = None
            self._journal_path.unlink()
            if self._fsync:
                self._sync_file(self.store / "zarr.json", folders=2)
            if self._atomic:
                move_into_place(self.store, self.path)
            elif self._replaced is not None:
                if self.count:
                    remove_path(self._replaced)
                else:
                    remove_path(self.store)
                    os.rename(self._replaced, self.path)
                self._replaced = None
        except BaseException:
            if self._atomic:
                remove_path(self.store)
            raise
        finally:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
            self.closed = True
            if self._own_lock:
                self._lock.release()

    def discard(self) -> None:
        """Give up an unfinished write: an atomic writer's store is removed and an overwritten
        store is put back; a capture that replaced nothing keeps its store as it is (interrupted, readable)."""
        if not self.closed:
            self._abandon()

    def _abandon(self, *, remove_store: bool = False) -> None:
        """Close the journal, remove the store where it replaces another or is written aside (or
        ``remove_store``: a start that failed), and put a replaced store back."""
        from flexvox_core.output_files import remove_path

        try:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
            if self.store is not None and (remove_store or self._atomic or self._replaced is not None):
                remove_path(self.store)
            if self._replaced is not None:
                os.rename(self._replaced, self.path)
                self._replaced = None
        finally:
            self.closed = True
            if self._own_lock:
                self._lock.release()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is not None and self._atomic:
            self.discard()
        else:
            self.close()


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return st.st_dev, st.st_ino


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
    body = memoryview(data)[_JOURNAL_HEADER_SIZE:]
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


def write_simulation(path, result, *, overwrite: bool = False) -> Path:
    """Write a :class:`~flexvox_core.simulate.SimulationResult` as a recording, atomically: the
    store appears at ``path`` complete, or not at all (an old one stays when the write fails)."""
    F, H, W = result.frames.shape
    attrs = recording_attrs(
        result.code, rate_hz=result.rate_hz, kind="simulated", storage=result.storage,
        effects=result.effects, seed=result.seed, source=result.source,
        multiplexed=result.multiplexed, placement=result.placement,
    )
    period = 1.0 / result.rate_hz
    with RecordingWriter(path, height=H, width=W, dtype=result.frames.dtype, attrs=attrs, overwrite=overwrite,
                         atomic=True) as writer:
        for f in range(F):
            writer.append(result.frames[f], frame_id=f, timestamp=f * period, dropped=bool(result.dropped[f]))
        writer.write_ground_truth(result.ground_truth)
    return Path(path)


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
        idx = int(key)
        if not -self.n <= idx < self.n:
            raise IndexError(f"row {idx} is out of range for {self.n} rows")
        row = self.read(idx % self.n, idx % self.n + 1)[0]
        return row[rest] if rest else row

    def __array__(self, dtype=None, copy=None):
        out = self.read(0, self.n)
        return out if dtype is None else out.astype(dtype)


RowsView = VerifiedRows
"""The name of :class:`VerifiedRows` before checksums."""


def _chunk_files_missing(array: zarr.Array, store: Path) -> list[int]:
    """Indexes of a 1-D array's chunks whose file is missing (zarr would read them as zeros)."""
    n_chunks = -(-array.shape[0] // array.chunks[0]) if array.shape[0] else 0
    return [j for j in range(n_chunks)
            if not (store / array.basename / array.metadata.encode_chunk_key((j,))).exists()]


@dataclass
class Recording:
    """An opened, validated recording.

    ``journal`` holds the committed per-frame values of an *interrupted* capture (a store
    whose writer never closed, see the module docstring); it is None for a finished one.
    """

    path: Path
    group: zarr.Group
    attrs: dict
    journal: dict | None = field(default=None, repr=False)
    rows: int | None = field(default=None, repr=False)
    """The frames' rows when it was opened (a finished recording's count); None: read them now."""

    @property
    def interrupted(self) -> bool:
        """True when the capture writing this recording did not finish (journal present)."""
        return self.journal is not None

    @property
    def has_checksums(self) -> bool:
        """True when every frame carries a CRC (schema 2 and later)."""
        if self.journal is not None:
            return self.journal.get("frame_crc") is not None
        return "frame_crc" in self.group

    @cached_property
    def frames(self) -> VerifiedRows:
        """The raw frames ``(F, H, W)`` as stored (float32 or uint16 counts), checked as they are read.

        Exactly the committed rows (an interrupted capture may have rows allocated past them), as
        they were when the recording was opened.
        """
        crcs = None
        if self.has_checksums:
            crcs = self.journal["frame_crc"] if self.journal is not None else np.asarray(self.group["frame_crc"][:])
        return VerifiedRows(self.group["frames"], self.n_frames, crcs=crcs, what="frames",
                            store=self.path, required=None if crcs is not None else ~self.per_frame("dropped"))

    @property
    def code(self) -> np.ndarray:
        """The code ``(m, n, K)`` bool."""
        return np.asarray(self.attrs["code"], dtype=bool)

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per frame."""
        return int(self.attrs["K"])

    @property
    def n_frames(self) -> int:
        """Camera frames stored (committed frames of an interrupted capture)."""
        if self.journal is not None:
            return min(len(self.journal["frame_id"]), int(self.group["frames"].shape[0]))
        if self.rows is not None:  # as seen when opened: a capture starting since cannot add rows to it
            return self.rows
        return int(self.group["frames"].shape[0])

    @property
    def has_ground_truth(self) -> bool:
        """True for simulated recordings that hold the high-speed video."""
        return "ground_truth" in self.group

    def per_frame(self, name: str) -> np.ndarray:
        """``frame_id``, ``timestamp``, ``dropped`` (or ``frame_crc``, schema 2) as a numpy array."""
        if name not in _WRITTEN_PER_FRAME:
            raise RecordingError(f"`name` must be one of {', '.join(_WRITTEN_PER_FRAME)}; got {name!r}")
        if self.journal is not None:
            values = self.journal.get(name)
            if values is None:
                raise RecordingError(f"{self.path} has no `{name}` (schema 1)")
            return values[: self.n_frames].copy()
        if name not in self.group:
            raise RecordingError(f"{self.path} has no `{name}` (schema {self.attrs.get('schema_version')})")
        return np.asarray(self.group[name][:])

    @property
    def ground_truth_rows(self) -> VerifiedRows:
        """The simulated high-speed video ``(S, H, W)`` float32, checked as it is read."""
        if not self.has_ground_truth:
            raise RecordingError(f"{self.path} holds no ground truth (a captured recording)")
        gt = self.group["ground_truth"]
        crcs = np.asarray(self.group["ground_truth_crc"][:]) if "ground_truth_crc" in self.group else None
        return VerifiedRows(gt, gt.shape[0], crcs=crcs, what="ground truth", store=self.path)

    def ground_truth(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Sub-frames ``[start, stop)`` of the simulated high-speed video ``(S, H, W)`` float32."""
        rows = self.ground_truth_rows
        return rows.read(start, rows.n if stop is None else stop)

    def normalised_frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``[start, stop)`` as float32 relative units (counts converted)."""
        from flexvox_core.simulate.simulator import normalise_frames

        return normalise_frames(np.asarray(self.frames[start:stop]), self.attrs["storage"])

    def _per_frame_gaps(self) -> list[str]:
        """Checksum chunks whose file is missing (zarr reads them as zeros). Only ``frame_crc`` is checked:
        zarr writes no chunk whose values all equal the fill value, which ``dropped`` (all False) and a
        one-frame ``frame_id`` legitimately are, while a chunk of CRCs that are all 0 does not occur."""
        if self.journal is not None:
            return []  # an interrupted capture's per-frame values come from its journal
        lines = []
        for name in ("frame_crc",):
            if name in self.group:
                arr = self.group[name]
                for j in _chunk_files_missing(arr, self.path):
                    a, b = j * arr.chunks[0], min(arr.shape[0], (j + 1) * arr.chunks[0]) - 1
                    lines.append(f"per-frame array `{name}` rows {a}..{b}: its chunk file is missing (it reads as "
                                 "zeros)")
        return lines

    def verify(self, progress=None, *, chunk_rows: int = 16) -> list[str]:
        """Check every committed frame (and ground-truth sub-frame): each chunk exists, decodes, matches its
        CRC and holds no NaN or inf. Returns one line per damaged row (empty when all are sound).

        ``progress(done, total)`` is called as rows are checked (rows of frames and ground truth).
        """
        parts = [self.frames] + ([self.ground_truth_rows] if self.has_ground_truth else [])
        total = sum(p.n for p in parts)
        done = 0
        found = self._per_frame_gaps()
        for part in parts:
            for start in range(0, part.n, chunk_rows):
                stop = min(part.n, start + chunk_rows)
                found += [f"{part.what} row {row}: {why}" for row, why in part.problems(start, stop)]
                done += stop - start
                if progress is not None:
                    progress(done, total)
        if not self.has_checksums:
            found.append("no checksums (schema 1): missing chunks were checked, changed values cannot be")
        return found


def open_recording(path) -> Recording:
    """Open and validate a recording's structure; :class:`RecordingError` says what is wrong.

    Frames are checked as they are read (:attr:`Recording.frames`); :meth:`Recording.verify`
    checks them all.
    """
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such recording")
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:  # zarr raises several types for a damaged store
        raise RecordingError(f"{path}: not a readable Zarr store ({type(exc).__name__}: {exc})") from exc
    attrs = dict(group.attrs).get("flexvox")
    if not isinstance(attrs, dict):
        raise RecordingError(f"{path}: not a flexvox recording (no `flexvox` attributes)")
    version = attrs.get("schema_version")
    if version is None:
        raise RecordingError(f"{path}: the recording has no schema_version; it was not written by flexvox")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise RecordingError(f"{path}: schema version {version!r} is not a whole number >= 1; the recording's "
                             "metadata is damaged")
    if version > SCHEMA_VERSION:
        raise RecordingError(
            f"{path}: schema version {version!r} is newer than this software reads ({SCHEMA_VERSION}); "
            "update flexvox"
        )
    for _ in range(SNAPSHOT_TRIES):
        journal, rows = _journal_snapshot(path, group)
        rec = Recording(path, group, attrs, journal, rows)
        problems = validate_recording(rec)
        # Seen without a journal, and one there now: a capture started while this looked (its per-frame arrays may
        # already have grown past the rows seen). Look again rather than call it damaged.
        if not (problems and journal is None and (path / JOURNAL).exists()):
            break
    if problems:
        raise RecordingError(f"{path}: " + "; ".join(problems))
    if journal is not None:
        _logger.info("%s: an interrupted capture; %d committed frames", path, len(journal["frame_id"]))
    return rec


SNAPSHOT_TRIES = 5
"""Times :func:`open_recording` looks again at a recording whose frames changed while it looked."""


def _journal_snapshot(path: Path, group):
    """(journal, rows): the capture journal's committed records and None, or None and the frames' rows of a
    finished recording, seen consistently with each other.

    A writer creates the journal before it first grows the frames and removes it after trimming them to the
    count. So the frames' rows are read before and after looking for the journal: with a journal, the rows were
    read while it existed; without one, equal rows mean a finished recording (a capture starting between the
    two reads would show its first block of empty rows as frames, one finishing its capacity).
    """
    def rows():
        try:
            return group["frames"].shape[0]
        except KeyError:  # no frames array (yet): validate_recording says so
            return None

    for _ in range(SNAPSHOT_TRIES):
        before = rows()
        if (path / JOURNAL).exists():
            try:
                return read_journal(path / JOURNAL), None
            except FileNotFoundError:  # the capture finished meanwhile: look again
                continue
            except OSError as exc:
                raise RecordingError(f"{path}: cannot read the capture journal ({exc})") from exc
        if rows() == before:
            return None, before
    raise RecordingError(f"{path}: the recording changed while it was opened {SNAPSHOT_TRIES} times (a capture "
                         "starting or finishing in it); open it again")


def validate_recording(rec: Recording) -> list[str]:
    """Structural problems of a recording (empty when it is sound)."""
    problems = []
    missing = [k for k in _REQUIRED_ATTRS if k not in rec.attrs]
    if missing:
        return [f"missing attribute(s): {', '.join(missing)}"]
    try:
        code = validate_code(rec.attrs["code"])
    except ValueError as exc:
        return [f"bad code attribute: {exc}"]
    m, n, K = code.shape
    if [m, n] != list(rec.attrs["tile"]) or K != rec.attrs["K"]:
        problems.append(f"code shape {code.shape} disagrees with tile {rec.attrs['tile']} and K {rec.attrs['K']}")
    problems += rate_problems(rec.attrs["rates"], K)
    if not rec.attrs.get("multiplexed") and not is_identity_code(code):
        problems.append("the code opens pixels in more than one slot (or slots for more than one pixel), but the "
                        "recording is not marked `multiplexed`: no reconstruction can tell what its frames hold")
    # Each array looked up by name, never by listing the folder: a capture writing beside this reader renames
    # zarr's temporary metadata files into place, and a listing that meets one as it vanishes fails.
    needed = ("frames", *PER_FRAME) + (("frame_crc",) if rec.attrs["schema_version"] >= 2 else ())
    for name in needed:
        if name not in rec.group:
            problems.append(f"array `{name}` is missing")
    has_gt, has_gt_crc = ("ground_truth" in rec.group), ("ground_truth_crc" in rec.group)  # each a read: once
    if has_gt and rec.attrs["schema_version"] >= 2 and not has_gt_crc:
        problems.append("array `ground_truth_crc` is missing")
    if problems:
        return problems
    F = rec.n_frames
    if rec.group["frames"].ndim != 3:
        problems.append(f"`frames` must be (F, H, W); got {rec.group['frames'].shape}")
    if rec.journal is None:
        for name in needed[1:]:
            if rec.group[name].shape != (F,):
                problems.append(f"`{name}` has {rec.group[name].shape[0]} entries for {F} frames")
    elif rec.attrs["schema_version"] >= 2 and rec.journal["frame_crc"] is None:
        problems.append("the capture journal has no frame checksums (schema 1) in a schema-2 recording")
    kind = rec.attrs["storage"].get("kind")
    if kind not in ("float", "counts"):
        problems.append(f"unknown storage kind {kind!r}")
    if has_gt:
        gt = rec.group["ground_truth"].shape
        if gt != (F * K, *rec.group["frames"].shape[1:]):
            problems.append(f"`ground_truth` {gt} does not match {F} frames of K = {K}")
        elif has_gt_crc and rec.group["ground_truth_crc"].shape != (gt[0],):
            problems.append(f"`ground_truth_crc` has {rec.group['ground_truth_crc'].shape[0]} entries for {gt[0]} "
                            "sub-frames")
    return problems


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
        for name in _WRITTEN_PER_FRAME:
            values = rec.journal.get(name)
            if values is None or name not in group:
                continue
            arr = group[name]
            arr.resize((n,))
            arr[:] = values[:n]
        if frames.shape[0] != n:
            frames.resize((n, *frames.shape[1:]))
        attrs = dict(group.attrs)["flexvox"]
        group.attrs["flexvox"] = {**attrs, "recovered_utc": _now()}
        (rec.path / JOURNAL).unlink()
        _logger.info("%s: recovered an interrupted capture of %d frames", rec.path, n)
        return n
