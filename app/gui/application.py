"""Building and running the application (what ``flexvox app`` calls).

``ensure_application`` and ``configure_pyqtgraph`` live in :mod:`app.gui.widgets.qapp` and are
re-exported here for callers that build a window.

:func:`launch` shows a window at once (:class:`StartupWindow`, which says what is loading) and only then
opens the rig (when it is given as a callable), imports the workspaces and builds the main window
behind it, so the operator sees the application start before the slow part of starting it. This
module imports only Qt (and pyqtgraph) at its top for that reason.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from app.gui.widgets.qapp import DEFAULT_SIZE, configure_pyqtgraph, ensure_application

if TYPE_CHECKING:
    from app.gui.main_window import MainWindow
    from app.gui.widgets.qt_jobs import JobRunner
    from app.gui.widgets.settings import AppSettings

__all__ = ["StartupWindow", "build_window", "configure_pyqtgraph", "ensure_application", "launch"]

_logger = logging.getLogger(__name__)


def build_window(rig, *, settings: AppSettings | None = None, recording=None, runner: JobRunner | None = None,
                 capture_factory=None) -> MainWindow:
    """The main window over ``rig`` (a :class:`rig_drivers.interfaces.Rig`), opening ``recording`` if given."""
    from app.gui.main_window import MainWindow
    from app.gui.models.expected_quality import load_table
    from app.gui.models.rig_service import RigService
    from app.gui.widgets.qt_jobs import JobRunner
    from app.gui.widgets.settings import default_settings

    configure_pyqtgraph()
    settings = settings or default_settings()
    window = MainWindow(RigService(rig), settings, runner or JobRunner(), load_table(),
                        capture_factory=capture_factory)
    if recording is not None:
        window.show_workspace("Review")
        window.review.open_recording(recording)
    return window


class StartupWindow(QWidget):
    """The window shown the moment ``flexvox app`` starts, saying what is loading, until the main window replaces it."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setWindowTitle("flexvox — starting")
        self.label = QLabel("starting …")
        self.label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.label.setStyleSheet("font-size: 16px")
        QVBoxLayout(self).addWidget(self.label)
        self.resize(*DEFAULT_SIZE)

    def say(self, text: str) -> None:
        """Show ``text`` now (the event loop does not run while the application loads)."""
        self.label.setText(text)
        _logger.info("start-up: %s", text)
        self.repaint()
        ensure_application().processEvents()


def launch(rig, *, recording=None, settings: AppSettings | None = None) -> int:
    """Show a window at once, build the application behind it, run the event loop; returns the exit status.

    ``rig`` is a :class:`rig_drivers.interfaces.Rig`, or a callable that opens one (it then opens behind the
    startup window too).
    """
    app = ensure_application()
    startup = StartupWindow()
    startup.show()
    startup.say("starting flexvox …")
    if callable(rig):
        startup.say("opening the rig …")
        rig = rig()
    startup.say("loading the Calibrate, Capture and Review workspaces …")
    window = build_window(rig, settings=settings, recording=recording)
    window.show()
    startup.close()
    status = app.exec()
    _logger.info("event loop ended with %s", status)
    return int(status)
