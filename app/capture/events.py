"""What a capture publishes as it runs (Qt-free): a small signal, and the capture's three events.

A front end subscribes instead of asking the service for its state on a timer::

    service.events.progress.connect(lambda stats: print(stats.rows_written))
    service.events.finished.connect(lambda result: print(result.message))

The service emits every event on one thread of its own (``flexvox-capture-events``), never on the
threads that read the camera or write the disk, so a slow subscriber (a terminal nobody reads, a
busy window) never holds a frame up. A callback runs on that thread: a Qt window hands the event to
its GUI thread (``flexvox_app.gui.capture.capture_signals``). What a callback raises is logged and
ignored: a subscriber cannot stop a capture. Qt-free models driven on the GUI thread (Capture's
``flexvox_app.gui.models.capture_model``, Review's ``review_model`` and its parts) use the same :class:`Signal`,
letting their callbacks' errors through.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

_logger = logging.getLogger(__name__)


class Signal:
    """Callbacks called, in the order connected, each time the signal is emitted.

    Parameters
    ----------
    name : str
        Its name in log messages.
    contain : bool
        Log what a callback raises and go on with the next (a capture's events: a subscriber cannot stop
        the capture). False: it reaches the emitter (a model driven on the GUI thread, whose callbacks'
        errors the event loop reports).
    """

    def __init__(self, name: str, *, contain: bool = True):
        self.name = name
        self.contain = bool(contain)
        self._lock = threading.Lock()
        self._callbacks: list[Callable] = []

    def connect(self, callback: Callable) -> Callable:
        """Call ``callback(*args)`` on every emit; returns it (so it can serve as a decorator)."""
        if not callable(callback):
            raise TypeError(f"`callback` of {self.name} must be callable; got {type(callback).__name__}")
        with self._lock:
            self._callbacks.append(callback)
        return callback

    def disconnect(self, callback: Callable) -> None:
        """Stop calling ``callback`` (nothing happens when it is not connected)."""
        with self._lock:
            self._callbacks = [c for c in self._callbacks if c != callback]

    def __len__(self) -> int:
        with self._lock:
            return len(self._callbacks)

    def emit(self, *args) -> None:
        """Call every connected callback with ``args``, on this thread; one that raises is logged and skipped
        (unless the signal does not ``contain`` errors)."""
        with self._lock:
            callbacks = list(self._callbacks)
        for callback in callbacks:
            if not self.contain:
                callback(*args)
                continue
            try:
                callback(*args)
            except Exception:  # noqa: BLE001 - a subscriber's bug must not end the capture
                _logger.exception("a subscriber to %s failed", self.name)


class CaptureEvents:
    """The events of one capture, emitted in this order on the service's event thread.

    Attributes
    ----------
    started : Signal
        ``(setup)``: the rig is set up (a :class:`~flexvox_app.capture.rig_setup.RigSetup`) and frames are being read.
    progress : Signal
        ``(stats)``: a :class:`~flexvox_app.capture.status.CaptureStats`, every ``progress_every_s`` while the capture
        runs, and once more with the final counters when it has ended.
    finished : Signal
        ``(result)``: the :class:`~flexvox_app.capture.status.CaptureResult`, once, when the recording is finalised.
    """

    def __init__(self):
        self.started = Signal("started")
        self.progress = Signal("progress")
        self.finished = Signal("finished")

    def disconnect(self, callback: Callable) -> None:
        """Take ``callback`` off every event."""
        for signal in (self.started, self.progress, self.finished):
            signal.disconnect(callback)
