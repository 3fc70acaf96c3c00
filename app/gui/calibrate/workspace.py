"""The Calibrate workspace: the whole calibration off the GUI thread, its results, save; live co-location.

The workspace runs the calibration and composes its parts:

- the run itself here: :func:`flexvox_app.gui.models.calibration_model.run_workspace_calibration` (the
  pipeline ``flexvox calibrate`` runs) on the job runner, with the step and its pattern count on
  screen and Cancel taking effect between steps and patterns;
- :class:`~flexvox_app.gui.calibrate.results_view.ResultsView`: every step's numbers and verdict, the
  homography's residual map, the shutter's wrong pixels, the sync leakage and delay sweep, and on
  the simulated rig the hidden truth beside what was found;
- :class:`~flexvox_app.gui.calibrate.save_panel.SavePanel`: the calibration file, or "Use for capture";
- :class:`~flexvox_app.gui.calibrate.live_colocation.LiveColocation`: the alignment numbers re-measured
  while the operator adjusts the beam splitter;
- :class:`~flexvox_app.gui.calibrate.projector_screen.ProjectorScreen`: on a real rig whose projector takes
  its patterns on a video input (the DLPC350), the screen the patterns go to while the rig is used;
- the synchronisation wizard (:mod:`flexvox_app.gui.calibrate.sync_wizard`).

On the simulated rig the calibration runs on the rig Capture records with (its calibration target
put in view), so "Use for capture" hands Capture a calibration of the same rig.
"""

from __future__ import annotations

import html
import logging
from collections.abc import Callable

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.calibrate.live_colocation import LiveColocation
from flexvox_app.gui.calibrate.projector_screen import ProjectorScreen
from flexvox_app.gui.calibrate.results_view import ResultsView
from flexvox_app.gui.calibrate.save_panel import SavePanel
from flexvox_app.gui.models.calibration_model import (
    STEPS,
    CalibrationOutcome,
    StepTracker,
    run_workspace_calibration,
    target_for,
)
from flexvox_app.gui.models.holder import Holder
from flexvox_app.gui.models.jobs import CancelToken
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.qt_jobs import JobHandle, JobRunner
from flexvox_app.gui.widgets.rich_text import GREEN, GREY, RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine
from flexvox_app.gui.widgets.workspace_layout import controls_beside_view
from flexvox_core.deprecations import renamed_keyword, warn_renamed

_logger = logging.getLogger(__name__)

CALIBRATION_USER = "the calibration"
WIZARD_USER = "the synchronisation wizard"
PROGRESS_STEP = 1000
"""The progress bar's units per calibration step."""

TILES = ((4, 4), (2, 4), (4, 2), (2, 2), (3, 5))


def steps_html(current: int, finished: bool = False) -> str:
    """The list of steps with done ✓, running ▶ and to-come · marks."""
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


