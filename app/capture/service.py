"""The capture service: a plan's frames from the rig into a crash-safe recording, its progress published as events.

A capture takes a :class:`~flexvox_app.capture.plan.CapturePlan` (code, camera rate) and a
:class:`~flexvox_calibration.capture_setup.CaptureCalibration` (homography, phase, camera trigger delay),
both built the same way by ``flexvox capture`` and the Capture workspace. The projector shows
:meth:`CapturePlan.patterns` (the patterns calibration verifies), the camera's trigger is
delayed by the calibration's delay where the camera can do it (else the operator confirms it was
set another way), and the recording stores the phase and the delay in use.

Three parts, each in its own module:

* the **acquisition engine** (:class:`~flexvox_app.capture.engine.AcquisitionEngine`): sets the rig up,
  starts the projector and the sync box that trigger the camera, reads the camera, and puts the
  rig back;
* the **recording sink** (:class:`~flexvox_app.capture.sink.RecordingSink`): the one-writer lock, the
  recording created at the first frame, frame-id gaps as dropped rows, each row's checksum, the
  finalisation;
* the **service** here, the runner between them: its state, the threads and the queue between
  them, the counters, and the events a front end subscribes to
  (:class:`~flexvox_app.capture.events.CaptureEvents`: ``started``, ``progress``, ``finished``), emitted on
  a thread of their own.

Qt-free; it sits above ``rig_drivers`` and ``flexvox_core``.

Threads and the queue policy
----------------------------
Three worker threads::

    camera ──engine.frames──> [reader] ──put──> bounded queue ──get──> [writer] ──sink.write──> recording
                                  └──> latest-frame slot (display: newest frame only)
                                                        counters ──> [events] ──> progress, finished

* The **reader** drives the engine: it reads frames (each read waits at most
  ``SyncSetting.read_slice_s``), puts every frame in the latest-frame slot (a single
  reference swapped under a lock: the display never slows capture, and sees only the newest
  frame) and in the queue.
* The **queue** holds at most ``QueuePolicy.capacity`` frames. When it is full (the disk
  is slower than the camera) the reader *blocks* up to ``QueuePolicy.block_s`` for room
  (the camera's own buffers absorb that time); if there is still no room the frame is
  *discarded* and counted in ``queue_drops``. A discarded frame is never lost silently:
  its frame id is missing, so the sink records it, like every frame-id gap, as a zero
  row flagged ``dropped`` (the recording convention of simulations). Memory is bounded by
  ``capacity`` frames.
* The **writer** hands each frame to the sink as it arrives (one chunk per frame,
  crash-safe: see :mod:`flexvox_core.recording.writer`).
* The **events** thread emits ``started``, then ``progress`` every ``progress_every_s`` until the
  capture has ended, then the final ``progress`` and ``finished``. Subscribers run there, so a slow
  one never holds up the reader or the writer.

Every wait has a timeout; :meth:`CaptureService.stop` sets an event that the reader and the
writer check at least every ``read_slice_s`` / 0.1 s, so it returns promptly: after the recording is
finalised and the last ``progress`` and ``finished`` have been delivered (:meth:`CaptureService.wait`
waits for the same without stopping).

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

import contextvars
import logging
import queue
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict

from flexvox_app.capture.engine import AcquisitionEngine, CameraStopped
from flexvox_app.capture.events import CaptureEvents
from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.rig_setup import CaptureError, RigSetup, check_calibration_rig
from flexvox_app.capture.settings import QueuePolicy, SyncSetting
from flexvox_app.capture.sink import RecordingSink, check_output, os_message
from flexvox_app.capture.status import CaptureResult, CaptureState, CaptureStats
from flexvox_calibration.capture_setup import CaptureCalibration
from flexvox_calibration.errors import CalibrationWarning
from flexvox_core.recording import RecordingError
from rig_drivers.interfaces import Frame, Rig

_logger = logging.getLogger(__name__)

_SHOWN_BY_CALLER: contextvars.ContextVar[bool] = contextvars.ContextVar("flexvox_capture_warnings_shown",
                                                                         default=False)


@contextmanager
def warnings_shown_by_caller() -> Iterator[None]:
    """For a front end that shows a capture's warnings itself (``flexvox capture``'s ``warning:`` lines, the
    Capture workspace's question): services built inside log them at INFO only, and issue no
    :class:`~flexvox_calibration.errors.CalibrationWarning`."""
    token = _SHOWN_BY_CALLER.set(True)
    try:
        yield
    finally:
        _SHOWN_BY_CALLER.reset(token)


def _warn(message: str) -> None:
    """``message`` to the user: a WARNING in the log and a :class:`CalibrationWarning` at the caller's line (only
    the log, at INFO, inside :func:`warnings_shown_by_caller`)."""
    if _SHOWN_BY_CALLER.get():
        _logger.info("capture: %s", message)
        return
    _logger.warning("capture: %s", message)
    warnings.warn(message, CalibrationWarning, stacklevel=3)  # the line that built the CaptureService


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
        Homography, phase and trigger delay (default: uncalibrated). One made for another rig, camera or
        resolution (:attr:`CaptureCalibration.rig`) is refused with the words a calibration file made for another
        rig is refused with. One whose sync was measured at another timing than the plan's is used with its phase
        as a guess: a :class:`~flexvox_calibration.errors.CalibrationWarning` and a WARNING in the log say so, and
        :attr:`warnings` and :attr:`CaptureResult.warnings` hold it.
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
    progress_every_s : float
        How often :attr:`events` publishes ``progress`` while the capture runs.

    Raises
    ------
    CaptureError
        For a bad argument, or an existing ``path`` without ``overwrite``.
    flexvox_calibration.capture_setup.CalibrationRefused
        For a calibration made for another rig, camera or resolution.

    Attributes
    ----------
    warnings : list of str
        What the capture is made with that is worth reading: the calibration's at this timing
        (:meth:`CaptureCalibration.for_plan`), and after :meth:`start` the rig set-up's notes.
    engine : AcquisitionEngine
        The devices' side.
    sink : RecordingSink
        The recording's side.
    events : CaptureEvents
        ``started``, ``progress`` and ``finished``, to subscribe to before :meth:`start`.
    """

    def __init__(self, rig: Rig, plan: CapturePlan, path, *, frames: int | None = None,
                 calibration: CaptureCalibration | None = None, sync: SyncSetting | None = None,
                 queue_policy: QueuePolicy | None = None, projector_size=None, storage: dict | None = None,
                 ground_truth: bool = False,
                 writer_factory: Callable | None = None, overwrite: bool = False, durable: bool = False,
                 rig_info: dict | None = None, progress_every_s: float = 0.2):
        if not isinstance(plan, CapturePlan):
            raise CaptureError(f"`plan` must be a CapturePlan (flexvox_app.capture.plan); got {type(plan).__name__}")
        try:
            self.code = plan.code
        except ValueError as exc:
            raise CaptureError(f"`plan`: {exc}") from None
        if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int) or frames < 1):
            raise CaptureError(f"`frames` must be a whole number >= 1 or None; got {frames!r}")
        if calibration is not None and not isinstance(calibration, CaptureCalibration):
            raise CaptureError(f"`calibration` must be a CaptureCalibration (flexvox_calibration.capture_setup); got "
                               f"{type(calibration).__name__}")
        if not 0 < progress_every_s <= 60:
            raise CaptureError(f"`progress_every_s` must be in (0, 60] s; got {progress_every_s!r}")
        self.calibration = calibration or CaptureCalibration()
        check_calibration_rig(self.calibration, rig, projector_size)  # again at start() if the rig cannot say yet
        self.rig = rig
        self.plan = plan
        self.path = check_output(path, overwrite=overwrite)
        self.n_target = frames
        self.sync_setting = sync or SyncSetting()
        self.policy = queue_policy or QueuePolicy()
        self.K = int(self.code.shape[2])
        self.phase_slots, self.trigger_delay_us, self.warnings = self.calibration.for_plan(self.K, plan.period_us)
        guess = self.calibration.timing_guess(self.K, plan.period_us)
        if guess:
            _warn(guess)
        self.engine = AcquisitionEngine(rig, plan, self.calibration, self.sync_setting, projector_size=projector_size)
        self.sink = RecordingSink(self.path, plan, self.calibration, target=frames, storage=storage,
                                  ground_truth=self.engine.ground_truth() if ground_truth else None,
                                  writer_factory=writer_factory, overwrite=overwrite, durable=durable,
                                  rig_info=rig_info)
        self.events = CaptureEvents()
        self._progress_every_s = float(progress_every_s)

        self._queue: queue.Queue = queue.Queue(maxsize=self.policy.capacity)
        self._latest = LatestFrame()
        self._stop = threading.Event()
        self._reader_done = threading.Event()
        self._done = threading.Event()
        self._events_done = threading.Event()  # the last progress and finished delivered
        self._events_thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._state = CaptureState.IDLE
        self._threads: list[threading.Thread] = []
        self._error: str | None = None
        self._result: CaptureResult | None = None
        # the reader's counters (the sink counts what it wrote)
        self._received = 0
        self._queue_drops = 0
        self._max_depth = 0
        self._t_start = 0.0
        self._t_first = None
        self._t_last_arrival = None
        self._first_stamp = self._last_stamp = None
        self._first_id: int | None = None
        self._last_seen_id: int | None = None

    def __repr__(self) -> str:
        target = f"{self.n_target} frames" if self.n_target is not None else "until stopped"
        result = self._result
        done = (f"; {result.reason}: {result.stats.rows_written} rows written ({result.stats.drops} dropped)"
                if result is not None else "")
        return (f"<CaptureService {self._state.value}: {target} of tile {self.plan.tile[0]}x{self.plan.tile[1]} "
                f"(K = {self.K}) at {self.plan.camera_hz:g} Hz into {self.path.name}, rig {self.rig.name!r}{done}>")

    # ------------------------------------------------------------------ public
    @property
    def state(self) -> CaptureState:
        """The capture's state."""
        return self._state

    @property
    def setup(self) -> RigSetup | None:
        """How the rig was set up (after :meth:`start`)."""
        return self.engine.setup

    @property
    def frame_period_s(self) -> float:
        """The camera frame period set up on the rig (K projector periods)."""
        return self.engine.frame_period_s

    @property
    def first_frame_id(self) -> int | None:
        """The camera's id of the recording's first frame (None before it arrives): row ``r`` holds id
        ``first_frame_id + r``."""
        with self._lock:
            return self._first_id

    def latest(self) -> tuple[Frame | None, int]:
        """The newest frame for display and its sequence number (never blocks capture)."""
        return self._latest.get()

    def stats(self) -> CaptureStats:
        """A snapshot of the counters."""
        now = time.perf_counter()
        rows, drops, write_busy, t_last_write = self.sink.counters()
        with self._lock:
            t0 = self._t_first
            span_w = (t_last_write - t0) if (t0 is not None and t_last_write is not None) else 0.0
            span_c = (self._t_last_arrival - t0) if (t0 is not None and self._t_last_arrival is not None) else 0.0
            return CaptureStats(
                frames_received=self._received, rows_written=rows, drops=drops,
                queue_drops=self._queue_drops, queue_depth=self._queue.qsize(),
                queue_capacity=self.policy.capacity, max_queue_depth=self._max_depth,
                write_rate_hz=(rows - 1) / span_w if span_w > 0 else 0.0,
                camera_rate_hz=self._camera_rate(span_c),
                writer_capacity_hz=rows / write_busy if write_busy > 0 else 0.0,
                elapsed_s=(now - self._t_start) if self._t_start else 0.0,
                state=self._state.value,
                finishing=self.sink.finishing,
            )

    def _camera_rate(self, arrival_span_s: float) -> float:
        """The camera's frame rate on its own clock: frame ids over timestamps (frames the driver delivers in a burst
        after a stall do not raise it); by arrival when the timestamps do not advance. Called under the lock."""
        first, last = self._first_stamp, self._last_stamp
        if first is not None and last is not None and last > first and self._last_seen_id > self._first_id:
            return (self._last_seen_id - self._first_id) / (last - first)
        return (self._received - 1) / arrival_span_s if arrival_span_s > 0 else 0.0

    def start(self) -> None:
        """Take the recording's path, set up the devices and start capturing on worker threads.

        Raises
        ------
        CaptureError
            When another capture writes the path, or a device refuses its setup (the devices are
            stopped and closed again).
        """
        if self._state is not CaptureState.IDLE:
            raise CaptureError(f"cannot start: the capture is {self._state.value} (a service captures once)")
        self.sink.claim()  # one writer per recording: refused here, before any device is touched
        try:
            setup = self.engine.set_up()
        except CaptureError:
            self.sink.release()
            raise
        self.warnings = list(setup.warnings)
        self.sink.prepare(setup, setup.rig_attrs(self.rig))
        self._t_start = time.perf_counter()
        self._state = CaptureState.RUNNING
        self._threads = [threading.Thread(target=target, name=f"flexvox-capture-{name}", daemon=True)
                         for name, target in (("reader", self._read_loop), ("writer", self._write_loop),
                                              ("events", self._publish_loop))]
        self._events_thread = self._threads[2]
        for thread in self._threads:
            thread.start()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait until the capture has ended and its last ``progress`` and ``finished`` events have been delivered.

        Parameters
        ----------
        timeout_s : float or None
            The longest wait in seconds; None waits as long as it takes.

        Returns
        -------
        bool
            True when the capture ended and every subscriber to ``finished`` has returned; False when
            ``timeout_s`` passed first, or the capture was not started (call it again later). Called from a
            subscriber (on the event thread), it waits for the capture's end only: the events it is delivering
            cannot wait for themselves.
        """
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        if not self._done.wait(timeout_s):
            return False
        if threading.current_thread() is self._events_thread:
            return True
        remaining = None if deadline is None else max(0.0, deadline - time.monotonic())
        return self._events_done.wait(remaining)

    def stop(self, timeout_s: float = 10.0) -> CaptureResult | None:
        """Stop capturing, keep what was captured, and return the result once ``finished`` was delivered.

        When :meth:`stop` returns, the last ``progress`` and the ``finished`` events have been emitted and
        their subscribers have returned (in a notebook their output stays in the cell that stopped the capture).

        Parameters
        ----------
        timeout_s : float
            The longest wait in seconds, for the threads to finish and the events to be delivered.

        Returns
        -------
        CaptureResult or None
            None only when the threads did not finish within ``timeout_s`` (the disk hangs): call
            :meth:`wait` later, then read :attr:`result`. When the capture ended but a subscriber still runs
            after ``timeout_s``, the result is returned and a warning logged.
        """
        if self._state is CaptureState.IDLE:
            raise CaptureError("cannot stop: the capture was not started")
        if self._state is CaptureState.RUNNING:
            self._state = CaptureState.STOPPING
        self._stop.set()
        if not self.wait(timeout_s):
            if self._result is None:
                _logger.error("capture threads did not finish within %g s", timeout_s)
                return None
            _logger.warning("capture: a subscriber to its events still runs %g s after the stop", timeout_s)
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
        self._done.wait(timeout_s)
        result = self.stop()
        if result is None:
            raise CaptureError("the capture threads did not finish; the disk may hang")
        return result

    # ------------------------------------------------------------------ threads
    def _fail(self, message: str) -> None:
        with self._lock:
            if self._error is None:
                self._error = message
        _logger.error("capture: %s", message)
        self._stop.set()

    def _read_loop(self) -> None:
        try:
            for frame in self.engine.frames(self._stop):
                now = time.perf_counter()
                with self._lock:
                    if self._t_first is None:
                        self._t_first = now
                        self._first_id = frame.frame_id
                        self._first_stamp = frame.timestamp_s
                    self._t_last_arrival = now
                    self._last_stamp = frame.timestamp_s
                    self._received += 1
                    self._last_seen_id = frame.frame_id
                self._latest.put(frame)
                if not self._enqueue(frame):
                    break
                if self.n_target is not None and frame.frame_id - self._first_id >= self.n_target - 1:
                    break
        except CameraStopped as exc:
            self._fail(str(exc))
        except Exception as exc:  # noqa: BLE001 - a reader bug must still end the capture cleanly
            _logger.exception("capture reader crashed")
            self._fail(f"the camera reader crashed: {type(exc).__name__}: {exc}")
        finally:
            self.engine.tear_down()
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
        sink = self.sink
        try:
            while not sink.target_reached:
                try:
                    frame = self._queue.get(timeout=0.1)
                except queue.Empty:
                    if self._reader_done.is_set() and self._queue.empty():
                        break
                    continue
                sink.write(frame)
            sink.write_gap_through(self._last_seen_id)
        except (OSError, RecordingError) as exc:
            self._fail(sink.refused or f"cannot write {self.path}: {os_message(exc)}")
        except Exception as exc:  # noqa: BLE001 - a writer bug must still end the capture cleanly
            _logger.exception("capture writer crashed")
            self._fail(f"the recording writer crashed: {type(exc).__name__}: {exc}")
        finally:
            self._stop.set()
            if not self._reader_done.wait(max(5.0, 3 * self.sync_setting.read_slice_s)):
                _logger.error("capture: the camera reader did not stop in time")
            if self._error is not None:
                reason = "error"
            elif self.n_target is None or sink.rows < self.n_target:
                reason = "stopped"
            else:
                reason = "done"
            self._finish(reason)

    def _finish(self, reason: str) -> None:
        sink = self.sink
        try:
            if sink.refused is None:
                sink.create(None)  # a capture stopped before its first frame: an empty recording
        except (OSError, RecordingError) as exc:
            self._fail(sink.refused or f"cannot create {self.path}: {os_message(exc)}")
            reason = "error"
        s = self.stats()
        writer_note = sink.finalise(reason, {
            "reason": reason, "error": self._error, "frames_received": s.frames_received,
            "rows": s.rows_written, "drops": s.drops, "queue_drops": s.queue_drops,
            "write_rate_hz": s.write_rate_hz, "camera_rate_hz": s.camera_rate_hz,
            "queue": asdict(self.policy)})
        self._state = CaptureState.DONE
        held, where = sink.what_was_recorded()
        s = self.stats()
        drops = f"{s.drops} dropped ({s.queue_drops} by the queue)"
        if reason == "error":
            message = f"capture stopped: {self._error}{writer_note}; {where}; {drops}"
        else:
            verb = "captured" if reason == "done" else "stopped after"
            message = f"{verb} {s.rows_written} frames: {drops}; {where}{writer_note}"
        self._result = CaptureResult(self.path, reason, message, held, s, self._error, tuple(self.warnings))
        _logger.info("%s", message)
        self._done.set()

    def _publish_loop(self) -> None:
        """Emit ``started``, ``progress`` every ``progress_every_s`` until the end, then the last ``progress`` and
        ``finished``."""
        events = self.events
        try:
            events.started.emit(self.setup)
            while not self._done.wait(self._progress_every_s):
                events.progress.emit(self.stats())
            result = self._result
            events.progress.emit(result.stats)
            events.finished.emit(result)
        finally:
            self._events_done.set()
