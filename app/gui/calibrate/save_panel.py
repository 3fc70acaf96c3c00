"""The Calibrate workspace's "Save" box: write a successful calibration, or hand it to Capture."""

from __future__ import annotations

import html
from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QFileDialog, QGroupBox, QHBoxLayout, QLineEdit, QPushButton, QVBoxLayout

from flexvox_app.gui.models.calibration_model import CalibrationOutcome
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.widgets.questions import replace_question
from flexvox_app.gui.widgets.rich_text import AMBER, GREEN, RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine


class SavePanel(QGroupBox):
    """Save the calibration file (:func:`flexvox_calibration.files.save_calibration`) or use it for capture.

    A failed calibration is never written and never handed over.
    """

    saved = Signal(object)
    """The path written."""
    use_for_capture = Signal(object)
    """The successful :class:`CalibrationOutcome` the operator hands to the Capture workspace."""

    def __init__(self, settings: AppSettings, parent=None):
        super().__init__("Save", parent)
        self.settings = settings
        self.outcome: CalibrationOutcome | None = None
        self.saved_path: Path | None = None
        """Where the current outcome was saved (None: not saved)."""
        self.path = QLineEdit(settings.get_str("calibrate/path", ""))
        self.path.setPlaceholderText("folder/rig-calibration.json")
        self.browse = QPushButton("Browse…")
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(self.browse)
        self.save_button = QPushButton("Save calibration")
        self.save_button.setEnabled(False)
        self.label = StatusLine("run a calibration first", lines=2)
        self.use_button = QPushButton("Use for capture")
        self.use_button.setToolTip("hand this homography, sync phase and trigger delay to the Capture workspace")
        self.use_button.setEnabled(False)
        buttons = QHBoxLayout()
        buttons.addWidget(self.save_button)
        buttons.addWidget(self.use_button)
        v = QVBoxLayout(self)
        v.addLayout(row)
        v.addLayout(buttons)
        v.addWidget(self.label)
        self.save_button.clicked.connect(lambda: self.save(self.path.text().strip()))
        self.use_button.clicked.connect(self._use_clicked)
        self.browse.clicked.connect(self._browse)
        self.path.textChanged.connect(lambda t: settings.set("calibrate/path", t))

    def set_outcome(self, outcome: CalibrationOutcome | None, note: str = "") -> None:
        """The run whose result may be saved (None: running, cancelled or failed; ``note`` says which)."""
        if outcome is not self.outcome:
            self.saved_path = None
        self.outcome = outcome
        ok = outcome is not None and outcome.success
        self.save_button.setEnabled(ok)
        self.use_button.setEnabled(ok)
        if ok:
            self.label.setText("ready to save (homography and sync)")
        elif outcome is not None:
            self.label.setText(coloured(f"not saved: the {outcome.report.get('failed')} step failed (a failed "
                                        "calibration is never written)", RED))
        else:
            self.label.setText(html.escape(note))

    def hold(self, note: str) -> None:
        """A new calibration runs: nothing can be saved or used until it ends; ``note`` says so."""
        self.save_button.setEnabled(False)
        self.use_button.setEnabled(False)
        self.label.setText(html.escape(note))

    def release(self, note: str) -> None:
        """The run ended without a new result: the outcome held before is offered again (saved or not, as it
        was); ``note`` says what happened."""
        ok = self.outcome is not None and self.outcome.success
        self.save_button.setEnabled(ok)
        self.use_button.setEnabled(ok)
        saved = f"; saved as {self.saved_path}" if ok and self.saved_path is not None else ""
        self.label.setText(html.escape(note + saved))

    def _browse(self) -> None:
        start = self.path.text() or str(Path(self.settings.last_folder()) / "rig-calibration.json")
        path, _ = QFileDialog.getSaveFileName(self, "Save calibration", start, "Calibration (*.json)",
                                              options=QFileDialog.Option.DontConfirmOverwrite)  # Save asks
        if path:
            self.settings.remember_folder(path)
            self.path.setText(path)

    def save(self, path) -> Path | None:
        """Write the calibration file; None (with the reason shown) when it cannot.

        An existing file is replaced only when the operator answers Replace to the question that names it
        (atomically: the old file stays until the new one is complete).
        """
        from flexvox_calibration.errors import CalibrationError
        from flexvox_calibration.files import save_calibration

        if self.outcome is None or not self.outcome.success:
            self.label.setText(coloured("nothing to save: run a successful calibration first", RED))
            return None
        if not str(path):
            self.label.setText(coloured("choose where to save (folder/name.json)", RED))
            return None
        target = Path(path).expanduser()
        if target.exists() and not replace_question(self, target, "calibration"):
            self.label.setText(coloured(f"not saved: {target} is kept (choose another path)", AMBER))
            return None
        try:
            written = save_calibration(target, self.outcome.homography, self.outcome.identity,
                                       sync=self.outcome.sync, overwrite=True)
        except CalibrationError as exc:
            self.label.setText(coloured(f"not saved: {in_gui_words(str(exc))}", RED))
            return None
        self.saved_path = Path(written)
        self.settings.remember_folder(written)
        self.label.setText(coloured(f"saved {written}", GREEN))
        self.saved.emit(written)
        return written

    def _use_clicked(self) -> None:
        if self.outcome is not None and self.outcome.success:
            self.use_for_capture.emit(self.outcome)
