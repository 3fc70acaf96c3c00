"""The Calibrate workspace: the whole calibration off the GUI thread, its results, save; live co-location numbers.

Run calibration runs :func:`app.gui.models.calibration_model.run_workspace_calibration` (the pipeline
``flexvox calibrate`` runs) on the job runner, with the step and its pattern count on screen
and Cancel taking effect between steps and patterns. The results: co-location numbers and the
parallax verdict; homography RMS, coverage, inliers and the residual heat map; shutter slot
accuracy and the map of wrong pixels; sync phase and delay with the leakage curve and the delay
sweep; drop and drift verdicts; on the simulated rig, the hidden truth beside what was found.
Save writes the calibration file (:func:`calibration.files.save_calibration`).

"Co-location live" re-measures the alignment numbers (:func:`calibration.colocation.measure_alignment`)
over and over while the operator adjusts the beam splitter; each measurement is a job, the
next one starts when the previous ended (never two at once, never during a calibration).

The synchronisation wizard lives in :mod:`app.gui.calibrate.sync_wizard`.

On a real rig whose projector takes its patterns on a video input (the DLPC350), the workspace
chooses the projector's screen ("projector screen") and injects a
:class:`~app.gui.projector.display.ProjectorDisplay` on it as the projector's display sink while a
calibration, the live numbers or the wizard use the rig: every pattern the session loads is shown
full-screen, pixel-exact, and on screen before the sequence starts. The window closes and the sink
is removed when they end.
"""

from __future__ import annotations

import html
import logging
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QScrollArea,
    QSplitter,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.gui.calibrate.colocation_view import ColocationView
from app.gui.models.calibration_model import (
    STEPS,
    CalibrationOutcome,
    StepTracker,
    measure_live_colocation,
    run_workspace_calibration,
    summary_rows,
    target_for,
    verdict,
)
from app.gui.models.jobs import CancelToken
from app.gui.models.rig_service import RigService
from app.gui.projector.display import ProjectorDisplay
from app.gui.projector.window import ScreenPicker
from app.gui.widgets.image_panel import ImagePanel
from app.gui.widgets.qt_jobs import JobHandle, JobRunner
from app.gui.widgets.rich_text import GREEN, GREY, RED
from app.gui.widgets.settings import AppSettings

_logger = logging.getLogger(__name__)

TILES = ((4, 4), (2, 4), (4, 2), (2, 2), (3, 5))
LIVE_INTERVAL_MS = 300
"""Pause between two live co-location measurements."""
UNDECODED_RGBA = (60, 60, 90, 255)
WRONG_RGB = (230, 40, 40)
RIGHT_RGB = (70, 110, 70)


def _colour(good: bool | None) -> str:
    return GREY if good is None else (GREEN if good else RED)


def results_html(outcome: CalibrationOutcome) -> str:
    """The results page (rich text): one table per step with its verdict and message."""
    parts = []
    said = ("succeeded: save it" if outcome.success
            else f"stopped: the {outcome.report.get('failed', 'last')} step failed")
    verdict_word = (f"<b style='color:{GREEN if outcome.success else RED}'>calibration {html.escape(said)}</b> "
                    f"in {outcome.seconds:.1f} s")
    parts.append(f"<p>{verdict_word}</p>")
    for title, figures, status, message in summary_rows(outcome):
        word, good = verdict(status)
        rows = "".join(f"<tr><td>{html.escape(k)}</td><td><b>{html.escape(v)}</b></td></tr>" for k, v in figures)
        parts.append(f"<h3>{html.escape(title)} <span style='color:{_colour(good)}'>{html.escape(word)}</span></h3>"
                     f"<table cellspacing='4'>{rows}</table><p>{html.escape(message)}</p>")
    for note in outcome.notes:
        parts.append(f"<p style='color:{GREY}'>Note: {html.escape(note)}.</p>")
    return "".join(parts)


