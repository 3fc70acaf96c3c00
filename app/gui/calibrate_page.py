"""The Calibrate workspace: an honest placeholder until the calibration package's wizards land."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QScrollArea, QVBoxLayout, QWidget


def calibrate_cli_available() -> bool:
    """True when ``flexvox calibrate`` is registered in the command line."""
    from app.cli.main import SUBCOMMANDS

    return any(m.__name__.rsplit(".", 1)[-1] == "calibrate" for m in SUBCOMMANDS)


def calibrate_text(cli_available: bool) -> str:
    """What the page says (rich text)."""
    cli = ("<p>Today, run the whole calibration from a terminal: <code>flexvox calibrate --rig mock</code> "
           "(or <code>--rig RIG.toml</code>; <code>-o CAL.json</code> saves the homography and sync).</p>"
           if cli_available else
           "<p>The command line <code>flexvox calibrate</code> (co-location, homography, shutter masks, "
           "synchronisation) is being written in <code>calibration/</code> and <code>app/cli/calibrate.py</code>; "
           "it is <b>not registered yet</b> in this build, so there is no calibration from the app or the "
           "command line today.</p>")
    return (
        "<h2>Calibrate — not in the app yet</h2>"
        "<p>This workspace will hold three tools, built on the Qt-free <code>calibration</code> package "
        "(another engineer is writing it now):</p>"
        "<ol>"
        "<li><b>Co-location view</b>: the live camera with the expected projector grid overlaid, and the "
        "offset, rotation, scale and parallax numbers updating while you adjust the beam splitter.</li>"
        "<li><b>Homography wizard</b>: Gray-code patterns, progress, decoded coverage, residual heat map, "
        "RMS reprojection error, save.</li>"
        "<li><b>Synchronisation wizard</b>: wiring checklist, trigger test, phase sweep with its leakage plot, "
        "drop and drift test, save.</li>"
        "</ol>"
        + cli +
        "<p>Until then the Capture workspace's live view runs with the rig as it is (the simulated rig needs "
        "no calibration).</p>"
    )


class CalibratePage(QWidget):
    """Says what will be here and which command line exists."""

    def __init__(self, *, cli_available: bool | None = None, parent: QWidget | None = None):
        super().__init__(parent)
        available = calibrate_cli_available() if cli_available is None else cli_available
        self.label = QLabel(calibrate_text(available))
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        self.label.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.label.setMaximumWidth(820)
        inner = QWidget()
        v = QVBoxLayout(inner)
        v.setContentsMargins(24, 16, 24, 16)
        v.addWidget(self.label)
        v.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(inner)
        scroll.setWidgetResizable(True)
        QVBoxLayout(self).addWidget(scroll)
