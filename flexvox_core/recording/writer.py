"""Writing a recording: frames appended as they arrive, crash-safely, or a whole simulation at once.

Crash safety (a writer killed at any instruction, SIGKILL included)
-------------------------------------------------------------------
Zarr keeps an array's shape in its ``zarr.json``; growing four arrays by one row per frame
rewrites four metadata files per frame, and a process killed between two of them leaves
arrays of different lengths (a damaged recording), or a frame's row allocated before its
chunk is written (a silent black frame). So, while it writes, :class:`RecordingWriter`

1. *allocates in blocks*: the arrays grow by ``block_frames`` rows at a time (metadata is
   rewritten once per block, never per frame); rows past the true count are unwritten
   chunks (zarr's fill value);
2. writes each frame's chunk, *then* appends one 28-byte record (frame id, timestamp,
   dropped flag, the frame's CRC-32, the record's CRC-32) to a small append-only journal,
   ``frames/capture.journal`` (:mod:`flexvox_core.recording.journal`). The record is the
   commit point: a frame counts once its record is complete. A record torn by the kill fails
   its length or CRC and is ignored, with everything after it;
3. copies the per-frame values into the ``frame_id`` / ``timestamp`` / ``dropped`` /
   ``frame_crc`` arrays once per block (so plain zarr readers of a live capture see them, a
   block late).

:meth:`RecordingWriter.close` writes the remaining per-frame values, trims every array to
the true count, and deletes the journal: a closed recording is plain Zarr with exact
shapes (what older readers and napari expect). A store that still has a journal is an
*interrupted* capture, which :func:`~flexvox_core.recording.reader.open_recording` reads by its
journal and :func:`~flexvox_core.recording.repair.recover_recording` finalises in place.

Zarr's own ``LocalStore`` writes every key through a temporary file and a rename (zarr
3.1), so a kill never leaves a torn ``zarr.json`` or chunk; the journal does not depend on
that beyond "a file is old or new". What survives a *power loss* depends on the OS flushing
its page cache: pass ``fsync=True`` (``flexvox capture --durable``) to flush every frame's
chunk, its folders and its journal record to the disk before the next frame (slower; see
``bench/bench_durable.py``).

One writer (:mod:`flexvox_core.writer_lock`)
--------------------------------------------
A writer holds an OS lock beside the recording for as long as it writes; a second writer, or a
command that would replace the recording, is refused and told which process holds it.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np
import zarr

from flexvox_core.codes import is_identity_code
from flexvox_core.ngff import image_compressor
from flexvox_core.output_errors import OVERWRITE_HINT
from flexvox_core.recording.errors import RecordingError
from flexvox_core.recording.journal import JOURNAL, journal_header, journal_record
from flexvox_core.recording.schema import (
    FRAME_AXES,
    PER_FRAME_DTYPES,
    WRITTEN_PER_FRAME,
    frames_ngff,
    recording_attrs,
    values_crc,
)

DEFAULT_BLOCK_FRAMES = 64
"""Rows a writer allocates at a time."""


class RecordingWriter:
    """Append frames to a new recording as they arrive, crash-safely (see the module docstring).

    Each :meth:`append` writes the frame's chunk, then commits it with a journal record that
    carries the frame's CRC, so a recording interrupted at any point (an exception, SIGKILL, a
    full disk) holds every completed frame and opens with
    :func:`~flexvox_core.recording.reader.open_recording`. Call
    :meth:`close` (or use the writer as a context manager) to finalise: exact array shapes,
    journal removed. The writer holds the recording's :class:`~flexvox_core.writer_lock.WriterLock`
    from its creation until :meth:`close` or :meth:`discard`.

    Parameters
    ----------
    path : str or Path
        The store (a directory) to create; its name ends in ``.zarr``.
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
    OutputError
        For a path whose name does not end in ``.zarr``, or that names a file or a folder that is not a Zarr store.
    OSError
        When the store cannot be created (a full disk, a file-size limit): what the writer had
        made of it is removed and a store it was to replace is put back, so nothing is left that
        would read as a damaged recording.
    """

    def __init__(self, path, *, height: int, width: int, dtype, attrs: dict, overwrite: bool = False,
                 block_frames: int = DEFAULT_BLOCK_FRAMES, fsync: bool = False, atomic: bool = False,
                 lock=None):
        from flexvox_core.output_files import (
            check_overwrite,
            check_store_suffix,
            refuse_other_kind,
            remove_dead_partials,
            temporary_sibling,
        )
        from flexvox_core.writer_lock import WriterLock

        check_overwrite(overwrite)
        self.path = check_store_suffix(path)  # before the lock: a refused name leaves nothing behind
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
        remove_dead_partials(self.path)  # a killed writer's partial store of this path: said and removed
        self._fd = None
        self._replaced: Path | None = None
        self._atomic = bool(atomic)
        self.store: Path | None = None
        try:
            if (self.path.exists() or self.path.is_symlink()) and not overwrite:
                raise RecordingError(f"{self.path} already exists; {OVERWRITE_HINT}")
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
                raise RecordingError(f"{store} already exists; {OVERWRITE_HINT}")
            self.store = store  # from here on the store is this writer's own: a failed start removes it
            # The frames are also an OME-Zarr image (NGFF 0.5: axes t, y, x; t = one camera frame), so
            # generic OME-Zarr readers open the raw coded frames; flexvox's own block stays under "flexvox".
            self.group = zarr.open_group(str(self.store), mode="w-", zarr_format=3,
                                         attributes={"flexvox": attrs, "ome": frames_ngff(attrs)})
            self.frames = self.group.create_array("frames", shape=(0, height, width), chunks=(1, height, width),
                                                  dtype=dtype, fill_value=0, dimension_names=FRAME_AXES)
            self.per_frame = {
                name: self.group.create_array(name, shape=(0,), chunks=(4096,), dtype=PER_FRAME_DTYPES[name],
                                              fill_value=0)
                for name in WRITTEN_PER_FRAME
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
            self._pending = {name: [] for name in WRITTEN_PER_FRAME}
            self._root_id = _identity(self.store)
            self._journal_path = self.store / JOURNAL
            self._fd = os.open(self._journal_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
            self._write_all(journal_header(os.getpid()))
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
        for name in ("frames", *WRITTEN_PER_FRAME):
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
        for name in WRITTEN_PER_FRAME:
            values = np.asarray(self._pending[name], dtype=PER_FRAME_DTYPES[name])
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
        self._write_all(journal_record(frame_id, timestamp, dropped, crc))
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
                if not restore_if_empty(self.path, self._replaced, self.count):
                    remove_path(self._replaced)
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


def restore_if_empty(path, replaced, committed: int) -> bool:
    """The rule for an overwriting capture that ends with no frame: the recording it moved aside comes back.

    When ``committed`` (the frames the new store at ``path`` holds) is 0, the new store is deleted and ``replaced``
    (the earlier recording, ``.NAME.replaced-PID-XXXX.zarr``) is renamed back to ``path``; return True. Otherwise
    change nothing and return False. :meth:`RecordingWriter.close` applies it (and deletes the earlier recording
    once the new one holds frames), and so does :func:`~flexvox_core.recording.repair.repair_recording` for a
    capture killed before its first frame.
    """
    from flexvox_core.output_files import fsync_folder, remove_path

    if committed:
        return False
    path = Path(path)
    remove_path(path)
    os.rename(replaced, path)
    fsync_folder(path.parent)
    return True


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return st.st_dev, st.st_ino




def write_simulation(path, result, *, overwrite: bool = False) -> Path:
    """Write a :class:`~flexvox_core.simulate.SimulationResult` as a recording, atomically: the
    store appears at ``path`` complete, or not at all (an old one stays when the write fails)."""
    from flexvox_core.output_files import check_path

    path = check_path(path, call="fv.write_simulation(path, result)")
    if not all(hasattr(result, a) for a in ("frames", "ground_truth", "code", "rate_hz")):
        raise TypeError(f"`result` must be a SimulationResult (fv.simulate_video(video, code)); got "
                        f"{type(result).__name__}" + (": the path comes first, fv.write_simulation(path, result)"
                                                      if isinstance(result, str | os.PathLike) else ""))
    if not result.multiplexed and not is_identity_code(result.code):  # the reader would call it damaged
        raise ValueError("`result`'s code opens pixels in more than one slot, and the simulation is not marked "
                         "multiplexed: no reconstruction could tell what its frames hold. Simulate a multiplexed "
                         "capture through the MultiplexedCode itself, fv.simulate_video(video, "
                         "fv.multiplexed_code(tile)), not its `.code`; nothing was written")
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
