"""Building and running the application (what ``flexvox app`` calls).

``ensure_application`` and ``configure_pyqtgraph`` live in :mod:`flexvox_app.gui.widgets.qapp` and are
re-exported here for callers that build a window.

:func:`launch` shows a window at once (:class:`StartupWindow`, which says what is loading) and only then
opens the rig (when it is given as a callable), imports the workspaces and builds the main window
behind it, so the operator sees the application start before the slow part of starting it. This
module imports only Qt at its top for that reason (pyqtgraph loads with the workspaces).
"""

from __future__ import annotations

import html
import importlib
import logging
import threading
import time
from typing import TYPE_CHECKING

from PySide6.QtCore import QEventLoop, Qt, QTimer
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from flexvox_app.gui.widgets.qapp import DEFAULT_SIZE, configure_pyqtgraph, ensure_application

if TYPE_CHECKING:
    from flexvox_app.gui.main_window import MainWindow
    from flexvox_app.gui.widgets.qt_jobs import JobRunner
    from flexvox_app.gui.widgets.settings import AppSettings

__all__ = ["StartupWindow", "build_window", "configure_pyqtgraph", "ensure_application", "launch"]

_logger = logging.getLogger(__name__)


def build_window(rig, *, settings: AppSettings | None = None, recording=None, runner: JobRunner | None = None,
                 capture_factory=None) -> MainWindow:
    """The main window over ``rig`` (a :class:`rig_drivers.interfaces.Rig`), opening ``recording`` if given."""
    from flexvox_app.gui.main_window import MainWindow
    from flexvox_app.gui.models.expected_quality import load_table
    from flexvox_app.gui.models.rig_service import RigService
    from flexvox_app.gui.widgets.qt_jobs import JobRunner
    from flexvox_app.gui.widgets.settings import default_settings

    configure_pyqtgraph()
    settings = settings or default_settings()
    window = MainWindow(RigService(rig), settings, runner or JobRunner(), load_table(),
                        capture_factory=capture_factory)
    if recording is not None:
        window.show_workspace("Review")
        window.review.open_recording(recording)
    return window


STEPS = (
    ("start", "starting flexvox …"),
    ("rig", "opening the rig …"),
    ("numerics", "loading the numerics (NumPy, SciPy, Zarr, OpenCV) and designing the code …"),
    ("workspaces", "loading the Calibrate, Capture and Review workspaces …"),
    ("window", "building the window …"),
)
"""The start-up's steps in order, as the start-up window lists them."""

PRELOADED = ("flexvox_core.design", "flexvox_core.methods", "flexvox_app.capture",
             "flexvox_app.gui.models.calibration_model",
             "flexvox_app.gui.models.review_model", "flexvox_app.gui.models.jobs")
"""Qt-free modules the workspaces import, loaded on the start-up's loader thread while the window paints."""


