"""The recording sink: a capture's frames into its recording, gaps as dropped rows, and the recording's end.

:class:`RecordingSink` holds the recording's side of a capture and nothing of the devices': the
one-writer lock on the path (:meth:`~RecordingSink.claim`), the recording created at the first frame
with the code, rates, calibration and rig it was made with, each frame appended as its own crash-safe
chunk with its checksum (:class:`~flexvox_core.recording.RecordingWriter`), every frame-id gap
filled with zero rows flagged ``dropped`` (the convention of simulations), and the recording
finalised with the capture's counters (:meth:`~RecordingSink.finalise`), or left with its journal
when the disk refuses even that (it still opens). :class:`~flexvox_app.capture.service.CaptureService`
drives it on its writer thread.
"""

from __future__ import annotations

import errno
import logging
import threading
import time
from array import array
from collections.abc import Callable
from pathlib import Path

import numpy as np

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.rig_setup import CaptureError, RigSetup
from flexvox_calibration.capture_setup import CaptureCalibration
from flexvox_core import output_files
from flexvox_core._version import __version__
from flexvox_core.multiplex import MultiplexedCode
from flexvox_core.output_errors import OVERWRITE_HINT, OutputError
from flexvox_core.recording import RecordingError, RecordingWriter, open_recording, recording_attrs
from flexvox_core.writer_lock import WriterLock
from rig_drivers.interfaces import Frame

_logger = logging.getLogger(__name__)

MAX_GAP_FRAMES = 100_000
"""A frame-id jump larger than this is a broken camera counter, not dropped frames: capture stops."""

Writer = RecordingWriter
"""The writer interface the sink uses: ``append(frame, frame_id=, timestamp=, dropped=)``,
``count``, ``write_ground_truth_frames(rows)``, ``close(attrs_update=)``."""


def check_output(path, *, overwrite: bool = False, inputs=(), hint: str = OVERWRITE_HINT) -> Path:
    """The recording path a capture may create (:func:`flexvox_core.output_files.check_output`): refused
    when it is one of ``inputs`` (a code, calibration or rig file), exists (without ``overwrite``), is
    being written by another capture, or its folder does not exist or refuses files. Front ends call
    it before they open a rig, so the operator hears it at once. ``hint`` says how to allow overwriting, in the
    front end's words (Python's ``overwrite=True`` by default)."""
    try:
        return output_files.check_output(path, overwrite=overwrite, inputs=inputs, kind="store",
                                         hint=hint)
    except OutputError as exc:
        raise CaptureError(str(exc)) from None


def default_storage(dtype) -> dict:
    """The ``storage`` block for frames of ``dtype``: float as is, integers as counts scaled
    so that normalised values span [0, 1] of the type's range."""
    dtype = np.dtype(dtype)
    if np.issubdtype(dtype, np.floating):
        return {"kind": "float"}
    return {"kind": "counts", "black_level": 0, "gain": 1.0, "electrons_per_unit": float(np.iinfo(dtype).max)}


def os_message(exc: Exception) -> str:
    """An operator's reading of a write failure."""
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        return f"the disk is full ({exc})"
    if isinstance(exc, OSError) and exc.errno == errno.EFBIG:
        return (f"a file would pass the file-size limit (`ulimit -f`) or the largest file the file system "
                f"holds ({exc})")
    return str(exc)


