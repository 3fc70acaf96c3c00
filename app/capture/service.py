"""The capture service: the rig's devices set up for a plan, frames streamed to a recording.

A capture takes a :class:`~app.capture.plan.CapturePlan` (code, camera rate) and a
:class:`~calibration.capture_setup.CaptureCalibration` (homography, phase, camera trigger delay),
both built the same way by ``flexvox capture`` and the Capture workspace. The projector shows
:meth:`CapturePlan.patterns` (the patterns calibration verifies), the camera's trigger is
delayed by the calibration's delay where the camera can do it (else the operator confirms it was
set another way), and the recording stores the phase and the delay in use.

Qt-free (the Qt application drives it through :meth:`CaptureService.stats` and
:meth:`CaptureService.latest`, polled on a timer). It sits above ``rig_drivers`` and
``flexvox_core``.

Threads and the queue policy
----------------------------
Two worker threads::

    camera ──read_frame──> [reader] ──put──> bounded queue ──get──> [writer] ──append──> recording
                               └──> latest-frame slot (display: newest frame only)

* The **reader** owns the devices: it reads frames (each read waits at most
  ``SyncSetting.read_slice_s``), puts every frame in the latest-frame slot (a single
  reference swapped under a lock: the display never slows capture, and sees only the newest
  frame) and in the queue.
* The **queue** holds at most ``QueuePolicy.capacity`` frames. When it is full (the disk
  is slower than the camera) the reader *blocks* up to ``QueuePolicy.block_s`` for room
  (the camera's own buffers absorb that time); if there is still no room the frame is
  *discarded* and counted in ``queue_drops``. A discarded frame is never lost silently:
  its frame id is missing, so the writer records it, like every frame-id gap, as a zero
  row flagged ``dropped`` (the recording convention of simulations). Memory is bounded by
  ``capacity`` frames.
* The **writer** appends each frame to the recording as it arrives (one chunk per frame,
  crash-safe: see :mod:`flexvox_core.recording.writer`), filling frame-id gaps with dropped rows.

Every wait has a timeout; :meth:`CaptureService.stop` sets an event that both threads
check at least every ``read_slice_s`` / 0.1 s, so it returns promptly.

Failures
--------
A full disk or a vanished folder (``OSError`` from the writer), or a camera that fails
(``DeviceError``, e.g. unplugged), stops the capture: the writer keeps every frame already
received, the recording is finalised (or left with its journal when the disk refuses even
that — it still opens), and :attr:`CaptureResult.message` says what happened and how many
frames the recording holds, as read back from disk. A recording that cannot even be created (its
first metadata file refused: a full disk, a file-size limit) leaves nothing behind, and the
message says that nothing was recorded.
"""

from __future__ import annotations

import enum
import errno
import logging
import queue
import threading
import time
from array import array
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from app.capture.pacing import PacedClock
from app.capture.plan import CapturePlan
from app.capture.rig_setup import CaptureError, RigSetup, set_up_rig, stop_rig
from calibration.capture_setup import CaptureCalibration
from flexvox_core import output_files
from flexvox_core._version import __version__
from flexvox_core.multiplex import MultiplexedCode
from flexvox_core.output_errors import OutputError
from flexvox_core.recording import RecordingError, RecordingWriter, open_recording, recording_attrs
from flexvox_core.writer_lock import WriterLock
from rig_drivers.errors import DeviceError, DeviceTimeoutError
from rig_drivers.interfaces import DeviceState, Frame, Rig

_logger = logging.getLogger(__name__)

MAX_GAP_FRAMES = 100_000
"""A frame-id jump larger than this is a broken camera counter, not dropped frames: capture stops."""


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class SyncSetting:
    """Timing of a capture beyond the plan's rate.

    Parameters
    ----------
    use_sync_box : bool or None
        Drive projector and camera from the rig's sync box (None: when the rig has one).
    delay_set_by_hand : bool
        The operator has set the calibration's camera trigger delay on a camera that cannot be
        told it (no trigger-delay feature), e.g. in the vendor's tool. Without it such a camera
        refuses a calibration that needs a delay.
    read_slice_s : float
        Longest single wait for a frame (stop() is noticed within it).
    no_frame_timeout_s : float or None
        Capture stops with an error when no frame arrives for this long
        (None: ``max(2 s, 10 frame periods)``).
    """

    use_sync_box: bool | None = None
    delay_set_by_hand: bool = False
    read_slice_s: float = 0.2
    no_frame_timeout_s: float | None = None

    def __post_init__(self):
        if not 0 < self.read_slice_s <= 5:
            raise CaptureError(f"`read_slice_s` must be in (0, 5] s; got {self.read_slice_s!r}")

    def no_frame_s(self, camera_hz: float) -> float:
        """The no-frame timeout in seconds for a camera at ``camera_hz``."""
        if self.no_frame_timeout_s is not None:
            return float(self.no_frame_timeout_s)
        return max(2.0, 10.0 / camera_hz)