class CalibrateWorkspace(QWidget):
    """Run the whole calibration, show and save its results; live co-location numbers; the sync wizard.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner
    held_elsewhere : callable, optional
        ``() -> str | None``: why another workspace holds the rig now (a recording), None when it does not; asked
        before a calibration, the live numbers or the wizard starts (the main window's also stops Capture's live
        view, which yields to them). The deprecated keyword ``rig_guard`` still works, with a
        ``DeprecationWarning``, until the next release.

    Notes
    -----
    Who holds the rig has one name across the GUI (:mod:`flexvox_app.gui.models.holder`): :attr:`holder` and
    :meth:`held_here` say what this workspace holds, :meth:`held_elsewhere` what another does.
    """

    status = Signal(str)
    """A line for the status bar."""
    calibrated = Signal(object)
    """A :class:`CalibrationOutcome` (successful or not) after each run."""
    use_for_capture = Signal(object)
    sync_profile_saved = Signal(object)
    """``(path)``: the synchronisation wizard finished with a profile saved there."""
    rig_released = Signal()
    """A calibration or the wizard ended: what it paused elsewhere may start again."""
    """The successful outcome the operator hands to the Capture workspace."""

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner, *,
                 held_elsewhere: Callable[[], str | None] | None = None, parent: QWidget | None = None,
                 **deprecated):
        held_elsewhere = renamed_keyword(deprecated, "rig_guard", "held_elsewhere", held_elsewhere,
                                         "CalibrateWorkspace")
        if deprecated:
            raise TypeError(f"CalibrateWorkspace() got unexpected keywords {', '.join(deprecated)}")
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.runner = runner
        self._held_elsewhere = held_elsewhere
        self.outcome: CalibrationOutcome | None = None
        self.job: JobHandle | None = None
        self.tracker: StepTracker | None = None
        self.wizard = None
        """The synchronisation wizard while it is open."""
        self.sync_profile = None
        """The sync profile the wizard last saved (None: none since flexvox started)."""
        self._before_refusal: str | None = None
        """The step line before a refusal took its place (None: no refusal shown)."""
        self.pauses_elsewhere = None
        """``() -> list[str]``: what a calibration would pause outside this workspace (the main window's: Capture's
        live view), said before Run."""
        self._resume_colocation = False
        self._holding = False
        self._shut = False
        self.results_view = ResultsView()
        self.screen = ProjectorScreen(service, settings, parent=self)
        self.save_panel = SavePanel(settings)
        self.live_panel = LiveColocation(service, runner, self.screen, self.results_view,
                                         held_elsewhere=self._held_for_live, parent=self)
        self._build()
        self.save_panel.use_for_capture.connect(self.use_for_capture)
        self.save_panel.saved.connect(lambda path: self.status.emit(f"saved {path}"))

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
        self.step_label = StatusLine("not run", lines=2)
        self.pause_note = StatusLine("", lines=1)
        """What Run calibration pauses (Capture's live view, “measure continuously”), said before it does."""
        self.pause_note.setStyleSheet("color: gray")
        self.steps_label = QLabel(steps_html(-1))
        self.steps_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(run)
        f.addRow("shutter code", self.tile_box)
        if self.screen.needed:
            f.addRow("projector screen", self.screen.screen_box)
            f.addRow(self.screen.label)
        f.addRow(buttons)
        f.addRow(self.pause_note)
        f.addRow(self.progress)
        f.addRow(self.step_label)
        steps = QGroupBox("Steps")
        sv = QVBoxLayout(steps)
        sv.addWidget(self.steps_label)
        sv.addWidget(self.rig_label)
        self.profile_label = QLabel()
        """Which sync profile the wizard saved (this calibration's file holds its own sync)."""
        self.profile_label.setWordWrap(True)
        sv.addWidget(self.profile_label)
        self._show_profile()

        # Run, Cancel, Save, Use for capture and the wizard stay in view; the steps, the rig and co-location scroll.
        self.wizard_button = QPushButton("Synchronisation wizard…")
        self.controls_scroll = controls_beside_view(self, (steps, self.live_panel.box), self.results_view,
                                                    actions=(run, self.save_panel, self.wizard_button),
                                                    min_width=340, max_width=420)

        self.run_button.clicked.connect(self.run_calibration)
        self.cancel_button.clicked.connect(self.cancel)
        self.live_panel.check.toggled.connect(lambda _: self.refresh_pause_note())
        self.wizard_button.clicked.connect(self.open_sync_wizard)
        self.tile_box.currentIndexChanged.connect(
            lambda _: self.settings.set("calibrate/tile", self.tile_box.currentText().split(" ")[0]))

    # ------------------------------------------------------------------ state
    @property
    def running(self) -> bool:
        """True while a calibration job runs."""
        return self.job is not None and self.job.running

    def held_here(self) -> str | None:
        """Why this workspace holds the rig now, in words (a calibration, a live measurement or the wizard uses
        it; the reason the Capture workspace is refused), None when it does not."""
        if self.running:
            return "a calibration is running in the Calibrate workspace"
        if self.live_panel.measuring:
            return "the co-location live numbers are measuring in the Calibrate workspace"
        if self.service.held_by:
            return f"{self.service.held_by} uses the devices (Calibrate workspace)"
        return None

    @property
    def holder(self) -> Holder:
        """:attr:`~flexvox_app.gui.models.holder.Holder.CALIBRATING` while :meth:`held_here` names a reason, else
        :attr:`~flexvox_app.gui.models.holder.Holder.IDLE` (Capture's holds are its own model's)."""
        return Holder.CALIBRATING if self.held_here() else Holder.IDLE

    def held_elsewhere(self) -> str | None:
        """Why another workspace holds the rig now (a recording), None when it does not (asks ``held_elsewhere``
        as given; the main window's also stops Capture's live view, which yields to the Calibrate workspace)."""
        return self._held_elsewhere() if self._held_elsewhere is not None else None

    def rig_busy_reason(self) -> str | None:
        """Deprecated name of :meth:`held_here` (removed in the next release)."""
        warn_renamed("CalibrateWorkspace.rig_busy_reason()", "CalibrateWorkspace.held_here()")
        return self.held_here()

    @property
    def rig_guard(self) -> Callable[[], str | None] | None:
        """Deprecated: the ``held_elsewhere`` callable given (removed in the next release; call
        :meth:`held_elsewhere`)."""
        warn_renamed("CalibrateWorkspace.rig_guard", "CalibrateWorkspace.held_elsewhere()")
        return self._held_elsewhere

    @rig_guard.setter
    def rig_guard(self, held_elsewhere: Callable[[], str | None] | None) -> None:
        warn_renamed("CalibrateWorkspace.rig_guard", "CalibrateWorkspace(held_elsewhere=)")
        self._held_elsewhere = held_elsewhere

    def _held_for_live(self) -> str | None:
        """Why the live numbers may not measure now: a calibration runs, or another workspace holds the rig."""
        if self.running:
            return "a calibration is running"
        return self.held_elsewhere()

    def _claim_rig(self, user: str) -> str | None:
        """Take the rig for ``user``: refuse while Capture uses it, stop the live numbers, attach the
        projector display on a real rig. Returns the reason it cannot, or None."""
        paused = self.paused_by_run()
        self._holding = True  # the note says what this run paused until it ends
        held = self.held_elsewhere()
        if held:
            self._holding = False
            return held
        self._resume_colocation = self.live_panel.live
        self.live_panel.set_live(False)
        refused = self.screen.attach(user)
        if refused:
            self._resume_paused()
        elif paused:
            self.pause_note.setText("paused: " + " and ".join(paused) + " (resumed when it ends)")
            self.status.emit(f"{'the calibration' if user == 'calibration' else 'the wizard'} pauses "
                             + " and ".join(paused) + " until it ends")
        return refused

    def paused_by_run(self) -> list[str]:
        """What Run calibration (or the wizard) pauses now, in words; it resumes when they end."""
        out = list(self.pauses_elsewhere()) if self.pauses_elsewhere is not None else []
        if self.live_panel.live:
            out.append("“measure continuously”")
        return out

    def refresh_pause_note(self) -> None:
        """Say under Run what it would pause (nothing when nothing runs)."""
        if self._holding:
            return
        paused = self.paused_by_run()
        self.pause_note.setText("" if not paused else "Run pauses " + " and ".join(paused) + "; "
                                + ("both resume" if len(paused) > 1 else "it resumes") + " when it ends")

    def _resume_paused(self) -> None:
        """Start again what the run paused here (“measure continuously”), and tell the window (Capture's live
        view)."""
        resume, self._resume_colocation = self._resume_colocation, False
        self._holding = False
        if self._shut:
            return
        if resume and not self.live_panel.live:
            self.live_panel.set_live(True)
        self.rig_released.emit()
        self.refresh_pause_note()

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
            if self._before_refusal is None:
                self._before_refusal = self.step_label.text()
            self.step_label.setText(coloured(f"cannot start: {refused}", RED))
            return False
        self._before_refusal = None
        token = CancelToken()
        tracker = StepTracker(token)
        self.tracker = tracker
        tile, service = self.tile(), self.service

        def job(token_, progress):
            def report(done: int, total: int) -> None:  # the whole run's progress, taken where the step is known
                within = done / total if total > 0 else 0.0
                progress(round(PROGRESS_STEP * (max(tracker.index, 0) + min(within, 1.0))), len(STEPS) * PROGRESS_STEP)

            tracker.token = token_
            tracker.report = report
            return run_workspace_calibration(target_for(service), tile=tile, cancel=token_, tracker=tracker)

        # The last result stays the one offered (Save, Use for capture) until this run ends: a cancelled or
        # failed run leaves it as it was.
        previous = self.outcome
        self.save_panel.hold("calibrating …" + (f" (the calibration of {previous.finished_at} is kept if this run "
                                                "is cancelled)" if previous is not None and previous.success else ""))
        if previous is not None:
            self.results_view.show_outcome(previous, note=f"a new calibration is running; shown: the calibration "
                                                          f"of {previous.finished_at}")
        self.service.begin_use(CALIBRATION_USER)
        self._set_running(True)
        self.step_label.setText("starting …")
        self.steps_label.setText(steps_html(0))
        self.progress.setRange(0, len(STEPS) * PROGRESS_STEP)
        self.progress.setValue(0)
        self.job = self.runner.submit("calibration", job, on_progress=self._on_progress, on_finished=self._on_done,
                                      on_failed=self._on_failed, on_cancelled=self._on_cancelled,
                                      on_done=self._on_job_done)
        self.status.emit("calibrating …")
        return True

    def _set_running(self, running: bool) -> None:
        self.run_button.setEnabled(not running)
        self.cancel_button.setEnabled(running)
        self.live_panel.check.setEnabled(not running)
        self.wizard_button.setEnabled(not running)

    def cancel(self) -> None:
        """Ask the running calibration to stop at its next step or pattern."""
        if self.running:
            self.job.cancel()
            self.step_label.setText("cancelling …")

    def _on_progress(self, value: int, top: int) -> None:
        """One bar for the whole run (``value`` of ``top``): each step has its share, filled by its patterns."""
        t = self.tracker
        if t is None:
            return
        step = f"step {t.index + 1} of {len(STEPS)}: {html.escape(t.step)}"
        self.progress.setRange(0, top)
        self.progress.setValue(max(value, self.progress.value()))
        self.step_label.setText(f"{step} — {t.done}/{t.total} patterns" if t.total > 0 else step)
        self.steps_label.setText(steps_html(t.index))

    def _on_done(self, outcome: CalibrationOutcome) -> None:
        self.show_outcome(outcome)
        word = "succeeded" if outcome.success else f"stopped at the {outcome.report.get('failed')} step"
        self.step_label.setText(coloured(f"calibration {word} ({outcome.seconds:.1f} s)",
                                         GREEN if outcome.success else RED))
        self.steps_label.setText(steps_html(len(STEPS), finished=outcome.success))
        self.status.emit(f"calibration {word}")
        self.calibrated.emit(outcome)

    def _kept(self, what: str) -> None:
        """The run ended without a result (``what`` happened): the previous result stays offered, and shown."""
        previous = self.outcome
        # The Steps list shows the run the results show (the earlier one), not the steps of the one that ended.
        self.steps_label.setText(steps_html(len(STEPS), finished=previous.success) if previous is not None
                                 else steps_html(-1))
        if previous is not None:
            self.results_view.show_outcome(previous, note=f"{what}; shown: the calibration of {previous.finished_at}")
            kept = "can still be saved" if previous.success else "stays"
            self.save_panel.release(f"{what}; the calibration of {previous.finished_at} {kept}")
        else:
            self.results_view.show_message(f"{what}: no results")
            self.save_panel.release(f"nothing to save ({what})")

    def _on_failed(self, message: str) -> None:
        self.step_label.setText(coloured(f"calibration failed: {in_gui_words(message)}", RED))
        self._kept("the calibration failed")
        self.status.emit(f"calibration failed: {in_gui_words(message)}")

    def _on_cancelled(self) -> None:
        step = self.tracker.step if self.tracker is not None else ""
        self.step_label.setText(f"cancelled during {html.escape(step) or 'set-up'}; the devices were stopped")
        self._kept("the new run was cancelled")
        self.status.emit("calibration cancelled")

    def _on_job_done(self) -> None:
        self.screen.release("calibration")
        self.service.end_use(CALIBRATION_USER)
        finished = self.job is not None and self.job.outcome == "finished"
        self.progress.setRange(0, 1)
        self.progress.setValue(1 if finished else 0)
        self._set_running(False)
        QTimer.singleShot(0, self, self._resume_paused)  # once the job is forgotten: the rig is free then

    def show_outcome(self, outcome: CalibrationOutcome) -> None:
        """Show a run's figures, maps and plots, and offer its result to save."""
        self.outcome = outcome
        self.results_view.show_outcome(outcome)
        self.save_panel.set_outcome(outcome)

    # ------------------------------------------------------------------ wizard
    def open_sync_wizard(self):
        """Open the synchronisation wizard (modeless); returns it."""
        from flexvox_app.gui.calibrate.sync_wizard import SyncWizard

        refused = self._claim_rig("wizard")
        if refused:
            self.status.emit(f"cannot open the wizard: {refused}")
            return None
        hom = self.outcome.homography.homography if self.outcome is not None and self.outcome.homography \
            is not None and self.outcome.homography.success else None
        reference = self.outcome.sync if self.outcome is not None else None
        wizard = SyncWizard(target_for(self.service), self.runner, tile=self.tile(), homography=hom,
                            reference=reference, settings=self.settings, parent=self)
        wizard.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        wizard.finished.connect(self._wizard_finished)
        wizard.show()
        self.wizard = wizard
        self.service.begin_use(WIZARD_USER)
        return wizard

    def _show_profile(self) -> None:
        last = self.settings.get_str("calibrate/sync_profile_path", "")
        if self.sync_profile is not None:
            text = (f"sync profile saved by the wizard: {self.sync_profile} — Capture takes it with “Load sync "
                    "profile…” (its phase and trigger delay replace the calibration's)")
        elif last:
            text = f"last sync profile the wizard saved: {last} (the synchronisation wizard measures a new one)"
        else:
            text = "no sync profile saved yet: the calibration's own sync is used (the synchronisation wizard " \
                   "measures one in detail)"
        self.profile_label.setText(text)

    def _wizard_finished(self, _result: int) -> None:
        written = self.wizard.save_page.written if self.wizard is not None else None
        if written is not None:
            self.sync_profile = written
            self.wizard_button.setToolTip(f"last sync profile saved: {written}")
            self._show_profile()
            self.status.emit(f"sync profile saved: {written}; Capture offers it (“Load sync profile…”)")
            self.sync_profile_saved.emit(written)
        self.wizard = None
        self.screen.release("wizard")
        self.service.end_use(WIZARD_USER)
        QTimer.singleShot(0, self, self._resume_paused)

    def recheck_refusals(self) -> None:
        """The rig was freed (a recording ended): take the refusals that said it was held off the screen."""
        if self._before_refusal is not None and not self.running:
            self.step_label.setText(self._before_refusal)
            self._before_refusal = None
        self.live_panel.recheck()

    def closing_losses(self) -> list[str]:
        """What closing the window would stop or lose now: a calibration or a wizard measurement running, or a
        successful calibration not saved (the next start cannot restore it)."""
        out = []
        if self.running:
            out.append("the calibration running stops; its result is lost")
        if self.wizard is not None and self.wizard.measuring():
            out.append("the synchronisation wizard's measurement stops")
        if self.wizard is not None:
            out += [f"{w} is lost (not saved as a sync profile)" for w in self.wizard.unsaved_work()]
        o = self.outcome
        if o is not None and o.success and self.save_panel.saved_path is None:
            out.append(f"the calibration that succeeded at {o.finished_at} is not saved: it is lost (the next start "
                       "restores only a saved calibration)")
        return out

    def shutdown(self) -> None:
        """Stop the live numbers and cancel a running calibration (window closing): nothing paused resumes."""
        self._resume_colocation = False
        self._shut = True
        self.live_panel.set_live(False)
        if self.job is not None and self.job.running:
            self.job.cancel()
        self.screen.close()
