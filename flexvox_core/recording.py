"""Recordings: a Zarr v3 store (a directory) readable by anyone with zarr, dask or napari.

Layout (schema version 1)::

    REC.zarr/
      zarr.json            group attributes under "flexvox": schema_version, software_version,
                           created_utc, kind (simulated | captured), tile, K, code (m×n×K 0/1),
                           order (identity codes), multiplexed, placement_order, rates
                           {camera_hz, subframe_hz}, effects {name: params}, seed, source,
                           storage {kind: float | counts, ...}, calibration, rig
      frames/              (F, H, W) float32 (relative units) or uint16 counts; one frame per chunk
      frame_id/            (F,) int64
      timestamp/           (F,) float64, seconds
      dropped/             (F,) bool; a dropped frame is a zero row with its flag set
      ground_truth/        (S, H, W) float32, S = F·K — simulated recordings only
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

Zarr's own ``LocalStore`` writes every key through a temporary file and a rename (zarr
3.1), so a kill never leaves a torn ``zarr.json`` or chunk; the journal does not depend on
that beyond "a file is old or new". What survives a *power loss* depends on the OS flushing
its page cache: pass ``fsync=True`` to flush the journal at every frame (slower).
"""

from __future__ import annotations

import datetime as _dt
import errno
import logging
import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import zarr

from flexvox_core._version import __version__
from flexvox_core.codes import is_identity_code, order_from_code, validate_code

_logger = logging.getLogger(__name__)

SCHEMA_VERSION = 1
"""Bumped when the layout changes in a way older readers cannot follow."""

PER_FRAME = ("frame_id", "timestamp", "dropped")
_PER_FRAME_DTYPES = {"frame_id": "int64", "timestamp": "float64", "dropped": "bool"}
_REQUIRED_ATTRS = ("schema_version", "tile", "K", "code", "rates", "storage")

JOURNAL = "frames/capture.journal"
"""The per-frame journal of a capture being written (absent once the writer closed). It lives in
the ``frames`` array's folder, where zarr never looks for members (a file in the group's own
folder makes zarr warn when it lists the group)."""
_JOURNAL_MAGIC = b"FLXVJRN1"
_JOURNAL_HEADER = _JOURNAL_MAGIC + struct.pack("<II", 24, 0)  # magic, record size, reserved
_RECORD = struct.Struct("<qd?3xI")  # frame id, timestamp, dropped, pad, CRC-32 of the first 17 bytes
DEFAULT_BLOCK_FRAMES = 64


class RecordingError(ValueError):
    """A recording that cannot be read or is damaged; the message says what is wrong."""


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