@dataclass(frozen=True)
class QueuePolicy:
    """The bounded queue between camera and disk (see the module docstring).

    Parameters
    ----------
    capacity : int
        Frames held at most.
    block_s : float
        How long the camera reader waits for room before it discards a frame.
    """

    capacity: int = 64
    block_s: float = 0.5

    def __post_init__(self):
        if isinstance(self.capacity, bool) or not isinstance(self.capacity, int) or not 1 <= self.capacity <= 100_000:
            raise CaptureError(f"`capacity` must be a whole number 1..100000; got {self.capacity!r}")
        if not 0 <= self.block_s <= 60:
            raise CaptureError(f"`block_s` must be between 0 and 60 s; got {self.block_s!r}")


class CaptureState(enum.Enum):
    """Where a capture is."""

    IDLE = "idle"
    RUNNING = "running"
    STOPPING = "stopping"
    DONE = "done"


@dataclass(frozen=True)
class CaptureStats:
    """A snapshot of the counters.

    Attributes
    ----------
    frames_received : int
        Frames the camera delivered.
    rows_written : int
        Rows in the recording (frames + dropped rows).
    drops : int
        Rows flagged dropped (camera gaps and queue discards).
    queue_drops : int
        Frames discarded because the queue stayed full for ``block_s``.
    queue_depth, queue_capacity, max_queue_depth : int
    write_rate_hz : float
        Rows written per second since the first frame arrived.
    camera_rate_hz : float
        Frames delivered per second (measured).
    writer_capacity_hz : float
        Rows per second of time spent writing: what the disk path could sustain.
    elapsed_s : float
    state : str
    """

    frames_received: int = 0
    rows_written: int = 0
    drops: int = 0
    queue_drops: int = 0
    queue_depth: int = 0
    queue_capacity: int = 0
    max_queue_depth: int = 0
    write_rate_hz: float = 0.0
    camera_rate_hz: float = 0.0
    writer_capacity_hz: float = 0.0
    elapsed_s: float = 0.0
    state: str = CaptureState.IDLE.value


@dataclass(frozen=True)
class CaptureResult:
    """How a capture ended.

    ``reason`` is ``done`` (N frames), ``stopped`` (:meth:`CaptureService.stop`) or
    ``error``; ``frames_in_recording`` is read back from the recording on disk (None when
    it cannot be opened), ``message`` says it all in one line.
    """

    path: Path
    reason: str
    message: str
    frames_in_recording: int | None
    stats: CaptureStats
    error: str | None = None

    @property
    def ok(self) -> bool:
        """True unless the capture ended on an error."""
        return self.reason != "error"


class LatestFrame:
    """A one-frame slot for the display: the newest frame replaces the previous one.

    ``put`` never blocks (a reference swap under a lock); ``get`` returns the newest frame
    and its sequence number (increasing with each put), so a display can skip repaints.
    """

    def __init__(self):
        self._lock = threading.Lock()
        self._frame: Frame | None = None
        self._seq = 0

    def put(self, frame: Frame) -> None:
        """Publish ``frame``."""
        with self._lock:
            self._frame = frame
            self._seq += 1

    def get(self) -> tuple[Frame | None, int]:
        """``(newest frame or None, sequence number)``."""
        with self._lock:
            return self._frame, self._seq


# --------------------------------------------------------------------------- the service

Writer = RecordingWriter
"""The writer interface the service uses: ``append(frame, frame_id=, timestamp=, dropped=)``,
``count``, ``write_ground_truth_frames(rows)``, ``close(attrs_update=)``."""


