"""The live camera stream on a QThread: a worker reads frames and hands them to the GUI by signal."""

from __future__ import annotations

import logging
import threading

from PySide6.QtCore import QObject, QThread, Signal, Slot

from rig_drivers.errors import DeviceError

_logger = logging.getLogger(__name__)


class FrameReader(QObject):
    """Reads frames from a camera until stopped (lives on its own QThread)."""

    frame = Signal(object)
    """A :class:`rig_drivers.interfaces.Frame`."""
    failed = Signal(str)
    """Reading stopped on an error (in words)."""
    finished = Signal()

    def __init__(self, camera, *, timeout_s: float = 1.0):
        super().__init__()
        self.camera = camera
        self.timeout_s = timeout_s
        self._stop = threading.Event()

    def stop(self) -> None:
        """Ask the loop to end after the frame it is waiting for (thread-safe)."""
        self._stop.set()

    @Slot()
    def run(self) -> None:
        """The read loop."""
        try:
            while not self._stop.is_set():
                try:
                    f = self.camera.read_frame(self.timeout_s)
                except (DeviceError, OSError) as exc:
                    if not self._stop.is_set():
                        _logger.warning("live view: %s", exc)
                        self.failed.emit(str(exc))
                    break
                self.frame.emit(f)
        finally:
            self.finished.emit()


class LiveStream(QObject):
    """Owns the reader thread: :meth:`start`, :meth:`stop` (joins the thread)."""

    frame = Signal(object)
    failed = Signal(str)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._thread: QThread | None = None
        self._reader: FrameReader | None = None

    @property
    def running(self) -> bool:
        """True while the reader thread runs."""
        return self._thread is not None and self._thread.isRunning()

    def start(self, camera, *, timeout_s: float = 1.0) -> None:
        """Start reading ``camera`` (already acquiring) on a new thread."""
        self.stop()
        thread = QThread()
        reader = FrameReader(camera, timeout_s=timeout_s)
        reader.moveToThread(thread)
        thread.started.connect(reader.run)
        reader.finished.connect(thread.quit)
        reader.frame.connect(self.frame)
        reader.failed.connect(self.failed)
        self._thread, self._reader = thread, reader
        thread.start()

    def stop(self, timeout_ms: int = 3000) -> bool:
        """Stop reading and wait for the thread; False when it did not end in time."""
        if self._thread is None:
            return True
        self._reader.stop()
        self._thread.quit()
        ok = self._thread.wait(timeout_ms)
        if not ok:  # keep the references: dropping a running QThread would crash
            _logger.error("live view thread did not stop within %d ms", timeout_ms)
            return False
        self._thread, self._reader = None, None
        return True