class StartupWindow(QWidget):
    """The window shown the moment ``flexvox app`` starts, listing the steps of the start (the one under way, the
    ones done with their seconds) until the main window replaces it."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setWindowTitle("flexvox — starting")
        self.setAutoFillBackground(True)
        self.label = QLabel("starting flexvox …")
        self.label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        self.label.setStyleSheet("font-size: 16px")
        QVBoxLayout(self).addWidget(self.label)
        self.resize(*DEFAULT_SIZE)
        self.done: list[tuple[str, float]] = []  # (step, seconds)
        self.current = ""
        self._since = time.perf_counter()

    def show_now(self, timeout_s: float = 3.0) -> None:
        """Show the window and let the window system map and paint it before the slow part starts (at most
        ``timeout_s``): a window shown while the thread that should paint it is busy stays black."""
        self.show()
        app = ensure_application()
        end = time.perf_counter() + timeout_s
        handle = self.windowHandle()
        while time.perf_counter() < end and (handle is None or not handle.isExposed()):
            app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 20)
            time.sleep(0.005)
            handle = self.windowHandle()
        self.refresh()

    def say(self, text: str) -> None:
        """Start the step ``text`` (the previous one is done) and show it now."""
        now = time.perf_counter()
        if self.current:
            self.done.append((self.current, now - self._since))
        self.current, self._since = text, now
        _logger.info("start-up: %s", text)
        self.refresh()

    def refresh(self) -> None:
        """Paint the steps now, the one under way with its seconds so far."""
        lines = [f"<span style='color:gray'>✓ {html.escape(step)} {seconds:.1f} s</span>" for step, seconds
                 in self.done]
        if self.current:
            lines.append(f"<b>{html.escape(self.current)}</b> {time.perf_counter() - self._since:.0f} s")
        self.label.setText("<br>".join(lines))
        self.repaint()
        ensure_application().processEvents()


class _Loader(threading.Thread):
    """Opens the rig (when given as a callable), then imports :data:`PRELOADED` and designs the remembered tile's
    code, off the GUI thread, so the start-up window keeps painting meanwhile. ``step`` is the step under way."""

    def __init__(self, rig, tile):
        super().__init__(name="flexvox start-up", daemon=True)
        self.rig, self.tile = rig, tile
        self.step = "rig" if callable(rig) else "numerics"
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            if callable(self.rig):
                self.rig = self.rig()
            self.step = "numerics"
            for name in PRELOADED:
                importlib.import_module(name)
            if self.tile is not None:
                from flexvox_app.capture.plan import designed_code

                try:
                    designed_code(self.tile)
                except ValueError as exc:  # the Capture workspace says it when it shows the code
                    _logger.info("start-up: no code designed for %s: %s", self.tile, exc)
        except BaseException as exc:  # handed to the GUI thread, which raises it
            self.error = exc


def _remembered_tile(settings: AppSettings | None) -> tuple[int, int] | None:
    """The tile the Capture workspace will open with (its setting), when it is a designed identity code."""
    from flexvox_app.gui.widgets.settings import default_settings

    settings = settings or default_settings()
    if settings.get_bool("capture/multiplexed", False):
        return None
    try:
        m, n = (int(v) for v in settings.get_str("capture/tile", "4x4").split("x"))
    except ValueError:
        return None
    return m, n


def launch(rig, *, recording=None, settings: AppSettings | None = None) -> int:
    """Show a window at once, build the application behind it, run the event loop; returns the exit status.

    ``rig`` is a :class:`rig_drivers.interfaces.Rig`, or a callable that opens one. The start-up window is
    painted before anything slow starts and lists each step as it runs: the rig opens, the numerics load and the
    remembered tile's code is designed on a loader thread while the window keeps painting; the workspaces
    are imported and the main window built on the GUI thread (``bench/bench_startup.py`` times each step from the
    ``start-up: …`` log lines).
    """
    t0 = time.perf_counter()
    app = ensure_application()
    startup = StartupWindow()
    startup.show_now()
    startup.say(dict(STEPS)["start"])
    loader = _Loader(rig, _remembered_tile(settings))
    shown = loader.step
    startup.say(dict(STEPS)[shown])  # shown before the loader starts it
    loader.start()
    while loader.is_alive():
        if loader.step != shown:
            shown = loader.step
            startup.say(dict(STEPS)[shown])
        loader.join(0.05)
        startup.refresh()
    if loader.error is not None:
        startup.close()
        raise loader.error
    startup.say(dict(STEPS)["workspaces"])
    importlib.import_module("flexvox_app.gui.main_window")  # Qt widgets and pyqtgraph, on the GUI thread

    startup.say(dict(STEPS)["window"])
    window = build_window(loader.rig, settings=settings, recording=recording)
    window.show()
    startup.close()
    QTimer.singleShot(0, lambda: _logger.info("start-up: the main window is in after %.2f s",
                                              time.perf_counter() - t0))
    status = app.exec()
    _logger.info("event loop ended with %s", status)
    return int(status)