def check_output(path, *, overwrite: bool = False, inputs=()) -> Path:
    """The recording path a capture may create (:func:`flexvox_core.output_files.check_output`): refused
    when it is one of ``inputs`` (a code, calibration or rig file), exists (without ``overwrite``), is
    being written by another capture, or its folder does not exist or refuses files. Front ends call
    it before they open a rig, so the operator hears it at once."""
    try:
        return output_files.check_output(path, overwrite=overwrite, inputs=inputs, kind="store",
                                         hint="choose another path or allow overwriting")
    except OutputError as exc:
        raise CaptureError(str(exc)) from None


def default_storage(dtype) -> dict:
    """The ``storage`` block for frames of ``dtype``: float as is, integers as counts scaled
    so that normalised values span [0, 1] of the type's range."""
    dtype = np.dtype(dtype)
    if np.issubdtype(dtype, np.floating):
        return {"kind": "float"}
    return {"kind": "counts", "black_level": 0, "gain": 1.0, "electrons_per_unit": float(np.iinfo(dtype).max)}


class CaptureService:
    """Capture N frames (or until stopped) of a rig shuttered by a plan's code into a recording.

    Parameters
    ----------
    rig : Rig
        A :class:`rig_drivers.interfaces.Rig` (a :class:`~rig_drivers.profile.ProfileRig` or a
        :class:`~rig_drivers.simulated_rig.SimulatedRig`). Closed devices are opened and
        closed again at the end; open ones are left open (stopped).
    plan : CapturePlan
        The code and the camera rate.
    path : str or Path
        The recording to create.
    frames : int or None
        Rows to record (frames + dropped rows); None: until :meth:`stop`.
    calibration : CaptureCalibration
        Homography, phase and trigger delay (default: uncalibrated).
    sync : SyncSetting
    queue_policy : QueuePolicy
    projector_size : (H, W), optional
        Default: the rig's ``projector_size``.
    storage : dict, optional
        The recording's ``storage`` block (default :func:`default_storage` of the first frame).
    ground_truth : bool
        Simulated rigs: store the scene's high-speed video of the frames recorded as ``ground_truth``
        when the capture ends without error (refused on a real rig).
    writer_factory : callable, optional
        ``(path, height=, width=, dtype=, attrs=, overwrite=, fsync=, lock=) -> writer`` (tests
        inject slow or failing writers). Default :class:`~flexvox_core.recording.RecordingWriter`.
    overwrite : bool
        Replace an existing recording (never one another capture is writing: the recording's
        :class:`~flexvox_core.writer_lock.WriterLock` is taken in :meth:`start`, before any device
        is set up, and held until the recording is closed).
    durable : bool
        Flush every frame's chunk and journal record to the disk before the next frame (a power
        cut loses at most the frame in flight; slower: ``bench/bench_durable.py``).
    rig_info : dict, optional
        Extra entries for the recording's ``rig`` attribute.
    """

    def __init__(self, rig: Rig, plan: CapturePlan, path, *, frames: int | None = None,
                 calibration: CaptureCalibration | None = None, sync: SyncSetting | None = None,
                 queue_policy: QueuePolicy | None = None, projector_size=None, storage: dict | None = None,
                 ground_truth: bool = False,
                 writer_factory: Callable | None = None, overwrite: bool = False, durable: bool = False,
                 rig_info: dict | None = None):
        if not isinstance(plan, CapturePlan):
            raise CaptureError(f"`plan` must be a CapturePlan (app.capture.plan); got {type(plan).__name__}")
        try:
            self.code = plan.code
        except ValueError as exc:
            raise CaptureError(f"`plan`: {exc}") from None
        if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int) or frames < 1):
            raise CaptureError(f"`frames` must be a whole number >= 1 or None; got {frames!r}")
        if calibration is not None and not isinstance(calibration, CaptureCalibration):
            raise CaptureError(f"`calibration` must be a CaptureCalibration (calibration.capture_setup); got "
                               f"{type(calibration).__name__}")
        self.rig = rig
        self.plan = plan
        self.path = check_output(path, overwrite=overwrite)
        self.n_target = frames
        self.calibration = calibration or CaptureCalibration()
        self.sync_setting = sync or SyncSetting()
        self.policy = queue_policy or QueuePolicy()
        self.K = int(self.code.shape[2])
        self.phase_slots, self.trigger_delay_us, self.warnings = self.calibration.for_plan(self.K, plan.period_us)
        self.setup: RigSetup | None = None
        """How the rig was set up (after :meth:`start`)."""
        self._projector_size = projector_size
        self._storage = storage
        self._ground_truth = self._truth_of(rig) if ground_truth else None
        self._writer_factory = writer_factory or RecordingWriter
        self._overwrite = overwrite
        self._durable = bool(durable)
        self._path_lock = WriterLock(self.path)
        self._rig_info = dict(rig_info or {})

        self._queue: queue.Queue = queue.Queue(maxsize=self.policy.capacity)
        self._latest = LatestFrame()
        self._stop = threading.Event()
        self._reader_done = threading.Event()
        self._done = threading.Event()
        self._lock = threading.Lock()
        self._state = CaptureState.IDLE
        self._threads: list[threading.Thread] = []
        self._opened: list = []
        self._error: str | None = None
        self._result: CaptureResult | None = None
        self._writer = None
        self._writer_refused: str | None = None
        """Why the recording could not be created (None: it was, or was not tried yet)."""
        self._period_us = 0
        # counters
        self._received = 0
        self._rows = 0
        self._drops = 0
        self._queue_drops = 0
        self._max_depth = 0
        self._t_start = 0.0
        self._t_first = None
        self._t_last_arrival = None
        self._t_last_write = None
        self._write_busy = 0.0
        self._first_id: int | None = None
        self._last_seen_id: int | None = None
        self._next_id: int | None = None
        self._last_ts = 0.0
        self._ids = array("q")
        self._use_sync = False
        self._camera_size = (0, 0)
        self._rig_attrs: dict = {}

    # ------------------------------------------------------------------ public
    @property
    def state(self) -> CaptureState:
        """The capture's state."""
        return self._state

    @property
    def frame_period_s(self) -> float:
        """The camera frame period set up on the rig (K projector periods)."""
        return self.K * self._period_us / 1e6

    def latest(self) -> tuple[Frame | None, int]:
        """The newest frame for display and its sequence number (never blocks capture)."""
        return self._latest.get()

    def stats(self) -> CaptureStats:
        """A snapshot of the counters."""
        now = time.perf_counter()
        with self._lock:
            t0 = self._t_first
            span_w = (self._t_last_write - t0) if (t0 is not None and self._t_last_write is not None) else 0.0
            span_c = (self._t_last_arrival - t0) if (t0 is not None and self._t_last_arrival is not None) else 0.0
            return CaptureStats(
                frames_received=self._received, rows_written=self._rows, drops=self._drops,
                queue_drops=self._queue_drops, queue_depth=self._queue.qsize(),
                queue_capacity=self.policy.capacity, max_queue_depth=self._max_depth,
                write_rate_hz=(self._rows - 1) / span_w if span_w > 0 else 0.0,
                camera_rate_hz=(self._received - 1) / span_c if span_c > 0 else 0.0,
                writer_capacity_hz=self._rows / self._write_busy if self._write_busy > 0 else 0.0,
                elapsed_s=(now - self._t_start) if self._t_start else 0.0,
                state=self._state.value,
            )

    def start(self) -> None:
        """Set up the devices and start capturing on worker threads.

        Raises
        ------
        CaptureError
            When a device refuses its setup (the devices are stopped and closed again).
        """
        if self._state is not CaptureState.IDLE:
            raise CaptureError(f"cannot start: the capture is {self._state.value} (a service captures once)")
        sim = self.rig.simulated
        if sim is not None and isinstance(sim.clock, PacedClock):  # building the rig took wall time, not frames
            sim.clock.resync()
        try:  # one writer per recording: refused here, before any device is touched
            self._path_lock.acquire()
            if self.path.exists() and not self._overwrite:  # it may have appeared since the service was made
                raise CaptureError(f"{self.path} already exists; choose another path or allow overwriting")
        except (OutputError, CaptureError) as exc:
            self._path_lock.release()
            raise CaptureError(str(exc)) from None
        try:
            self._setup()
        except CaptureError:
            self._teardown()
            self._path_lock.release()
            raise
        except (DeviceError, ValueError) as exc:
            self._teardown()
            self._path_lock.release()
            raise CaptureError(f"cannot set up the rig: {exc}") from exc
        self._t_start = time.perf_counter()
        self._state = CaptureState.RUNNING
        reader = threading.Thread(target=self._read_loop, name="flexvox-capture-reader", daemon=True)
        writer = threading.Thread(target=self._write_loop, name="flexvox-capture-writer", daemon=True)
        self._threads = [reader, writer]
        reader.start()
        writer.start()

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the capture to end; True when it has."""
        return self._done.wait(timeout_s)

    def stop(self, timeout_s: float = 10.0) -> CaptureResult | None:
        """Stop capturing, keep what was captured, and return the result.

        Returns None only when the threads did not finish within ``timeout_s`` (the disk
        hangs); call :meth:`wait` again later.
        """
        if self._state is CaptureState.IDLE:
            raise CaptureError("cannot stop: the capture was not started")
        if self._state is CaptureState.RUNNING:
            self._state = CaptureState.STOPPING
        self._stop.set()
        if not self._done.wait(timeout_s):
            _logger.error("capture threads did not finish within %g s", timeout_s)
            return None
        return self._result

    @property
    def result(self) -> CaptureResult | None:
        """The result once the capture ended, else None."""
        return self._result

    def run(self, timeout_s: float | None = None) -> CaptureResult:
        """Start, wait until N frames are recorded (at most ``timeout_s``), stop; the result.

        Without ``timeout_s`` the wait is bounded by twice the capture's nominal length plus
        30 s.
        """
        if self.n_target is None and timeout_s is None:
            raise CaptureError("capturing until stopped needs `timeout_s` (or give `frames`)")
        self.start()
        if timeout_s is None:
            timeout_s = 2 * self.n_target * self.frame_period_s + 30.0
        self.wait(timeout_s)
        result = self.stop()
        if result is None:
            raise CaptureError("the capture threads did not finish; the disk may hang")
        return result

    # ------------------------------------------------------------------ setup
    def _open(self, device) -> None:
        if device.state is DeviceState.CLOSED:
            device.open()
            self._opened.append(device)
        device.enable()

    def _setup(self) -> None:
        setup = set_up_rig(self.rig, self.plan, self.calibration, projector_size=self._projector_size,
                           use_sync_box=self.sync_setting.use_sync_box,
                           delay_set_by_hand=self.sync_setting.delay_set_by_hand, open_device=self._open)
        self.setup = setup
        self.warnings = list(setup.warnings)
        self._period_us = setup.period_us
        self._use_sync = setup.use_sync
        self._camera_size = setup.camera_size
        self._rig_attrs = setup.rig_attrs(self.rig) | self._rig_info
        for w in self.warnings:
            _logger.info("capture: %s", w)

    @staticmethod
    def _truth_of(rig: Rig):
        truth = rig.truth
        if truth is None:
            raise CaptureError("ground truth exists only on the simulated rig (a real scene has none)")
        return truth.subframe_video

    def _teardown(self) -> None:
        for message in stop_rig(self.rig):
            _logger.error("capture teardown: %s", message)
        for device in reversed(self._opened):
            try:
                device.close()
            except DeviceError as exc:
                _logger.error("capture teardown: could not close %s: %s", device.name, exc)
        self._opened = []

    # ------------------------------------------------------------------ threads
    def _fail(self, message: str) -> None:
        with self._lock:
            if self._error is None:
                self._error = message
        _logger.error("capture: %s", message)
        self._stop.set()

    def _read_loop(self) -> None:
        camera = self.rig.camera
        slice_s = self.sync_setting.read_slice_s
        no_frame_s = self.sync_setting.no_frame_s(self.plan.camera_hz)
        last_frame_t = time.perf_counter()
        try:
            while not self._stop.is_set():
                try:
                    frame = camera.read_frame(slice_s)
                except DeviceTimeoutError as exc:
                    if time.perf_counter() - last_frame_t > no_frame_s:
                        self._fail(f"no frame from the camera for {no_frame_s:g} s ({exc})")
                        break
                    continue
                except DeviceError as exc:
                    self._fail(f"the camera failed (unplugged?): {exc}")
                    break
                now = time.perf_counter()
                last_frame_t = now
                with self._lock:
                    if self._t_first is None:
                        self._t_first = now
                        self._first_id = frame.frame_id
                    self._t_last_arrival = now
                    self._received += 1
                    self._last_seen_id = frame.frame_id
                self._latest.put(frame)
                if not self._enqueue(frame):
                    break
                if self.n_target is not None and frame.frame_id - self._first_id >= self.n_target - 1:
                    break
        except Exception as exc:  # noqa: BLE001 - a reader bug must still end the capture cleanly
            _logger.exception("capture reader crashed")
            self._fail(f"the camera reader crashed: {type(exc).__name__}: {exc}")
        finally:
            self._teardown()
            self._reader_done.set()

    def _enqueue(self, frame: Frame) -> bool:
        """Queue ``frame`` by the policy (block up to ``block_s``, then discard); False when
        capture is stopping."""
        deadline = time.perf_counter() + self.policy.block_s
        while True:
            remaining = deadline - time.perf_counter()
            try:
                if remaining <= 0:
                    self._queue.put_nowait(frame)
                else:
                    self._queue.put(frame, timeout=min(0.05, remaining))
            except queue.Full:
                if self._stop.is_set():
                    return False
                if time.perf_counter() < deadline:
                    continue
                with self._lock:
                    self._queue_drops += 1
                _logger.warning("capture: queue full for %g s, frame %d discarded (recorded as dropped)",
                                self.policy.block_s, frame.frame_id)
                return True
            depth = self._queue.qsize()
            with self._lock:
                self._max_depth = max(self._max_depth, depth)
            return True

    def _write_loop(self) -> None:
        """Write every received frame (draining the queue after a stop or a camera error)."""
        writer_ok = True
        try:
            while not self._target_reached():
                try:
                    frame = self._queue.get(timeout=0.1)
                except queue.Empty:
                    if self._reader_done.is_set() and self._queue.empty():
                        break
                    continue
                self._write_frame(frame)
            # Frames the queue discarded at the very end left no later id behind them.
            last = self._last_seen_id
            if last is not None and self._next_id is not None and last >= self._next_id:
                self._write_gap(last + 1)
        except (OSError, RecordingError) as exc:
            writer_ok = False
            self._fail(self._writer_refused or f"cannot write {self.path}: {_os_message(exc)}")
        except Exception as exc:  # noqa: BLE001 - a writer bug must still end the capture cleanly
            writer_ok = False
            _logger.exception("capture writer crashed")
            self._fail(f"the recording writer crashed: {type(exc).__name__}: {exc}")
        finally:
            self._stop.set()
            if not self._reader_done.wait(max(5.0, 3 * self.sync_setting.read_slice_s)):
                _logger.error("capture: the camera reader did not stop in time")
            if self._error is not None:
                reason = "error"
            elif self.n_target is None or self._rows < self.n_target:
                reason = "stopped"
            else:
                reason = "done"
            self._finish(reason, writer_ok)

    def _target_reached(self) -> bool:
        return self.n_target is not None and self._rows >= self.n_target

    def _ensure_writer(self, frame: Frame | None) -> None:
        if self._writer is not None:
            return
        H, W = self._camera_size
        dtype = np.dtype(np.float32) if frame is None else np.asarray(frame.image).dtype
        store = np.dtype(np.float32) if np.issubdtype(dtype, np.floating) else np.dtype(np.uint16)
        if frame is not None and np.issubdtype(dtype, np.integer) and dtype.itemsize > 2:
            raise RecordingError(f"camera frames of {dtype} cannot be stored (uint8/uint16 or float only)")
        storage = self._storage or default_storage(np.uint8 if dtype == np.uint8 else store)
        shutter = self.plan.shutter_code
        multiplexed = isinstance(shutter, MultiplexedCode)
        calibration = self.calibration.as_dict() | {"phase_slots": self.phase_slots,
                                                    "trigger_delay_us": self.trigger_delay_us,
                                                    "warnings": list(self.warnings)}
        attrs = recording_attrs(self.code, rate_hz=1e6 / (self.K * self._period_us), kind="captured",
                                storage=storage, calibration=calibration, rig=self._rig_attrs,
                                multiplexed=multiplexed, placement=shutter.placement if multiplexed else None,
                                source=f"flexvox {__version__} capture")
        try:
            self._writer = self._writer_factory(self.path, height=H, width=W, dtype=store, attrs=attrs,
                                                overwrite=self._overwrite, fsync=self._durable, lock=self._path_lock)
        except (OSError, RecordingError) as exc:  # the writer removed what it had made of the store
            self._writer_refused = f"cannot create {self.path}: {_os_message(exc)}"
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
        """Dropped rows for ids ``[next_id, until_id)`` (at most up to N rows)."""
        gap = until_id - self._next_id
        if gap > MAX_GAP_FRAMES:
            raise RecordingError(f"the camera's frame id jumped from {self._next_id - 1} to {until_id} "
                                 f"(more than {MAX_GAP_FRAMES} frames): a broken frame counter")
        for fid in range(self._next_id, until_id):
            if self._target_reached():
                return
            self._last_ts += self.frame_period_s
            self._append(None, fid, self._last_ts, True)
            self._next_id = fid + 1

    def _write_frame(self, frame: Frame) -> None:
        self._ensure_writer(frame)
        fid = int(frame.frame_id)
        if self._next_id is not None:
            if fid < self._next_id:
                raise RecordingError(f"the camera's frame id went backwards ({fid} after {self._next_id - 1})")
            self._write_gap(fid)
            if self._target_reached():
                return
        self._append(frame.image, fid, float(frame.timestamp_s), False)
        self._next_id = fid + 1
        self._last_ts = float(frame.timestamp_s)

    def _finish(self, reason: str, writer_ok: bool = True) -> None:
        writer_note = ""
        try:
            if self._writer_refused is None:
                self._ensure_writer(None)  # a capture stopped before its first frame: an empty recording
        except (OSError, RecordingError) as exc:
            self._fail(self._writer_refused or f"cannot create {self.path}: {_os_message(exc)}")
            reason = "error"
        try:
            if self._writer is not None:
                self._close_writer(reason)
        except (OSError, RecordingError) as exc:
            writer_note = f"; finalising failed ({_os_message(exc)}), the capture journal was kept"
            _logger.error("capture: finalising %s failed: %s", self.path, exc)
            if not getattr(self._writer, "closed", True):
                try:
                    self._writer.close()
                except (OSError, RecordingError) as exc2:
                    _logger.error("capture: closing %s failed again: %s", self.path, exc2)
        finally:
            self._path_lock.release()
        self._state = CaptureState.DONE
        held, where = self._what_was_recorded()
        s = self.stats()
        drops = f"{s.drops} dropped ({s.queue_drops} by the queue)"
        if reason == "error":
            message = f"capture stopped: {self._error}{writer_note}; {where}; {drops}"
        else:
            verb = "captured" if reason == "done" else "stopped after"
            message = f"{verb} {s.rows_written} frames: {drops}; {where}{writer_note}"
        self._result = CaptureResult(self.path, reason, message, held, s, self._error)
        _logger.info("%s", message)
        self._done.set()

    def _close_writer(self, reason: str) -> None:
        """Store the ground truth (simulated rigs) and finalise the recording with the capture's counters."""
        if self._ground_truth is not None and reason != "error" and self._writer.count:
            self._writer.write_ground_truth_frames(self._ground_truth(int(i), self.K) for i in self._ids)
        s = self.stats()
        self._writer.close(attrs_update={"capture": {
            "reason": reason, "error": self._error, "frames_received": s.frames_received,
            "rows": s.rows_written, "drops": s.drops, "queue_drops": s.queue_drops,
            "write_rate_hz": s.write_rate_hz, "camera_rate_hz": s.camera_rate_hz,
            "queue": asdict(self.policy)}})

    def _what_was_recorded(self) -> tuple[int | None, str]:
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


def _os_message(exc: Exception) -> str:
    """An operator's reading of a write failure."""
    if isinstance(exc, OSError) and exc.errno == errno.ENOSPC:
        return f"the disk is full ({exc})"
    if isinstance(exc, OSError) and exc.errno == errno.EFBIG:
        return (f"a file would pass the file-size limit (`ulimit -f`) or the largest file the file system "
                f"holds ({exc})")
    return str(exc)
