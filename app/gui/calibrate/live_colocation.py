"""The Calibrate workspace's "Co-location live": alignment numbers re-measured while the operator adjusts.

Each measurement (:func:`flexvox_app.gui.models.calibration_model.measure_live_colocation`: the numbers
and the camera's view under a white projector) is a job; the next one starts
:data:`LIVE_INTERVAL_MS` after the previous ended, so there are never two at once. The view shows
the camera with the projector's expected grid through the homography estimate.
"""

from __future__ import annotations

import html

from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QCheckBox, QGroupBox, QVBoxLayout, QWidget

from flexvox_app.gui.calibrate.projector_screen import ProjectorScreen
from flexvox_app.gui.calibrate.results_view import ResultsView
from flexvox_app.gui.models.calibration_model import measure_live_colocation, target_for
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.qt_jobs import JobHandle, JobRunner
from flexvox_app.gui.widgets.rich_text import RED, coloured
from flexvox_app.gui.widgets.status_line import StatusLine

LIVE_USER = "co-location live"
LIVE_INTERVAL_MS = 300
"""Pause between two live co-location measurements."""


class LiveColocation(QObject):
    """The live numbers' box (:attr:`box`) and the measuring loop.

    Parameters
    ----------
    service : RigService
    runner : JobRunner
    screen : ProjectorScreen
        Shows the patterns on a video-input projector while measuring.
    view : ResultsView
        Its "Co-location live" tab shows the camera and the grid.
    held_elsewhere : callable
        ``() -> str | None``: why something other than the live numbers holds the rig now (a calibration, a
        recording), None when nothing does.
    """

    def __init__(self, service: RigService, runner: JobRunner, screen: ProjectorScreen, view: ResultsView, *,
                 held_elsewhere, parent: QWidget):
        super().__init__(parent)
        self.service = service
        self.runner = runner
        self.screen = screen
        self.view = view
        self._held_elsewhere = held_elsewhere
        self.job: JobHandle | None = None
        self.alignment = None
        """The newest co-location result."""
        self.colocation = None
        """The newest :class:`~flexvox_app.gui.models.calibration_model.LiveColocation` (numbers, image, projector
        size)."""
        self._target = None
        box = QGroupBox("Co-location live", parent)
        self.check = QCheckBox("measure continuously")
        self.check.setToolTip("re-measure the offset, rotation and scale while you adjust the beam splitter")
        self.label = StatusLine("off", lines=3)
        v = QVBoxLayout(box)
        v.addWidget(self.check)
        v.addWidget(self.label)
        self.box = box
        self.refused = False
        """True while a refusal to measure is shown."""
        self.timer = QTimer(self)
        self.timer.setSingleShot(True)
        self.timer.setInterval(LIVE_INTERVAL_MS)
        self.timer.timeout.connect(self._measure)
        self.check.toggled.connect(self.set_live)

    def recheck(self) -> None:
        """The rig was freed: take a refusal to measure off the screen."""
        if self.refused and not self.live:
            self.refused = False
            self.label.setText("off" if self.alignment is None else
                               f"stopped · last: {html.escape(self.alignment.message)}")

    @property
    def live(self) -> bool:
        """True while the live numbers are on."""
        return self.check.isChecked()

    @property
    def measuring(self) -> bool:
        """True while a measurement job runs."""
        return self.job is not None and self.job.running

    def set_live(self, on: bool, *, blocked: str | None = None) -> None:
        """Start or stop the live numbers (``blocked``: a reason they may not start now)."""
        if on:
            held = blocked or self._held_elsewhere() or self.screen.attach("live")
            if held:
                self.label.setText(coloured(f"cannot measure: {held}", RED))
                self.refused = True
                on = False
            else:
                self.refused = False
        self.check.blockSignals(True)
        self.check.setChecked(on)
        self.check.blockSignals(False)
        if on:
            self.service.begin_use(LIVE_USER)
            self.label.setText("measuring …")
            self.view.setCurrentWidget(self.view.colocation_view)
            self.view.colocation_view.set_title("co-location live: measuring …")
            self._measure()
        else:
            self.timer.stop()
            if self.measuring:
                self.job.cancel()
            else:
                self._release()
            if not self.label.text().startswith("<span"):
                self.label.setText("off" if self.alignment is None else
                                   f"stopped · last: {html.escape(self.alignment.message)}")

    def _measure(self) -> None:
        if not self.live or self.measuring:
            return
        if self._target is None:
            self._target = target_for(self.service)
        target = self._target
        self.job = self.runner.submit(
            "co-location", lambda token, progress: measure_live_colocation(target, token),
            on_finished=self._on_colocation, on_failed=self._on_failed, on_done=self._on_done)

    def _on_colocation(self, live) -> None:
        self.colocation = live
        result = live.alignment
        view = self.view.colocation_view
        view.show_alignment(live.image, result.homography if result.success else None, live.projector_size)
        if result.success:
            view.set_title("co-location live: the camera with the projector's expected grid (dashed), border "
                           "(yellow) and centre (red) through the current homography estimate; white ○: the "
                           "camera's centre")
        else:
            view.set_title(f"co-location live: no homography estimate ({result.status})")
        self.alignment = result
        if result.success:
            dx, dy = result.offset_px
            # The message repeats the numbers before its "; ": show the numbers once, then only its advice.
            advice = result.message.split("; ", 1)[1] if "; " in result.message else ""
            text = (f"<b>offset</b> ({dx:+.2f}, {dy:+.2f}) px · <b>rotation</b> {result.rotation_deg:+.3f}° · "
                    f"<b>scale</b> {result.scale:.4f} camera px per projector px · <b>lit</b> "
                    f"{result.lit_fraction:.1%}{' · <b>mirrored</b>' if result.mirrored else ''}"
                    + (f"<br>{html.escape(advice)}" if advice else ""))
        else:
            text = coloured(result.message, RED)
        self.label.setText(text)

    def _on_failed(self, message: str) -> None:
        self.label.setText(coloured(f"live co-location stopped: {in_gui_words(message)}", RED))
        self.set_live(False)

    def _on_done(self) -> None:
        if self.live:
            self.timer.start()
        else:
            self._release()

    def _release(self) -> None:
        """The live numbers are off and no measurement runs: the screen and the devices are free."""
        self.screen.release("live")
        self.service.end_use(LIVE_USER)
