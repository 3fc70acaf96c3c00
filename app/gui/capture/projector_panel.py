"""The Capture workspace's "Projector output" box: the packed patterns full-screen on a chosen screen.

For a projector driven through its video input (a DLPC350): the plan's patterns through the
calibration (:meth:`flexvox_app.capture.plan.CapturePlan.patterns`, what a recording loads), packed into
24-bit frames (:attr:`flexvox_calibration.shutter.ShutterPatterns.packed`) on the job runner, and shown
pixel-exact by :class:`~flexvox_app.gui.projector.window.ProjectorWindow`.
"""

from __future__ import annotations

import html

from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QFormLayout, QGroupBox, QLabel, QPushButton

from flexvox_app.gui.models.capture_model import CaptureModel
from flexvox_app.gui.models.live_source import projector_size
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.projector.window import ProjectorWindow, ScreenPicker, live_screen
from flexvox_app.gui.widgets.qt_jobs import JobRunner
from flexvox_app.gui.widgets.questions import ask
from flexvox_app.gui.widgets.rich_text import AMBER, RED, coloured


class ProjectorPanel(QGroupBox):
    """Show (or close) the projector's patterns full-screen.

    Parameters
    ----------
    service : RigService
    runner : JobRunner
        Packs the patterns off the GUI thread.
    model : CaptureModel
        The plan and the calibration shown.
    """

    def __init__(self, service: RigService, runner: JobRunner, model: CaptureModel, parent=None):
        super().__init__("Projector output (video input)", parent)
        self.service = service
        self.runner = runner
        self.model = model
        self.window: ProjectorWindow | None = None
        """The open window, or None."""
        self._job = None
        self.screen_box = ScreenPicker()
        self.button = QPushButton("Show patterns full-screen")
        self.button.setCheckable(True)
        self.label = QLabel("closed · the packed patterns (24 masks per RGB frame) go full-screen on "
                            "the chosen screen, pixel for pixel; Esc closes")
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(self)
        f.addRow("screen", self.screen_box)
        f.addRow(self.button)
        f.addRow(self.label)
        self.button.toggled.connect(self._on_toggled)

    def chosen_screen(self):
        """The QScreen picked in the combo box (None: no screens)."""
        return self.screen_box.chosen()

    def _on_toggled(self, on: bool) -> None:
        if on:
            self.open()
        else:
            self.close_window()

    def _set_button(self, on: bool) -> None:
        self.button.blockSignals(True)
        self.button.setChecked(on)
        self.button.setText("Close projector window" if on else "Show patterns full-screen")
        self.button.blockSignals(False)

    def open(self) -> bool:
        """Pack the current patterns (on the job runner) and show them full-screen on the chosen screen.

        False (with the reason shown) when the plan's code cannot be made or no screen exists.
        """
        if self._job is not None and self._job.running:
            return True
        screen = self.chosen_screen()
        if screen is None:
            self.label.setText(coloured("no screen to show the patterns on", RED))
            self._set_button(False)
            return False
        if len(QGuiApplication.screens()) == 1 and not ask(
                self, "Cover the only screen?",
                f"{screen.name() or 'This screen'} is the only screen: the patterns would cover all of it, this window "
                "too, until you press Esc. Connect the projector's video input as a second screen to keep this one.\n\n"
                "Show the patterns full-screen here?", accept="Show full-screen", reject="Cancel"):
            self.label.setText("not shown: it is the only screen")
            self._set_button(False)
            return False
        plan = self.model.plan
        try:
            plan.code  # noqa: B018 - refuse an impossible code before packing
            camera_size = tuple(int(v) for v in self.service.rig.camera.sensor_shape)
        except (ValueError, OSError) as exc:
            self.label.setText(coloured(f"cannot make the patterns: {in_gui_words(str(exc))}", RED))
            self._set_button(False)
            return False
        psize = projector_size(self.service.rig.projector)
        layout = self.service.rig.projector.pixel_layout
        calibration = self.model.capture_calibration
        self.label.setText(f"packing {plan.K} masks of {psize[1]}×{psize[0]} …")
        self._set_button(True)

        def job(token, progress):
            return plan.patterns(camera_size, psize, calibration, layout=layout).packed

        def failed(message: str) -> None:
            self.label.setText(coloured(f"cannot make the patterns: {in_gui_words(message)}", RED))
            self._set_button(False)

        name = screen.name()
        self._job = self.runner.submit("projector patterns", job,
                                       on_finished=lambda frames: self._show(frames, name, plan.K), on_failed=failed)
        return True

    def _show(self, frames, screen_name: str, K: int) -> None:
        if not self.button.isChecked():
            return  # closed while packing
        # The screen is looked up again: one unplugged (or re-created by the platform) while the patterns were packed
        # leaves a deleted QScreen behind.
        screen = live_screen(screen_name)
        if screen is None:
            self.label.setText(coloured(f"not shown: the screen {html.escape(screen_name or '?')} is gone", RED))
            self._set_button(False)
            return
        self.close_window(keep_text=True)
        window = ProjectorWindow(frames, screen=screen)
        window.closed.connect(self._on_closed)
        self.window = window
        window.open()
        n = frames.shape[0]
        cycle = (f"{n} frames cycled every {window.timer.interval()} ms (K = {K} > 24; not locked to vsync: "
                 "prefer K ≤ 24 for the video input)" if n > 1 else f"1 frame: K = {K} masks in its bit-planes")
        text = [f"showing on {html.escape(screen.name() or 'screen')}: {frames.shape[2]}×{frames.shape[1]} pixels, "
                f"{cycle}; Esc closes"]
        warning = window.size_warning()
        if warning:
            text.append(coloured(f"• {warning}", AMBER))
        self.label.setText("<br>".join(text))
        self._set_button(True)

    def close_window(self, keep_text: bool = False) -> None:
        """Close the projector output window if it is open."""
        window, self.window = self.window, None
        if window is not None:
            window.closed.disconnect(self._on_closed)
            window.close()
            window.deleteLater()
            if not keep_text:
                self.label.setText("closed")
        self._set_button(False)

    def patterns_changed(self) -> None:
        """The plan or the calibration changed: an open window shows stale patterns, so close it and say so."""
        if self.window is not None:
            self.close_window()
            self.label.setText(coloured("closed: the patterns changed; show them again", AMBER))

    def _on_closed(self) -> None:
        window, self.window = self.window, None
        if window is not None:
            window.deleteLater()
        self.label.setText("closed (Esc)")
        self._set_button(False)
