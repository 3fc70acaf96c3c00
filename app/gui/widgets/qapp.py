"""The one QApplication of the process and the pyqtgraph options the app relies on.

Both the main window (:mod:`flexvox_app.gui.application`) and the projector output that
``flexvox calibrate|capture --projector-screen`` shows (:mod:`flexvox_app.gui.projector.display`) need a
QApplication; they get it here, so neither imports the other.
"""

from __future__ import annotations

import sys

from PySide6.QtWidgets import QApplication

DEFAULT_SIZE = (1280, 800)
"""The first window's size: every workspace's primary actions are in view at this size (and at 1024×700)."""


def configure_pyqtgraph() -> None:
    """pyqtgraph options the app relies on: row-major images (numpy's (H, W) order), antialiasing.

    pyqtgraph is imported here, not at the module's top, so the start-up window needs only Qt."""
    import pyqtgraph as pg

    pg.setConfigOptions(imageAxisOrder="row-major", antialias=True)


def ensure_application() -> QApplication:
    """The running QApplication, or a new one named flexvox."""
    app = QApplication.instance()
    if app is None:
        app = QApplication(sys.argv[:1])
        app.setOrganizationName("flexvox")
        app.setApplicationName("flexvox")
    return app
