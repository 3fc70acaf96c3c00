"""The Capture workspace's "Calibration" box: which calibration recordings use, and its phase and delay.

A calibration reaches Capture the ways it reaches ``flexvox capture``, through
:mod:`calibration.capture_setup` (the one loader): a calibration file, a sync profile (the
synchronisation wizard's; its phase and trigger delay replace the calibration's), or the
Calibrate workspace's fresh run ("Use for capture"). A file or run made for another rig, camera
or resolution is refused, in words, and the previous calibration is kept.

The box says what recordings use: the homography's origin, the phase of the shutter patterns
and the camera trigger delay that goes with it, and whether the camera applies the delay itself
(a camera with a trigger-delay feature) or the operator must set it and tick "trigger delay set
on the camera".
"""

from __future__ import annotations

import html

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QCheckBox, QFileDialog, QGridLayout, QGroupBox, QLabel, QPushButton, QVBoxLayout

from app.capture.plan import CapturePlan
from app.capture.rig_setup import trigger_delay_by
from app.gui.models.capture_calibration import capture_identity
from app.gui.models.rig_service import RigService
from app.gui.widgets.rich_text import AMBER, RED, coloured
from app.gui.widgets.settings import AppSettings
from calibration.capture_setup import (
    CalibrationRefused,
    CaptureCalibration,
    from_run,
    load_for_capture,
    load_sync_for_capture,
)