class RecordingWriter:
    """Append frames to a new recording as they arrive, crash-safely (see the module docstring).

    Each :meth:`append` writes the frame's chunk, then commits it with a journal record, so a
    recording interrupted at any point (an exception, SIGKILL, a full disk) holds every
    completed frame and opens with :func:`open_recording`. Call :meth:`close` (or use the
    writer as a context manager) to finalise: exact array shapes, journal removed.

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
        Replace an existing store.
    block_frames : int
        Rows allocated at a time (metadata writes per frame: 1 / block_frames).
    fsync : bool
        Flush the journal to the device at every frame (power-loss safety; slower).
    """

    def __init__(self, path, *, height: int, width: int, dtype, attrs: dict, overwrite: bool = False,
                 block_frames: int = DEFAULT_BLOCK_FRAMES, fsync: bool = False):
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise RecordingError(f"{self.path} already exists; choose another path or allow overwriting")
        dtype = np.dtype(dtype)
        if dtype not in (np.dtype("float32"), np.dtype("uint16")):
            raise RecordingError(f"frames must be float32 or uint16; got {dtype}")
        if isinstance(block_frames, bool) or not isinstance(block_frames, int) or not 1 <= block_frames <= 65536:
            raise RecordingError(f"`block_frames` must be a whole number 1..65536; got {block_frames!r}")
        self.group = zarr.open_group(str(self.path), mode="w", zarr_format=3)
        self.group.attrs["flexvox"] = attrs
        self.frames = self.group.create_array("frames", shape=(0, height, width), chunks=(1, height, width),
                                              dtype=dtype, fill_value=0)
        self.per_frame = {
            name: self.group.create_array(name, shape=(0,), chunks=(4096,), dtype=_PER_FRAME_DTYPES[name],
                                          fill_value=0)
            for name in PER_FRAME
        }
        self.count = 0
        self.capacity = 0
        self.closed = False
        self._block = block_frames
        self._fsync = bool(fsync)
        self._hw = (height, width)
        self._dtype = dtype
        self._flushed = 0
        self._pending = {name: [] for name in PER_FRAME}
        self._root_id = _identity(self.path)
        self._journal_path = self.path / JOURNAL
        self._fd = os.open(self._journal_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
        self._write_all(_JOURNAL_HEADER)

    # -- writing
    def _write_all(self, data: bytes) -> None:
        written = os.write(self._fd, data)
        if written != len(data):  # a short write: the disk is full
            raise OSError(errno.ENOSPC, f"short write to {self._journal_path} ({written} of {len(data)} bytes)")
        if self._fsync:
            os.fsync(self._fd)

    def _check_root(self) -> None:
        if _identity(self.path) != self._root_id:
            raise FileNotFoundError(errno.ENOENT, f"the recording folder {self.path} vanished (deleted, or its "
                                                  "disk was unmounted)")

    def _flush_per_frame(self) -> None:
        """Copy pending per-frame values into the zarr arrays (rows ``[flushed, count)``)."""
        if self.count == self._flushed:
            return
        for name in PER_FRAME:
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

    def append(self, frame, *, frame_id: int, timestamp: float, dropped: bool = False) -> None:
        """Write one camera frame ``(H, W)`` and commit it with its per-frame values.

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
        if frame is not None and not (dropped and not frame.any()):
            self.frames[i] = frame.astype(self._dtype, copy=False)
        head = struct.pack("<qd?", int(frame_id), float(timestamp), bool(dropped))
        self._write_all(_RECORD.pack(int(frame_id), float(timestamp), bool(dropped), zlib.crc32(head)))
        self._pending["frame_id"].append(int(frame_id))
        self._pending["timestamp"].append(float(timestamp))
        self._pending["dropped"].append(bool(dropped))
        self.count = i + 1

    def write_ground_truth(self, video: np.ndarray) -> None:
        """Store the simulated ground truth ``(S, H, W)`` float32."""
        video = np.asarray(video, dtype=np.float32)
        gt = self.group.create_array("ground_truth", shape=video.shape, chunks=(1, *video.shape[1:]),
                                     dtype="float32", fill_value=0)
        gt[:] = video

    def write_ground_truth_frames(self, rows) -> None:
        """Store the ground truth one camera frame at a time: ``rows`` yields ``(K, H, W)``
        blocks, one per recorded frame (so a long capture never holds it all in memory)."""
        K = int(dict(self.group.attrs)["flexvox"]["K"])
        gt = self.group.create_array("ground_truth", shape=(self.count * K, *self._hw), chunks=(1, *self._hw),
                                     dtype="float32", fill_value=0)
        done = 0
        for block in rows:
            block = np.asarray(block, dtype=np.float32)
            if block.shape != (K, *self._hw):
                raise RecordingError(f"ground-truth rows must have shape {(K, *self._hw)}; got {block.shape}")
            gt[done * K:(done + 1) * K] = block
            done += 1
        if done != self.count:
            raise RecordingError(f"ground truth for {done} frames; the recording holds {self.count}")

    def close(self, *, attrs_update: dict | None = None) -> None:
        """Finalise: per-frame arrays written, arrays trimmed to the count, journal removed.

        ``attrs_update`` is merged into the ``flexvox`` attributes first. No-op when closed.
        On an error (a full disk) the journal stays and the recording remains valid.
        """
        if self.closed:
            return
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
        finally:
            if self._fd is not None:
                os.close(self._fd)
                self._fd = None
            self.closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return st.st_dev, st.st_ino


def read_journal(path) -> dict:
    """The committed records of a capture journal: ``frame_id``, ``timestamp``, ``dropped``.

    Records after the first torn or corrupt one are ignored (a kill mid-write leaves at most
    one torn record, at the end).

    Raises
    ------
    RecordingError
        When the file is not a flexvox journal.
    """
    path = Path(path)
    data = path.read_bytes()
    if data[:len(_JOURNAL_MAGIC)] != _JOURNAL_MAGIC:
        raise RecordingError(f"{path}: not a flexvox capture journal")
    body = memoryview(data)[len(_JOURNAL_HEADER):]
    n_full = len(body) // _RECORD.size
    ids, stamps, drops = [], [], []
    for k in range(n_full):
        fid, ts, dr, crc = _RECORD.unpack_from(body, k * _RECORD.size)
        if zlib.crc32(bytes(body[k * _RECORD.size: k * _RECORD.size + 17])) != crc:
            _logger.warning("%s: record %d is corrupt; %d later record(s) ignored", path, k, n_full - k - 1)
            break
        ids.append(fid)
        stamps.append(ts)
        drops.append(dr)
    if len(body) % _RECORD.size:
        _logger.info("%s: a torn last record (%d bytes) is ignored", path, len(body) % _RECORD.size)
    return {"frame_id": np.asarray(ids, np.int64), "timestamp": np.asarray(stamps, np.float64),
            "dropped": np.asarray(drops, bool)}


def write_simulation(path, result, *, overwrite: bool = False) -> Path:
    """Write a :class:`~flexvox_core.simulate.SimulationResult` as a recording."""
    F, H, W = result.frames.shape
    attrs = recording_attrs(
        result.code, rate_hz=result.rate_hz, kind="simulated", storage=result.storage,
        effects=result.effects, seed=result.seed, source=result.source,
        multiplexed=result.multiplexed, placement=result.placement,
    )
    writer = RecordingWriter(path, height=H, width=W, dtype=result.frames.dtype, attrs=attrs, overwrite=overwrite)
    period = 1.0 / result.rate_hz
    for f in range(F):
        writer.append(result.frames[f], frame_id=f, timestamp=f * period, dropped=bool(result.dropped[f]))
    writer.write_ground_truth(result.ground_truth)
    writer.close()
    return Path(path)


class RowsView:
    """The first ``n`` rows of a zarr array, read lazily (an interrupted capture's frames).

    Offers what readers use of a ``zarr.Array``: ``shape``, ``dtype``, ``ndim``,
    ``chunks``, ``len`` and indexing (``[:]``, ``[i]``, ``[a:b]``, ``[a:b, y, x]``).
    """

    def __init__(self, array: zarr.Array, n: int):
        self.array = array
        self.n = int(n)

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

    def __getitem__(self, key):
        rest = ()
        if isinstance(key, tuple):
            key, rest = (key[0], key[1:]) if key else (slice(None), ())
        if key is Ellipsis:
            key, rest = slice(None), (Ellipsis, *rest)
        if isinstance(key, slice):
            start, stop, step = key.indices(self.n)
            if step != 1:
                return np.asarray(self.array[(slice(start, stop), *rest)])[::step]
            return self.array[(slice(start, max(start, stop)), *rest)]
        idx = int(key)
        if not -self.n <= idx < self.n:
            raise IndexError(f"row {idx} is out of range for {self.n} frames")
        return self.array[(idx % self.n, *rest)]

    def __array__(self, dtype=None, copy=None):
        out = np.asarray(self[:])
        return out if dtype is None else out.astype(dtype)


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

    @property
    def interrupted(self) -> bool:
        """True when the capture writing this recording did not finish (journal present)."""
        return self.journal is not None

    @property
    def frames(self) -> zarr.Array | RowsView:
        """The raw frames ``(F, H, W)`` as stored (float32 or uint16 counts).

        A ``zarr.Array``; for an interrupted capture with rows allocated past the true count,
        a :class:`RowsView` of exactly the committed rows.
        """
        arr = self.group["frames"]
        if self.journal is not None and arr.shape[0] != self.n_frames:
            return RowsView(arr, self.n_frames)
        return arr

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
        return int(self.group["frames"].shape[0])

    @property
    def has_ground_truth(self) -> bool:
        """True for simulated recordings that hold the high-speed video."""
        return "ground_truth" in self.group

    def per_frame(self, name: str) -> np.ndarray:
        """``frame_id``, ``timestamp`` or ``dropped`` as a numpy array."""
        if name not in PER_FRAME:
            raise RecordingError(f"`name` must be one of {', '.join(PER_FRAME)}; got {name!r}")
        if self.journal is not None:
            return self.journal[name][: self.n_frames].copy()
        return np.asarray(self.group[name][:])

    def ground_truth(self) -> np.ndarray:
        """The simulated high-speed video ``(S, H, W)`` float32."""
        if not self.has_ground_truth:
            raise RecordingError(f"{self.path} holds no ground truth (a captured recording)")
        return np.asarray(self.group["ground_truth"][:])

    def normalised_frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``[start, stop)`` as float32 relative units (counts converted)."""
        from flexvox_core.simulate.simulator import normalise_frames

        return normalise_frames(np.asarray(self.frames[start:stop]), self.attrs["storage"])


def open_recording(path) -> Recording:
    """Open and validate a recording; :class:`RecordingError` says what is wrong."""
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
    if not isinstance(version, int) or version > SCHEMA_VERSION:
        raise RecordingError(
            f"{path}: schema version {version!r} is newer than this software reads ({SCHEMA_VERSION}); "
            "update flexvox"
        )
    journal = None
    if (path / JOURNAL).exists():
        try:
            journal = read_journal(path / JOURNAL)
        except OSError as exc:
            raise RecordingError(f"{path}: cannot read the capture journal ({exc})") from exc
        _logger.info("%s: an interrupted capture; %d committed frames", path, len(journal["frame_id"]))
    rec = Recording(path, group, attrs, journal)
    problems = validate_recording(rec)
    if problems:
        raise RecordingError(f"{path}: " + "; ".join(problems))
    return rec


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
    names = set(rec.group.array_keys())
    for name in ("frames", *PER_FRAME):
        if name not in names:
            problems.append(f"array `{name}` is missing")
    if problems:
        return problems
    F = rec.n_frames
    if rec.frames.ndim != 3:
        problems.append(f"`frames` must be (F, H, W); got {rec.frames.shape}")
    if rec.journal is None:
        for name in PER_FRAME:
            if rec.group[name].shape != (F,):
                problems.append(f"`{name}` has {rec.group[name].shape[0]} entries for {F} frames")
    kind = rec.attrs["storage"].get("kind")
    if kind not in ("float", "counts"):
        problems.append(f"unknown storage kind {kind!r}")
    if "ground_truth" in names:
        gt = rec.group["ground_truth"].shape
        if gt != (F * K, *rec.frames.shape[1:]):
            problems.append(f"`ground_truth` {gt} does not match {F} frames of K = {K}")
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
    """
    rec = open_recording(path)
    if not rec.interrupted:
        return rec.n_frames
    n = rec.n_frames
    group = zarr.open_group(str(rec.path), mode="r+")
    frames = group["frames"]
    for name in PER_FRAME:
        arr = group[name]
        arr.resize((n,))
        arr[:] = rec.journal[name][:n]
    if frames.shape[0] != n:
        frames.resize((n, *frames.shape[1:]))
    attrs = dict(group.attrs)["flexvox"]
    group.attrs["flexvox"] = {**attrs, "recovered_utc": _now()}
    (rec.path / JOURNAL).unlink()
    _logger.info("%s: recovered an interrupted capture of %d frames", rec.path, n)
    return n
