"""A capture's events as Qt signals, delivered on the GUI thread.

The capture service emits its events (:class:`flexvox_app.capture.events.CaptureEvents`) on a thread of its
own. :class:`CaptureSignals` lives on the GUI thread and re-emits each as a Qt signal, which Qt
queues to the slots there, so a widget subscribes to a capture as to any Qt signal and never reads
the service's state on a timer. Each signal carries the capture it is about, so a slot can ignore a
capture it no longer shows.
"""

from __future__ import annotations

from PySide6.QtCore import QObject, Signal


class CaptureSignals(QObject):
    """The events of the capture being followed (:meth:`follow`), as Qt signals."""

    started = Signal(object, object)
    """``(capture, setup)``: the rig is set up and frames are being read."""
    progress = Signal(object, object)
    """``(capture, stats)``: its counters, every ``progress_every_s`` and once more at the end."""
    finished = Signal(object, object)
    """``(capture, result)``: it has ended and its recording is finalised."""

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._capture = None
        self._relays: tuple = ()

    def follow(self, capture) -> None:
        """Relay the events of ``capture`` (a :class:`~flexvox_app.capture.service.CaptureService`); the capture
        followed
        until now is let go."""
        self.release()

        def started(setup, c=capture):
            self.started.emit(c, setup)

        def progress(stats, c=capture):
            self.progress.emit(c, stats)

        def finished(result, c=capture):
            self.finished.emit(c, result)

        events = capture.events
        self._relays = ((events.started, started), (events.progress, progress), (events.finished, finished))
        for signal, relay in self._relays:
            signal.connect(relay)
        self._capture = capture

    def release(self) -> None:
        """Relay nothing more from the capture followed (events already queued are still delivered)."""
        for signal, relay in self._relays:
            signal.disconnect(relay)
        self._relays = ()
        self._capture = None