class CalibrationPanel(QGroupBox):
    """Load a calibration or a sync profile, or go uncalibrated; show the phase and delay in use.

    Parameters
    ----------
    service : RigService
        The capture rig (a calibration must match its identity).
    settings : AppSettings
    """

    changed = Signal(object)
    """The :class:`~calibration.capture_setup.CaptureCalibration` now used (None: uncalibrated)."""

    def __init__(self, service: RigService, settings: AppSettings, parent=None):
        super().__init__("Calibration", parent)
        self.service = service
        self.settings = settings
        self.calibration: CaptureCalibration | None = None
        """The calibration recordings use (None: uncalibrated, the identity map and phase 0)."""
        self.error = ""
        """Why the last calibration offered was refused ("" when it was taken)."""
        self._plan: CapturePlan | None = None
        self.label = QLabel()
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_label = QLabel()
        """One line for the workspace's actions: calibrated or not, the phase and delay, or the next step."""
        self.status_label.setWordWrap(True)
        self.status_label.setTextFormat(Qt.TextFormat.RichText)
        self.load_button = QPushButton("Load calibration…")
        self.sync_button = QPushButton("Load sync profile…")
        self.sync_button.setToolTip("the synchronisation wizard's profile: its phase and camera trigger delay")
        self.clear_button = QPushButton("Record uncalibrated")
        self.clear_button.setToolTip("forget the calibration: record with the identity homography, phase 0 and no "
                                     "trigger delay")
        self.delay_check = QCheckBox("trigger delay set on the camera (it cannot be told one)")
        self.delay_check.setToolTip("this camera has no trigger-delay feature: set the delay shown above in its "
                                    "vendor's tool, then tick this")
        row = QGridLayout()  # two a line: the controls column is narrow
        for i, b in enumerate((self.load_button, self.sync_button, self.clear_button)):
            row.addWidget(b, i // 2, i % 2)
        v = QVBoxLayout(self)
        v.addWidget(self.label)
        v.addLayout(row)
        v.addWidget(self.delay_check)
        self.load_button.clicked.connect(self._ask_calibration)
        self.sync_button.clicked.connect(self._ask_sync_profile)
        self.clear_button.clicked.connect(self.clear)
        self.delay_check.toggled.connect(lambda _: self._show())
        self._show()

    # ------------------------------------------------------------------ choosing
    def _identity(self):
        from rig_drivers.errors import DeviceError

        try:
            return capture_identity(self.service)
        except (DeviceError, OSError) as exc:
            raise CalibrationRefused(f"cannot read this rig's camera and projector sizes: {exc}") from exc

    def _ask(self, title: str, key: str) -> str:
        start = self.settings.last_folder(key)
        path, _ = QFileDialog.getOpenFileName(self, title, start, "flexvox calibration (*.json)")
        if path:
            self.settings.remember_folder(path, key)
        return path

    def _ask_calibration(self) -> None:
        path = self._ask("Load calibration", "capture/calibration_dir")
        if path:
            self.load_calibration(path)

    def _ask_sync_profile(self) -> None:
        path = self._ask("Load sync profile", "capture/calibration_dir")
        if path:
            self.load_sync_profile(path)

    def _take(self, make) -> bool:
        try:
            calibration = make()
        except CalibrationRefused as exc:
            self.error = str(exc)
            self._show()
            return False
        self.calibration, self.error = calibration, ""
        self._show()
        self.changed.emit(calibration)
        return True

    def load_calibration(self, path) -> bool:
        """Use a calibration file; False (reason shown, previous one kept) when refused."""
        return self._take(lambda: load_for_capture(path, self._identity()))

    def load_sync_profile(self, path) -> bool:
        """Use a sync profile's phase and trigger delay with the current homography; False when refused."""
        return self._take(lambda: load_sync_for_capture(path, self._identity(), base=self.calibration))

    def use_run(self, run, run_identity) -> bool:
        """Use a fresh calibration run (the Calibrate workspace's); False (with the reason) when refused."""
        return self._take(lambda: from_run(run, run_identity, self._identity()))

    def clear(self) -> None:
        """Record uncalibrated."""
        self.calibration, self.error = None, ""
        self._show()
        self.changed.emit(None)

    def refuse(self, message: str) -> None:
        """Show why a calibration could not be taken now (e.g. a recording runs)."""
        self.error = message
        self._show()

    def set_locked(self, locked: bool) -> None:
        """Grey the buttons out while a recording runs."""
        for w in (self.load_button, self.sync_button, self.clear_button, self.delay_check):
            w.setEnabled(not locked)

    # ------------------------------------------------------------------ what recordings use
    def capture_calibration(self) -> CaptureCalibration:
        """What recordings use (uncalibrated when none was chosen)."""
        return self.calibration or CaptureCalibration()

    @property
    def delay_set_by_hand(self) -> bool:
        """The operator confirmed the trigger delay is set on a camera that cannot be told it."""
        return self.delay_check.isChecked()

    def show_plan(self, plan: CapturePlan) -> None:
        """Say what a recording of ``plan`` uses (phase and delay at its timing)."""
        self._plan = plan
        self._show()

    def _show(self) -> None:
        cal = self.capture_calibration()
        lines = []
        short = (coloured("uncalibrated: run Calibrate and “Use for capture”, or load a calibration below", AMBER)
                 if self.calibration is None else "<b>calibrated</b>")
        if self.calibration is None:
            lines.append("<b>uncalibrated</b>: identity homography, phase 0, no trigger delay — a real rig (and the "
                         "simulated one) needs its calibration: run it in Calibrate and “Use for capture”, or load "
                         "the file")
        else:
            lines.append(f"<b>active</b>: {html.escape(cal.describe())}")
        needs_hand = False
        if self._plan is not None:
            phase, delay, warnings = cal.for_plan(self._plan.K, self._plan.period_us)
            by = trigger_delay_by(self.service.rig.camera.capabilities, delay, self.delay_set_by_hand)
            needs_hand = by in ("operator", None)
            if by == "none":
                lines.append(f"recordings use phase <b>{phase}</b>, no camera trigger delay")
            else:
                how = {"camera": "set by the camera", "operator": "set by you on the camera ✓"}.get(
                    by, "this camera cannot be told it: set it in the camera's own tool and tick the box below")
                lines.append(f"recordings use phase <b>{phase}</b> and a <b>{delay:.0f} µs</b> camera trigger delay "
                             f"({html.escape(how)})")
            lines += [coloured(f"• {w}", AMBER) for w in warnings if self.calibration is not None]
            if self.calibration is not None:
                short += f": phase {phase}" + (f", {delay:.0f} µs trigger delay" if by != "none" else "")
                if needs_hand and not self.delay_set_by_hand:
                    short += coloured(" — set the delay on the camera (Calibration below)", AMBER)
        self.delay_check.setVisible(needs_hand)
        if self.error:
            lines.append(coloured(f"refused: {self.error}", RED))
        self.label.setText("<br>".join(lines))
        if self.error:
            short += "<br>" + coloured(f"refused: {self.error}", RED)
        self.status_label.setText(short)
