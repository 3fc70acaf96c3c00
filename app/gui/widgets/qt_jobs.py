"""Long work off the GUI thread: callables run on a QThreadPool, with progress, result and cancel.

A job is ``fn(token, progress) -> result``; it polls ``token`` (a :class:`~flexvox_app.gui.models.jobs.CancelToken`)
and raises :class:`~flexvox_app.gui.models.jobs.Cancelled` to stop. Its :class:`JobHandle` carries Qt signals
emitted from the worker thread and delivered, queued, on the GUI thread.

Callbacks are given to :meth:`JobRunner.submit` so they are connected *before* the job starts: a
fast job may finish before the caller could connect to the handle it gets back (a queued signal
reaches only the slots connected when it was emitted). Once :meth:`JobRunner.shutdown` ran (the
window is closing), callbacks still queued are dropped: the widgets they would update are going, and a
job submitted after it is refused (its handle says "cancelled"; nothing runs).
``handle.outcome`` ("finished", "failed", "cancelled") and ``handle.running`` (False once every
callback ran) serve those who poll.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from flexvox_app.gui.models.jobs import Cancelled, CancelToken

_logger = logging.getLogger(__name__)


class JobHandle(QObject):
    """Signals and cancel token of one submitted job."""

    progress = Signal(int, int)
    """(done, total) as the job reports it."""
    finished = Signal(object)
    """The job's result."""
    failed = Signal(str)
    """The job raised: its message in words (the traceback is logged)."""
    cancelled = Signal()
    """The job stopped because it was cancelled."""
    done = Signal()
    """Emitted last, whatever the outcome."""

    def __init__(self, name: str, token: CancelToken):
        super().__init__()
        self.name = name
        self.token = token
        self.running = True
        self.outcome: str | None = None
        self.result = None
        self.message = ""

    def cancel(self) -> None:
        """Ask the job to stop at its next check (it emits ``cancelled``)."""
        self.token.cancel()


class _Runnable(QRunnable):
    def __init__(self, fn, handle: JobHandle):
        super().__init__()
        self.setAutoDelete(False)  # the runner keeps the Python object until `done`
        self._fn = fn
        self._handle = handle

    def run(self) -> None:
        h = self._handle
        try:
            result = self._fn(h.token, h.progress.emit)
        except Cancelled:
            _logger.info("job %s cancelled", h.name)
            h.outcome = "cancelled"
            h.cancelled.emit()
        except Exception as exc:  # a worker must report every failure to the GUI, never die silently
            if isinstance(exc, ValueError | OSError):  # the operator's input (a wrong file): one line, as shown
                _logger.warning("job %s failed: %s", h.name, exc)
                _logger.debug("job %s failed", h.name, exc_info=True)
            else:  # a bug: its traceback
                _logger.exception("job %s failed", h.name)
            h.message = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
            h.outcome = "failed"
            h.failed.emit(h.message)
        else:
            h.result = result
            h.outcome = "finished"
            h.finished.emit(result)
        finally:
            h.done.emit()


class JobRunner(QObject):
    """Runs jobs on a thread pool (its own by default, so tests and the app do not share one).

    Parameters
    ----------
    pool : QThreadPool, optional
    """

    def __init__(self, pool: QThreadPool | None = None, parent: QObject | None = None):
        super().__init__(parent)
        self.pool = pool or QThreadPool(self)
        self._live: dict[JobHandle, _Runnable] = {}
        self._shut = False

    def submit(self, name: str, fn: Callable[[CancelToken, Callable[[int, int], None]], object], *,
               on_progress=None, on_finished=None, on_failed=None, on_cancelled=None, on_done=None) -> JobHandle:
        """Run ``fn(token, progress)`` off the GUI thread, with the callbacks connected before it starts.

        The callbacks run on the GUI thread: ``on_progress(done, total)``, ``on_finished(result)``,
        ``on_failed(message)``, ``on_cancelled()``, then ``on_done()`` whatever happened.
        """
        handle = JobHandle(name, CancelToken())
        if self._shut:  # the window is closing: its thread pool takes no new work
            _logger.warning("job %s refused: the job runner was shut down", name)
            handle.running, handle.outcome, handle.message = False, "cancelled", "the job runner was shut down"
            handle.token.cancel()
            return handle
        for signal, slot in ((handle.progress, on_progress), (handle.finished, on_finished),
                             (handle.failed, on_failed), (handle.cancelled, on_cancelled)):
            if slot is not None:
                signal.connect(self._unless_shut(slot, name))
        handle.done.connect(lambda h=handle: self._forget(h))
        if on_done is not None:
            handle.done.connect(self._unless_shut(on_done, name))
        runnable = _Runnable(fn, handle)
        self._live[handle] = runnable
        self.pool.start(runnable)
        return handle

    def _unless_shut(self, slot, name: str):
        """``slot``, or nothing once the runner was shut down (its callers' widgets are being deleted)."""

        def call(*args):
            if self._shut:
                _logger.debug("job %s ended after shutdown: its callback is dropped", name)
                return
            slot(*args)

        return call

    def _forget(self, handle: JobHandle) -> None:
        handle.running = False
        self._live.pop(handle, None)

    @property
    def active(self) -> int:
        """Jobs submitted and not yet done."""
        return len(self._live)

    def cancel_all(self) -> None:
        """Cancel every running job."""
        for h in list(self._live):
            h.cancel()

    def shutdown(self, timeout_ms: int = 5000) -> bool:
        """Cancel every job and wait for the pool; False when a job did not stop in time.

        Callbacks of jobs that end after this are dropped (see the module docstring).
        """
        self._shut = True
        self.cancel_all()
        return self.pool.waitForDone(timeout_ms)