class RecordingSink:
    """Write a capture's frames to a new recording at ``path``.

    Parameters
    ----------
    path : Path
        Checked by :func:`check_output`.
    plan : CapturePlan
    calibration : CaptureCalibration
    target : int or None
        Rows to record (frames + dropped rows); None: no limit.
    storage : dict, optional
        The recording's ``storage`` block (default :func:`default_storage` of the first frame).
    ground_truth : callable, optional
        ``(frame_id, K) -> (K, H, W)``: stored as the recording's ground truth for the rows recorded
        when the capture ends without error (simulated rigs).
    writer_factory : callable, optional
        ``(path, height=, width=, dtype=, attrs=, overwrite=, fsync=, lock=) -> writer`` (default
        :class:`~flexvox_core.recording.RecordingWriter`).
    overwrite : bool
        Replace an existing recording (never one another capture is writing).
    durable : bool
        Flush every frame's chunk and journal record to the disk before the next frame.
    rig_info : dict, optional
        Extra entries for the recording's ``rig`` attribute.
    """

    def __init__(self, path: Path, plan: CapturePlan, calibration: CaptureCalibration, *, target: int | None = None,
                 storage: dict | None = None, ground_truth: Callable | None = None,
                 writer_factory: Callable | None = None, overwrite: bool = False, durable: bool = False,
                 rig_info: dict | None = None):
        self.path = path
        self.plan = plan
        self.calibration = calibration
        self.target = target
        self._storage = storage
        self._ground_truth = ground_truth
        self._writer_factory = writer_factory or RecordingWriter
        self._overwrite = overwrite
        self._durable = bool(durable)
        self._rig_info = dict(rig_info or {})
        self._lock_file = WriterLock(path)
        self._setup: RigSetup | None = None
        self._rig_attrs: dict = {}
        self._writer = None
        self.refused: str | None = None
        """Why the recording could not be created (None: it was, or was not tried yet)."""
        self.finishing = ""
        """What :meth:`finalise` is writing now, in words ("" before and after it)."""
        self._lock = threading.Lock()
        self._rows = 0
        self._drops = 0
        self._write_busy = 0.0
        self._t_last_write: float | None = None
        self._next_id: int | None = None
        self._last_ts = 0.0
        self._ids = array("q")

    # ------------------------------------------------------------------ the path
    def claim(self) -> None:
        """Take the recording's one-writer lock (held until :meth:`release`), refusing a path that has appeared.

        Raises
        ------
        CaptureError
            When another capture writes it, or it exists now (without ``overwrite``).
        """
        try:
            self._lock_file.acquire()
            if self.path.exists() and not self._overwrite:  # it may have appeared since the check
                raise CaptureError(f"{self.path} already exists; {OVERWRITE_HINT}")
        except (OutputError, CaptureError) as exc:
            self._lock_file.release()
            raise CaptureError(str(exc)) from None

    def release(self) -> None:
        """Let go of the one-writer lock."""
        self._lock_file.release()

    def prepare(self, setup: RigSetup, rig_attrs: dict) -> None:
        """What the recording says of the rig: how it was set up, and its ``rig`` attribute."""
        self._setup = setup
        self._rig_attrs = dict(rig_attrs) | self._rig_info

    # ------------------------------------------------------------------ counters
    @property
    def rows(self) -> int:
        """Rows written (frames and dropped rows)."""
        return self._rows

    @property
    def target_reached(self) -> bool:
        """The recording holds the rows asked for."""
        return self.target is not None and self._rows >= self.target

    def counters(self) -> tuple[int, int, float, float | None]:
        """``(rows, drops, seconds spent writing, perf_counter time of the last write or None)``."""
        with self._lock:
            return self._rows, self._drops, self._write_busy, self._t_last_write

    # ------------------------------------------------------------------ writing
    def write(self, frame: Frame) -> None:
        """Append ``frame``, after dropped rows for the ids the camera skipped (never past the target).

        Raises
        ------
        RecordingError
            For an id that went backwards or jumped by more than :data:`MAX_GAP_FRAMES`.
        OSError
            When the disk refuses (:attr:`refused` says so when the recording could not be created).
        """
        self.create(frame)
        fid = int(frame.frame_id)
        if self._next_id is not None:
            if fid < self._next_id:
                raise RecordingError(f"the camera's frame id went backwards ({fid} after {self._next_id - 1})")
            self._write_gap(fid)
            if self.target_reached:
                return
        self._append(frame.image, fid, float(frame.timestamp_s), False)
        self._next_id = fid + 1
        self._last_ts = float(frame.timestamp_s)

    def write_gap_through(self, last_id: int | None) -> None:
        """Dropped rows up to and including ``last_id``: frames the queue discarded at the very end, with no
        later frame behind them to show the gap."""
        if last_id is not None and self._next_id is not None and last_id >= self._next_id:
            self._write_gap(last_id + 1)

    def create(self, frame: Frame | None) -> None:
        """Create the recording for frames like ``frame`` (None: an empty one of float frames), once.

        Raises
        ------
        RecordingError, OSError
            When it cannot be created; the writer removes what it had made, :attr:`refused` says why.
        """
        if self._writer is not None:
            return
        setup = self._setup
        H, W = setup.camera_size
        K = self.plan.K
        dtype = np.dtype(np.float32) if frame is None else np.asarray(frame.image).dtype
        store = np.dtype(np.float32) if np.issubdtype(dtype, np.floating) else np.dtype(np.uint16)
        if frame is not None and np.issubdtype(dtype, np.integer) and dtype.itemsize > 2:
            raise RecordingError(f"camera frames of {dtype} cannot be stored (uint8/uint16 or float only)")
        storage = self._storage or default_storage(np.uint8 if dtype == np.uint8 else store)
        shutter = self.plan.shutter_code
        multiplexed = isinstance(shutter, MultiplexedCode)
        calibration = self.calibration.as_dict() | {"phase_slots": setup.phase_slots,
                                                    "trigger_delay_us": setup.trigger_delay_us,
                                                    "warnings": list(setup.warnings)}
        attrs = recording_attrs(self.plan.code, rate_hz=1e6 / (K * setup.period_us), kind="captured",
                                storage=storage, calibration=calibration, rig=self._rig_attrs,
                                multiplexed=multiplexed, placement=shutter.placement if multiplexed else None,
                                source=f"flexvox {__version__} capture")
        try:
            self._writer = self._writer_factory(self.path, height=H, width=W, dtype=store, attrs=attrs,
                                                overwrite=self._overwrite, fsync=self._durable, lock=self._lock_file)
        except (OSError, RecordingError) as exc:  # the writer removed what it had made of the store
            self.refused = f"cannot create {self.path}: {os_message(exc)}"
            raise

    def _append(self, image, frame_id: int, timestamp: float, dropped: bool) -> None:
        t0 = time.perf_counter()
        self._writer.append(image, frame_id=frame_id, timestamp=timestamp, dropped=dropped)
        t1 = time.perf_counter()
        self._ids.append(frame_id)
        with self._lock:
            self._rows += 1
            self._drops += int(dropped)
            self._write_busy += t1 - t0
            self._t_last_write = t1

    def _write_gap(self, until_id: int) -> None:
        """Dropped rows for ids ``[next_id, until_id)`` (at most up to the target)."""
        gap = until_id - self._next_id
        if gap > MAX_GAP_FRAMES:
            raise RecordingError(f"the camera's frame id jumped from {self._next_id - 1} to {until_id} "
                                 f"(more than {MAX_GAP_FRAMES} frames): a broken frame counter")
        period_s = self.plan.K * self._setup.period_us / 1e6
        for fid in range(self._next_id, until_id):
            if self.target_reached:
                return
            self._last_ts += period_s
            self._append(None, fid, self._last_ts, True)
            self._next_id = fid + 1

    # ------------------------------------------------------------------ the end
    def finalise(self, reason: str, capture_attrs: dict) -> str:
        """Store the ground truth (when asked, and ``reason`` is not ``error``) and close the recording with
        ``capture_attrs`` as its ``capture`` attribute; releases the lock.

        Returns
        -------
        str
            "" when it closed, else the clause that says finalising failed and the journal was kept.
        """
        note = ""
        try:
            if self._writer is not None:
                if self._ground_truth is not None and reason != "error" and self._writer.count:
                    self._writer.write_ground_truth_frames(self._truth_rows())
                self.finishing = "closing the recording (the per-frame arrays, the journal removed)"
                self._writer.close(attrs_update={"capture": capture_attrs})
        except (OSError, RecordingError) as exc:
            note = f"; finalising failed ({os_message(exc)}), the capture journal was kept"
            _logger.error("capture: finalising %s failed: %s", self.path, exc)
            if not getattr(self._writer, "closed", True):
                try:
                    self._writer.close()
                except (OSError, RecordingError) as exc2:
                    _logger.error("capture: closing %s failed again: %s", self.path, exc2)
        finally:
            self.finishing = ""
            self.release()
        return note

    def _truth_rows(self):
        """The ground truth's rows, one per recorded frame, saying in :attr:`finishing` how far it is."""
        K, n = self.plan.K, len(self._ids)
        for done, i in enumerate(self._ids):
            self.finishing = f"writing the scene's ground truth: frame {done + 1} of {n}"
            yield self._ground_truth(int(i), K)

    def what_was_recorded(self) -> tuple[int | None, str]:
        """(frames the recording on disk holds or None, the sentence that says so)."""
        if self._writer is None:  # the recording could not be created
            if self._overwrite and self.path.exists():
                return None, f"nothing was recorded; the recording that was at {self.path} is unchanged"
            if not (self.path.exists() or self.path.is_symlink()):
                return None, f"nothing was recorded ({self.path} was not created)"
        try:
            held = open_recording(self.path).n_frames
        except RecordingError as exc:
            return None, f"the recording cannot be opened: {exc}"
        return held, f"{self.path} holds {held} frame(s) and opens cleanly"
