"""The main window: the device panel and the Calibrate, Capture and Review workspaces as tabs."""

from __future__ import annotations

import logging

from PySide6.QtCore import QMargins, QRect, Qt, QTimer
from PySide6.QtGui import QAction, QGuiApplication, QKeySequence
from PySide6.QtWidgets import QMainWindow, QTabWidget

from flexvox_app.gui.calibrate.workspace import CalibrateWorkspace
from flexvox_app.gui.capture.workspace import CaptureWorkspace
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.review.workspace import ReviewWorkspace
from flexvox_app.gui.widgets.device_dock import DeviceDock
from flexvox_app.gui.widgets.device_panel import DevicePanel
from flexvox_app.gui.widgets.qapp import DEFAULT_SIZE
from flexvox_app.gui.widgets.qt_jobs import JobRunner
from flexvox_app.gui.widgets.questions import ask
from flexvox_app.gui.widgets.rich_text import RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.wheel_guard import guard_value_widgets, install_wheel_guard

_logger = logging.getLogger(__name__)

WORKSPACES = ("Calibrate", "Capture", "Review")


class MainWindow(QMainWindow):
    """flexvox's main window.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner
    quality_table : dict or None
    capture_factory : callable, optional
        Builds capture services for the Capture workspace (tests inject failing writers).

    The Calibrate and Capture workspaces share the rig: each is given ``held_elsewhere``, which asks the other
    before it uses the devices (who holds them: :mod:`flexvox_app.gui.models.holder`), so a calibration never
    starts during a recording and the reverse.
    """

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner, quality_table: dict | None,
                 *, capture_factory=None):
        super().__init__()
        self.service = service
        self.settings = settings
        self.runner = runner
        self._closed = False
        rig = "simulated rig" if service.simulated else service.name
        self.setWindowTitle(f"flexvox — {rig}")
        self.calibrate = CalibrateWorkspace(service, settings, runner, held_elsewhere=self._held_by_capture)
        self.capture = CaptureWorkspace(service, settings, runner, capture_factory=capture_factory,
                                        held_elsewhere=self._held_by_calibrate)
        self.review = ReviewWorkspace(settings, runner, quality_table)
        self.tabs = QTabWidget()
        for name, w in zip(WORKSPACES, (self.calibrate, self.capture, self.review), strict=True):
            self.tabs.addTab(w, name)
        self.setCentralWidget(self.tabs)
        self.devices = DevicePanel(service)
        self.device_dock = DeviceDock(self.devices, service, settings, self)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, self.device_dock)
        self.review.status.connect(lambda text: self.statusBar().showMessage(text, 8000))
        self.capture.open_requested.connect(self._review_recording)
        self.capture.recording_finished.connect(lambda _: self.calibrate.recheck_refusals())
        self.calibrate.status.connect(lambda text: self.statusBar().showMessage(text, 8000))
        self.calibrate.use_for_capture.connect(self._use_for_capture)
        self.calibrate.sync_profile_saved.connect(self.capture.calibration_panel.offer_sync_profile)
        self.capture.calibration_panel.file_replaced.connect(lambda text: self.statusBar().showMessage(text, 15000))
        self._live_paused = False
        """Capture's live view was stopped for a calibration or the wizard (it starts again when they end)."""
        self.calibrate.pauses_elsewhere = lambda: ["Capture's live view"] if self.capture.live else []
        self.capture.live_panel.shown_running.connect(lambda _: self.calibrate.refresh_pause_note())
        self.calibrate.rig_released.connect(self._resume_live)
        self.calibrate.refresh_pause_note()
        self.calibrate.save_panel.saved.connect(
            lambda path: self.capture.outcome_saved(self.calibrate.save_panel.outcome, path))

        menu = self.menuBar().addMenu("&File")
        open_action = QAction("&Open recording…", self)
        open_action.setShortcut(QKeySequence.StandardKey.Open)
        open_action.triggered.connect(self._open)
        quit_action = QAction("&Quit", self)
        quit_action.setShortcut(QKeySequence.StandardKey.Quit)
        quit_action.triggered.connect(self.close)
        menu.addAction(open_action)
        menu.addAction(quit_action)
        view = self.menuBar().addMenu("&View")
        self.fold_action = QAction("&Fold the Devices panel", self)
        self.fold_action.setCheckable(True)
        self.fold_action.setChecked(self.device_dock.folded)
        self.fold_action.toggled.connect(self.device_dock.set_folded)
        self.device_dock.folded_changed.connect(self.fold_action.setChecked)
        view.addAction(self.fold_action)

        geometry = settings.get_bytes("window/geometry")
        if geometry is not None:
            self.restoreGeometry(geometry)
        else:
            self.resize(*DEFAULT_SIZE)
        self.fit_to_screen()
        # The first start opens where the operator's path starts (Calibrate), never on an empty Review.
        self.tabs.setCurrentIndex(min(max(settings.get_int("window/tab", 0), 0), len(WORKSPACES) - 1))
        self.statusBar().showMessage("simulated rig: every device is a simulation" if service.simulated
                                     else f"rig profile: {service.name}")
        # The wheel scrolls the columns; it changes a value only in the widget the operator clicked into.
        install_wheel_guard()
        guard_value_widgets(self)

    def fit_to_screen(self, available: QRect | None = None, frame: QMargins | None = None) -> None:
        """Keep the whole window, its title bar and its status bar, inside ``available`` (default: its screen's
        available geometry, without the desktop's panels): shrink it and move it in where it does not fit.

        ``frame``: the window manager's decoration around the window (default: as it is now; nothing before
        the window is shown, so it is fitted again once it is). Qt's offscreen platform has no screen to fit:
        there only an explicit ``available`` is fitted.
        """
        if available is None:
            screen = self.screen()
            if screen is None or QGuiApplication.platformName() == "offscreen":  # no screen there: nothing to fit
                return
            available = screen.availableGeometry()
        if frame is None:
            outer, inner = self.frameGeometry(), self.geometry()
            frame = QMargins(inner.left() - outer.left(), inner.top() - outer.top(), outer.right() - inner.right(),
                             outer.bottom() - inner.bottom())
        width = min(self.width(), available.width() - frame.left() - frame.right())
        height = min(self.height(), available.height() - frame.top() - frame.bottom())
        if (width, height) != (self.width(), self.height()):
            _logger.info("window %dx%d does not fit the screen's %dx%d: %dx%d", self.width(), self.height(),
                         available.width(), available.height(), width, height)
            self.resize(width, height)
        outer_w, outer_h = width + frame.left() + frame.right(), height + frame.top() + frame.bottom()
        x = min(max(self.frameGeometry().x(), available.left()), available.left() + available.width() - outer_w)
        y = min(max(self.frameGeometry().y(), available.top()), available.top() + available.height() - outer_h)
        if (x, y) != (self.frameGeometry().x(), self.frameGeometry().y()):
            self.move(x, y)  # move() places the frame

    def showEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Fit the screen again once the window manager has framed the window."""
        super().showEvent(event)
        QTimer.singleShot(0, self.fit_to_screen)

    def _held_by_capture(self) -> str | None:
        """Why the Capture workspace holds the rig, keeping the Calibrate workspace off it: a recording (a live view
        is stopped for it)."""
        if self.capture.recording:
            return "a recording is running in the Capture workspace"
        if self.capture.live:
            self.capture.stop_live()
            self._live_paused = True
        return None

    def _resume_live(self) -> None:
        """A calibration or the wizard ended: start Capture's live view again when it stopped it."""
        if not self._live_paused or self._closed:
            return
        self._live_paused = False
        if self.calibrate.live_panel.live or self.capture.recording:
            return  # the rig is taken again: the operator starts it when it is free
        if self.capture.start_live():
            self.statusBar().showMessage("Capture's live view runs again", 8000)

    def _held_by_calibrate(self) -> str | None:
        """Why the Calibrate workspace holds the rig, keeping the Capture workspace off it: a calibration, its
        live numbers or the wizard using the devices."""
        return self.calibrate.held_here()

    def _use_for_capture(self, outcome) -> None:
        """Hand the Calibrate workspace's result to Capture (as its file when it was saved); say in the status bar
        whether it was taken."""
        used = self.capture.use_outcome(outcome, self.calibrate.save_panel.saved_path)
        self.statusBar().showMessage("Capture now records with this calibration" if used else
                                     "Capture refused the calibration: see its Calibration box", 8000)
        if used:
            self.show_workspace("Capture")
        else:
            self.calibrate.save_panel.label.setText(coloured(f"not used for capture: {self.capture.calibration_error}",
                                                             RED))

    def _review_recording(self, path) -> None:
        self.show_workspace("Review")
        self.review.open_recording(path)

    def _open(self) -> None:
        self.tabs.setCurrentWidget(self.review)
        self.review._ask_open()

    def show_workspace(self, name: str) -> None:
        """Bring the named workspace forward."""
        self.tabs.setCurrentIndex(WORKSPACES.index(name))

    def closing_losses(self) -> list[str]:
        """What closing the window now would stop or lose, in words (empty: nothing)."""
        return self.capture.closing_losses() + self.calibrate.closing_losses() + self.review.closing_losses()

    @staticmethod
    def closing_question(losses: list[str]) -> str:
        """The close question's text for ``losses`` (it follows them while it is open: the frames go on)."""
        return "Closing the window now:\n\n" + "\n".join(f"• {line}" for line in losses) + "\n\nQuit anyway?"

    def closeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Ask first when closing would stop a recording or a calibration or lose results; then stop live view and
        jobs, close devices, save the window."""
        if self._closed:
            event.accept()
            return
        losses = self.closing_losses()
        if losses and not ask(self, "Quit flexvox?", self.closing_question(losses), accept="Quit",
                              reject="Keep working", update=lambda: self.closing_question(self.closing_losses())):
            event.ignore()
            return
        self._closed = True
        self.settings.set("window/geometry", self.saveGeometry())
        self.settings.set("window/tab", self.tabs.currentIndex())
        self.settings.sync()
        self.capture.shutdown()
        self.calibrate.shutdown()
        self.review.shutdown()  # before the runner: nothing may schedule a preview after it shut down
        if not self.runner.shutdown(5000):
            _logger.error("background jobs did not stop within 5 s")
        self.service.close()
        super().closeEvent(event)
