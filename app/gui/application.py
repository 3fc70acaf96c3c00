"""Building and running the application (what ``flexvox app`` calls)."""

from __future__ import annotations

import logging
import sys

import pyqtgraph as pg
from PySide6.QtWidgets import QApplication

from app.gui.expected_quality import load_table
from app.gui.main_window import MainWindow
from app.gui.qt_jobs import JobRunner
from app.gui.rig_service import RigService
from app.gui.settings import AppSettings, default_settings

_logger = logging.getLogger(__name__)


def configure_pyqtgraph() -> None:
    """pyqtgraph options the app relies on: row-major images (numpy's (H, W) order), antialiasing."""
    pg.setConfigOptions(imageAxisOrder="row-major", antialias=True)


def ensure_application() -> QApplication:
    """The running QApplication, or a new one named flexvox."""
    app = QApplication.instance()
    if app is None:
        app = QApplication(sys.argv[:1])
        app.setOrganizationName("flexvox")
        app.setApplicationName("flexvox")
    return app


def build_window(rig, *, settings: AppSettings | None = None, recording=None, runner: JobRunner | None = None,
                 capture_factory=None) -> MainWindow:
    """The main window over ``rig`` (a :class:`rig_drivers.profile.Rig`), opening ``recording`` if given."""
    configure_pyqtgraph()
    settings = settings or default_settings()
    window = MainWindow(RigService(rig), settings, runner or JobRunner(), load_table(),
                        capture_factory=capture_factory)
    if recording is not None:
        window.show_workspace("Review")
        window.review.open_recording(recording)
    return window


def launch(rig, *, recording=None, settings: AppSettings | None = None) -> int:
    """Show the window and run the event loop; returns the exit status."""
    app = ensure_application()
    window = build_window(rig, settings=settings, recording=recording)
    window.show()
    status = app.exec()
    _logger.info("event loop ended with %s", status)
    return int(status)