class CalibrateWorkspace(QWidget):
    """Run the whole calibration, show and save its results; live co-location numbers.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner
    rig_guard : callable, optional
        ``() -> str | None``: a reason the rig is busy elsewhere (a recording), asked before a
        calibration or a live measurement starts on a real rig.
    """

    status = Signal(str)
    """A line for the status bar."""
    calibrated = Signal(object)
    """A :class:`CalibrationOutcome` (successful or not) after each run."""
    use_for_capture = Signal(object, object)
    """(outcome, saved path or None): the operator hands the successful result to the Capture workspace."""

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner, *, rig_guard=None,
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.runner = runner
        self.rig_guard = rig_guard
        self.outcome: CalibrationOutcome | None = None
        self.job: JobHandle | None = None
        self.live_job: JobHandle | None = None
        self.alignment = None
        """The newest live co-location result."""
        self.colocation = None
        """The newest :class:`~app.gui.models.calibration_model.LiveColocation` (numbers, image, projector size)."""
        self.saved_path: Path | None = None
        """Where the current outcome was saved (None: not saved)."""
        self.tracker: StepTracker | None = None
        self._live_target = None
        self.projector_display: ProjectorDisplay | None = None
        """The display sink injected into a video-input projector while the rig is in use (None otherwise)."""
        self._display_users: set[str] = set()
        self._build()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        run = QGroupBox("Calibration")
        seed = self.service.rig.simulated.truth.seed if self.service.simulated else None
        self.rig_label = QLabel(
            f"simulated rig (seed {seed}, the rig Capture records with): calibration puts its calibration target "
            "in view (a still textured wall) and finds the hidden homography, phase and delay; the result is "
            "compared with the truth" if self.service.simulated
            else f"rig profile {html.escape(self.service.name)}: its own devices")
        self.rig_label.setWordWrap(True)
        self.tile_box = QComboBox()
        for m, n in TILES:
            self.tile_box.addItem(f"{m}×{n} (K = {m * n})", (m, n))
        self.tile_box.setCurrentIndex(max(0, self.tile_box.findText(self.settings.get_str("calibrate/tile", "4×4"),
                                                                    Qt.MatchFlag.MatchStartsWith)))
        self.run_button = QPushButton("Run calibration")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        buttons = QHBoxLayout()
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.step_label = QLabel("not run")
        self.step_label.setWordWrap(True)
        self.step_label.setTextFormat(Qt.TextFormat.RichText)
        self.steps_label = QLabel(self._steps_html(-1))
        self.steps_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(run)
        f.addRow(self.rig_label)
        f.addRow("shutter code", self.tile_box)
        self.screen_box = ScreenPicker(self.settings.get_str("calibrate/screen", ""))
        self.display_label = QLabel("")
        self.display_label.setWordWrap(True)
        self.display_label.setTextFormat(Qt.TextFormat.RichText)
        if self.needs_display:
            self.screen_box.setToolTip("the screen that feeds the projector's video input (HDMI): the calibration "
                                       "patterns go there full-screen, pixel for pixel")
            f.addRow("projector screen", self.screen_box)
            f.addRow(self.display_label)
        f.addRow(buttons)
        f.addRow(self.progress)
        f.addRow(self.step_label)
        f.addRow(self.steps_label)

        save = QGroupBox("Save")
        self.save_path = QLineEdit(self.settings.get_str("calibrate/path", ""))
        self.save_path.setPlaceholderText("folder/rig-calibration.json")
        self.save_browse = QPushButton("Browse…")
        row = QHBoxLayout()
        row.addWidget(self.save_path, 1)
        row.addWidget(self.save_browse)
        self.save_button = QPushButton("Save calibration")
        self.save_button.setEnabled(False)
        self.save_label = QLabel("run a calibration first")
        self.save_label.setWordWrap(True)
        self.save_label.setTextFormat(Qt.TextFormat.RichText)
        self.use_button = QPushButton("Use for capture")
        self.use_button.setToolTip("hand this homography and sync phase to the Capture workspace")
        self.use_button.setEnabled(False)
        save_buttons = QHBoxLayout()
        save_buttons.addWidget(self.save_button)
        save_buttons.addWidget(self.use_button)
        v = QVBoxLayout(save)
        v.addLayout(row)
        v.addLayout(save_buttons)
        v.addWidget(self.save_label)

        live = QGroupBox("Co-location live")
        self.live_check = QCheckBox("measure continuously (while you adjust the beam splitter)")
        self.live_label = QLabel("off")
        self.live_label.setWordWrap(True)
        self.live_label.setTextFormat(Qt.TextFormat.RichText)
        v = QVBoxLayout(live)
        v.addWidget(self.live_check)
        v.addWidget(self.live_label)

        self.wizard_button = QPushButton("Synchronisation wizard…")
        left = QWidget()
        lv = QVBoxLayout(left)
        for w in (run, save, live):
            lv.addWidget(w)
        lv.addWidget(self.wizard_button)
        lv.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(left)
        scroll.setWidgetResizable(True)
        scroll.setMinimumWidth(380)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)

        self.results = QLabel("<p>Run the calibration: co-location check, homography, shutter masks, "
                              "synchronisation, drops and drift. The figures appear here.</p>")
        self.results.setWordWrap(True)
        self.results.setTextFormat(Qt.TextFormat.RichText)
        self.results.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        self.results.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.results.setContentsMargins(12, 8, 12, 8)
        results_scroll = QScrollArea()
        results_scroll.setWidget(self.results)
        results_scroll.setWidgetResizable(True)

        self.residuals = ImagePanel("homography residuals: not measured yet", colormap="inferno")
        self.wrong_panel = ImagePanel("shutter: not verified yet")
        self.leakage_plot = pg.PlotWidget(title="leakage: light of each slot that reached the exposure (delay 0)")
        self.leakage_plot.setBackground("#202020")
        self.leakage_plot.setLabel("bottom", "projected slot")
        self.leakage_plot.setLabel("left", "fraction of the slot's light")
        self.leakage_bars = pg.BarGraphItem(x=[], height=[], width=0.8, brush=(90, 160, 255, 200))
        self.leakage_plot.addItem(self.leakage_bars)
        self.sweep_plot = pg.PlotWidget(title="delay sweep: slots of light lost against the camera delay")
        self.sweep_plot.setBackground("#202020")
        self.sweep_plot.setLabel("bottom", "camera trigger delay (µs)")
        self.sweep_plot.setLabel("left", "slots lost")
        self.sweep_points = self.sweep_plot.plot([], [], pen=None, symbol="o", symbolBrush=(255, 200, 80))
        self.sweep_fit = self.sweep_plot.plot([], [], pen=pg.mkPen((120, 200, 255), width=1))
        sync_page = QWidget()
        sv = QVBoxLayout(sync_page)
        sv.addWidget(self.leakage_plot)
        sv.addWidget(self.sweep_plot)
        self.tabs = QTabWidget()
        self.tabs.addTab(results_scroll, "Results")
        self.tabs.addTab(self.residuals, "Homography residuals")
        self.tabs.addTab(self.wrong_panel, "Shutter: wrong pixels")
        self.tabs.addTab(sync_page, "Sync leakage")
        self.colocation_view = ColocationView()
        self.tabs.addTab(self.colocation_view, "Co-location live")

        split = QSplitter()
        split.addWidget(scroll)
        split.addWidget(self.tabs)
        split.setStretchFactor(1, 1)
        split.setSizes([420, 880])
        QHBoxLayout(self).addWidget(split)

        self.live_timer = QTimer(self)
        self.live_timer.setSingleShot(True)
        self.live_timer.setInterval(LIVE_INTERVAL_MS)
        self.live_timer.timeout.connect(self._measure_live)

        self.run_button.clicked.connect(self.run_calibration)
        self.cancel_button.clicked.connect(self.cancel)
        self.save_button.clicked.connect(self._save_clicked)
        self.use_button.clicked.connect(self._use_clicked)
        self.save_browse.clicked.connect(self._browse)
        self.live_check.toggled.connect(self.set_live)
        self.wizard_button.clicked.connect(self.open_sync_wizard)
        self.tile_box.currentIndexChanged.connect(
            lambda _: self.settings.set("calibrate/tile", self.tile_box.currentText().split(" ")[0]))
        self.save_path.textChanged.connect(lambda t: self.settings.set("calibrate/path", t))

    @staticmethod
    def _steps_html(current: int, failed: str | None = None, finished: bool = False) -> str:
        lines = []
        for i, name in enumerate(STEPS):
            if finished or i < current:
                mark, colour = "✓", GREEN
            elif i == current:
                mark, colour = "▶", "#2e86c1"
            else:
                mark, colour = "·", GREY
            lines.append(f"<span style='color:{colour}'>{mark} {html.escape(name)}</span>")
        return "<br>".join(lines)

    # ------------------------------------------------------------------ state
    @property
    def running(self) -> bool:
        """True while a calibration job runs."""
        return self.job is not None and self.job.running

    def rig_busy_reason(self) -> str | None:
        """Why the Capture workspace may not use the rig now (a calibration or a live measurement runs on it)."""
        if self.running:
            return "a calibration is running in the Calibrate workspace"
        if self.live_job is not None and self.live_job.running:
            return "the co-location live numbers are measuring in the Calibrate workspace"
        return None

    def _guard(self) -> str | None:
        # The simulated rig is the rig Capture uses too: the same rule holds for it.
        if self.rig_guard is None:
            return None
        return self.rig_guard()

    # ------------------------------------------------------------------ the projector's screen
    @property
    def needs_display(self) -> bool:
        """True on a real rig whose projector takes its patterns on a video input (it has a display sink)."""
        return not self.service.simulated and hasattr(self.service.rig.projector, "display")

    def _claim_rig(self, user: str) -> str | None:
        """Take the rig for ``user``: refuse while Capture uses it, stop the live numbers, attach the
        projector display on a real rig. Returns the reason it cannot, or None."""
        busy = self._guard()
        if busy:
            return busy
        self.set_live(False)
        return self.attach_display(user)

    def chosen_screen(self):
        """The QScreen picked for the projector's video input (None: no screens)."""
        return self.screen_box.chosen()

    def attach_display(self, user: str) -> str | None:
        """Inject the display sink into the projector for ``user`` (a job); the reason when it cannot."""
        if not self.needs_display:
            return None
        screen = self.chosen_screen()
        if screen is None:
            return "no screen to show the patterns on: connect the projector's video input (HDMI) as a screen"
        if self.projector_display is None or self.projector_display.screen is not screen:
            self._close_display()
            self.projector_display = ProjectorDisplay(screen, parent=self)
            self.projector_display.shown.connect(self._on_display_shown)
        self.settings.set("calibrate/screen", self.screen_box.currentData() or "")
        self.service.rig.projector.display = self.projector_display
        self._display_users.add(user)
        self.display_label.setText(f"patterns go to {html.escape(screen.name() or 'the chosen screen')}")
        return None

    def release_display(self, user: str) -> None:
        """``user`` is done with the rig: when nobody else uses it, remove the sink and close its window."""
        self._display_users.discard(user)
        if not self._display_users:
            self._close_display()

    def _close_display(self) -> None:
        display, self.projector_display = self.projector_display, None
        if display is None:
            return
        projector = self.service.rig.projector
        if getattr(projector, "display", None) is display:
            projector.display = None
        display.close()
        display.deleteLater()
        self.display_label.setText("projector window closed")

    def _on_display_shown(self, n: int) -> None:
        d = self.projector_display
        if d is not None and d.window is not None:
            H, W = d.window.frame_size
            warning = d.window.size_warning()
            text = f"showing pattern {d.frames_shown} ({W}×{H}, {n} frame{'s' if n > 1 else ''})"
            self.display_label.setText(text + (f"<br><span style='color:{RED}'>{html.escape(warning)}</span>"
                                               if warning else ""))

    def tile(self) -> tuple[int, int]:
        """The shutter code's tile."""
        return tuple(self.tile_box.currentData())

    # ------------------------------------------------------------------ the run
    def run_calibration(self) -> bool:
        """Start a calibration; False (with the reason shown) when it cannot start now."""
        if self.running:
            return False
        refused = self._claim_rig("calibration")
        if refused:
            self.step_label.setText(f"<span style='color:{RED}'>cannot start: {html.escape(refused)}</span>")
            return False
        token = CancelToken()
        tracker = StepTracker(token)
        self.tracker = tracker
        tile, service = self.tile(), self.service

        def job(token_, progress):
            tracker.token = token_
            tracker.report = progress
            return run_workspace_calibration(target_for(service), tile=tile, cancel=token_, tracker=tracker)

        self.outcome = None
        self.saved_path = None
        self.save_button.setEnabled(False)
        self.use_button.setEnabled(False)
        self.save_label.setText("calibrating …")
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.live_check.setEnabled(False)
        self.wizard_button.setEnabled(False)
        self.step_label.setText("starting …")
        self.steps_label.setText(self._steps_html(0))
        self.progress.setRange(0, 0)
        self.job = self.runner.submit("calibration", job, on_progress=self._on_progress, on_finished=self._on_done,
                                      on_failed=self._on_failed, on_cancelled=self._on_cancelled,
                                      on_done=self._on_job_done)
        self.status.emit("calibrating …")
        return True

    def cancel(self) -> None:
        """Ask the running calibration to stop at its next step or pattern."""
        if self.running:
            self.job.cancel()
            self.step_label.setText("cancelling …")

    def _on_progress(self, done: int, total: int) -> None:
        t = self.tracker
        if t is None:
            return
        n = len(STEPS)
        step = f"step {t.index + 1} of {n}: {html.escape(t.step)}"
        if total > 0:
            self.progress.setRange(0, total)
            self.progress.setValue(done)
            self.step_label.setText(f"{step} — {done}/{total} patterns")
        else:
            self.progress.setRange(0, 0)
            self.step_label.setText(step)
        self.steps_label.setText(self._steps_html(t.index))

    def _on_done(self, outcome: CalibrationOutcome) -> None:
        self.show_outcome(outcome)
        word = "succeeded" if outcome.success else f"stopped at the {outcome.report.get('failed')} step"
        self.step_label.setText(f"<span style='color:{GREEN if outcome.success else RED}'>calibration {word} "
                                f"({outcome.seconds:.1f} s)</span>")
        self.steps_label.setText(self._steps_html(len(STEPS), finished=outcome.success))
        self.status.emit(f"calibration {word}")
        self.calibrated.emit(outcome)

    def _on_failed(self, message: str) -> None:
        self.step_label.setText(f"<span style='color:{RED}'>calibration failed: {html.escape(message)}</span>")
        self.save_label.setText("nothing to save")
        self.status.emit(f"calibration failed: {message}")

    def _on_cancelled(self) -> None:
        step = self.tracker.step if self.tracker is not None else ""
        self.step_label.setText(f"cancelled during {html.escape(step) or 'set-up'}; the devices were stopped")
        self.save_label.setText("nothing to save (cancelled)")
        self.status.emit("calibration cancelled")

    def _on_job_done(self) -> None:
        self.release_display("calibration")
        self.progress.setRange(0, 1)
        self.progress.setValue(1 if self.outcome is not None else 0)
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        self.live_check.setEnabled(True)
        self.wizard_button.setEnabled(True)
        if not self.service.simulated:
            for role in ("projector", "camera", "sync"):
                self.service.notify(role)

    # ------------------------------------------------------------------ results
    def show_outcome(self, outcome: CalibrationOutcome) -> None:
        """Show a run's figures, maps and plots."""
        if outcome is not self.outcome:
            self.saved_path = None
        self.outcome = outcome
        self.results.setText(results_html(outcome))
        hom = outcome.homography
        if hom is not None and np.isfinite(hom.residual_map).any():
            rmap = hom.residual_map
            finite = np.isfinite(rmap)
            top = float(np.percentile(rmap[finite], 99.5)) or 1.0
            self.residuals.set_image(np.where(finite, rmap, 0.0).astype(np.float32), levels=(0.0, top))
            over = np.zeros((*rmap.shape, 4), np.uint8)
            over[~finite] = UNDECODED_RGBA
            self.residuals.set_overlay(over)
            self.residuals.set_title(f"homography residual |H(projector point) − camera pixel| (px): RMS "
                                     f"{hom.rms_px:.3f} px, {hom.coverage:.1%} decoded, {hom.inliers} inliers "
                                     "(blue-grey: not decoded)")
        else:
            self.residuals.clear("no homography fit")
            self.residuals.set_title("homography residuals: no fit")
        ver = outcome.shutter
        if ver is not None:
            rgb = np.zeros((*ver.wrong.shape, 3), np.uint8)
            rgb[ver.decodable] = RIGHT_RGB
            rgb[ver.wrong] = WRONG_RGB
            self.wrong_panel.set_image(rgb)
            self.wrong_panel.set_title(f"shutter: {int(ver.wrong.sum())} camera pixels see another slot (red) of "
                                       f"{int(ver.decodable.sum())} decodable (green); accuracy {ver.accuracy:.3%}")
        else:
            self.wrong_panel.clear("the run stopped before the shutter step")
            self.wrong_panel.set_title("shutter: not verified")
        sync = outcome.sync
        if sync is not None and sync.leakage:
            k = np.arange(len(sync.leakage))
            self.leakage_bars.setOpts(x=k, height=np.asarray(sync.leakage), width=0.8)
        else:
            self.leakage_bars.setOpts(x=[], height=[], width=0.8)
        if sync is not None and sync.sweep:
            d = np.array([p[0] for p in sync.sweep])
            lost = np.array([p[1] for p in sync.sweep])
            self.sweep_points.setData(d, lost)
            if np.isfinite(sync.slope) and np.isfinite(sync.offset_slots):
                self.sweep_fit.setData(d, sync.offset_slots + sync.slope * d / sync.period_us)
            else:
                self.sweep_fit.setData([], [])
        else:
            self.sweep_points.setData([], [])
            self.sweep_fit.setData([], [])
        self.use_button.setEnabled(outcome.success)
        if outcome.success:
            self.save_button.setEnabled(True)
            self.save_label.setText("ready to save (homography and sync)")
        else:
            self.save_button.setEnabled(False)
            self.save_label.setText(f"<span style='color:{RED}'>not saved: the "
                                    f"{html.escape(str(outcome.report.get('failed')))} step failed "
                                    "(a failed calibration is never written)</span>")

    # ------------------------------------------------------------------ save
    def _browse(self) -> None:
        start = self.save_path.text() or str(Path.home() / "rig-calibration.json")
        path, _ = QFileDialog.getSaveFileName(self, "Save calibration", start, "Calibration (*.json)")
        if path:
            self.save_path.setText(path)

    def _save_clicked(self) -> None:
        self.save(self.save_path.text().strip())

    def save(self, path) -> Path | None:
        """Write the calibration file; None (with the reason shown) when it cannot."""
        from calibration.errors import CalibrationError
        from calibration.files import save_calibration

        if self.outcome is None or not self.outcome.success:
            self.save_label.setText(f"<span style='color:{RED}'>nothing to save: run a successful calibration "
                                    "first</span>")
            return None
        if not str(path):
            self.save_label.setText(f"<span style='color:{RED}'>choose where to save (folder/name.json)</span>")
            return None
        try:
            written = save_calibration(Path(path).expanduser(), self.outcome.homography, self.outcome.identity,
                                       sync=self.outcome.sync)
        except CalibrationError as exc:
            self.save_label.setText(f"<span style='color:{RED}'>not saved: {html.escape(str(exc))}</span>")
            return None
        self.saved_path = Path(written)
        self.save_label.setText(f"<span style='color:{GREEN}'>saved {html.escape(str(written))}</span>")
        self.status.emit(f"saved {written}")
        return written

    def _use_clicked(self) -> None:
        if self.outcome is not None and self.outcome.success:
            self.use_for_capture.emit(self.outcome, self.saved_path)

    # ------------------------------------------------------------------ live co-location
    def set_live(self, on: bool) -> None:
        """Start or stop the live co-location numbers."""
        if on and self.running:
            on = False
        if on:
            busy = self._guard() or self.attach_display("live")
            if busy:
                self.live_label.setText(f"<span style='color:{RED}'>cannot measure: {html.escape(busy)}</span>")
                on = False
        self.live_check.blockSignals(True)
        self.live_check.setChecked(on)
        self.live_check.blockSignals(False)
        if on:
            self.live_label.setText("measuring …")
            self.tabs.setCurrentWidget(self.colocation_view)
            self.colocation_view.set_title("co-location live: measuring …")
            self._measure_live()
        else:
            self.live_timer.stop()
            if self.live_job is not None and self.live_job.running:
                self.live_job.cancel()
            else:
                self.release_display("live")
            if not self.live_label.text().startswith("<span"):
                self.live_label.setText("off" if self.alignment is None else
                                        f"stopped · last: {html.escape(self.alignment.message)}")

    @property
    def live(self) -> bool:
        """True while live co-location numbers are on."""
        return self.live_check.isChecked()

    def _measure_live(self) -> None:
        if not self.live or (self.live_job is not None and self.live_job.running):
            return
        if self._live_target is None:
            self._live_target = target_for(self.service)
        target = self._live_target
        self.live_job = self.runner.submit(
            "co-location", lambda token, progress: measure_live_colocation(target, token),
            on_finished=self._on_colocation, on_failed=self._on_live_failed, on_done=self._on_live_done)

    def _on_colocation(self, live) -> None:
        self.colocation = live
        result = live.alignment
        self.colocation_view.show_alignment(live.image, result.homography if result.success else None,
                                            live.projector_size)
        if result.success:
            self.colocation_view.set_title(
                "co-location live: the camera with the projector's expected grid (dashed), border (yellow) and "
                "centre (red) through the current homography estimate; white ○: the camera's centre")
        else:
            self.colocation_view.set_title(f"co-location live: no homography estimate ({result.status})")
        self._on_alignment(result)

    def _on_alignment(self, result) -> None:
        self.alignment = result
        if result.success:
            dx, dy = result.offset_px
            text = (f"<b>offset</b> ({dx:+.2f}, {dy:+.2f}) px · <b>rotation</b> {result.rotation_deg:+.3f}° · "
                    f"<b>scale</b> {result.scale:.4f} · <b>lit</b> {result.lit_fraction:.1%}"
                    f"{' · <b>mirrored</b>' if result.mirrored else ''}<br>{html.escape(result.message)}")
        else:
            text = f"<span style='color:{RED}'>{html.escape(result.message)}</span>"
        self.live_label.setText(text)

    def _on_live_failed(self, message: str) -> None:
        self.live_label.setText(f"<span style='color:{RED}'>live co-location stopped: {html.escape(message)}</span>")
        self.set_live(False)

    def _on_live_done(self) -> None:
        if self.live:
            self.live_timer.start()
        else:
            self.release_display("live")

    # ------------------------------------------------------------------ wizard
    def open_sync_wizard(self):
        """Open the synchronisation wizard (modeless); returns it."""
        from app.gui.calibrate.sync_wizard import SyncWizard

        refused = self._claim_rig("wizard")
        if refused:
            self.status.emit(f"cannot open the wizard: {refused}")
            return None
        hom = self.outcome.homography.homography if self.outcome is not None and self.outcome.homography \
            is not None and self.outcome.homography.success else None
        wizard = SyncWizard(target_for(self.service), self.runner, tile=self.tile(),
                            homography=hom, parent=self)
        wizard.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        wizard.finished.connect(self._wizard_finished)
        wizard.show()
        self.wizard = wizard
        return wizard

    def _wizard_finished(self, _result: int) -> None:
        self.release_display("wizard")

    def shutdown(self) -> None:
        """Stop the live numbers and cancel a running calibration (window closing)."""
        self.set_live(False)
        if self.job is not None and self.job.running:
            self.job.cancel()
        self._display_users.clear()
        self._close_display()
