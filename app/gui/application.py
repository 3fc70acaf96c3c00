"""Building and running the application (what ``flexvox app`` calls).

``ensure_application`` and ``configure_pyqtgraph`` live in :mod:`app.gui.widgets.qapp` and are
re-exported here for callers that build a window.
"""

from __future__ import annotations

import logging

from app.gui.main_window import MainWindow
from app.gui.models.expected_quality import load_table
from app.gui.models.rig_service import RigService
from app.gui.widgets.qapp import configure_pyqtgraph, ensure_application
from app.gui.widgets.qt_jobs import JobRunner
from app.gui.widgets.settings import AppSettings, default_settings

__all__ = ["build_window", "configure_pyqtgraph", "ensure_application", "launch"]

_logger = logging.getLogger(__name__)


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
