"""The synchronisation wizard (``QWizard``): wiring checklist, trigger test, phase sweep, drop/drift test, save.

Each measuring page runs its step on the job runner with its own
:class:`flexvox_calibration.session.RigSession` (opened and closed by the job), so the window keeps
running; a page is complete when its measurement succeeded (the drop/drift page when it ran:
its verdict is saved with the profile either way). The steps are the ``flexvox_calibration.sync``
functions ``flexvox calibrate`` uses: :func:`~flexvox_calibration.sync.measure_sync` (single-shot band
code and delay sweep: the leakage curve) and :func:`~flexvox_calibration.sync.check_frames`; Save
writes :func:`~flexvox_calibration.sync.save_sync_profile`.
"""

from __future__ import annotations

import html
import logging
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (
    QCheckBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
    QWizard,
    QWizardPage,
)

from flexvox_app.gui.models.calibration_model import CalibrationTarget
from flexvox_app.gui.models.jobs import CancelToken
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.widgets.qt_jobs import JobHandle, JobRunner
from flexvox_app.gui.widgets.questions import ask, replace_question
from flexvox_app.gui.widgets.rich_text import AMBER, GREEN, RED
from flexvox_app.gui.widgets.status_line import StatusLine

_logger = logging.getLogger(__name__)
PROFILE_PATH = "calibrate/sync_profile_path"
"""Settings key: the last sync profile the wizard saved (its Save page offers the path again)."""


WIRING = (
    "the projector's TRIG_OUT_2 (or the sync box's frame output) is wired to the camera's trigger input",
    "that input is the trigger line named in the rig profile (Line0 unless it says otherwise)",
    "the projector is on, out of standby, and lights a still, flat, bright target the camera sees",
    "the camera's exposure and gain are set so the lit target is not saturated",
)


def trigger_verdict(frames, slots: int, settled: int) -> str:
    """What the trigger test found, explained: which camera frames came, and how bright they were in the camera's
    own units (counts of its full scale, or the simulated camera's relative units)."""
    ids = ", ".join(str(f.frame_id) for f in frames)
    gaps = (f"; the camera numbers every frame, and {settled} before each was skipped while the pattern settled"
            if settled else "")
    image = frames[0].image
    mean = float(np.mean([f.image.mean() for f in frames]))
    if np.issubdtype(image.dtype, np.integer):
        top = float(np.iinfo(image.dtype).max)
        level = f"mean level {mean:.0f} of {top:.0f} counts ({mean / top:.0%} of the camera's full scale)"
    else:
        level = (f"mean level {mean:.3g} in relative units (a white target seen through {slots} open slots reads "
                 f"about {slots}: the target sends back {mean / slots:.0%} of that)")
    return (f"{len(frames)} triggered frames arrived (camera frame numbers {ids}{gaps}); {level}: the camera follows "
            "the projector")


def _say(label, text: str, colour: str | None = None) -> None:
    label.setText(f"<span style='color:{colour}'>{html.escape(text)}</span>" if colour else html.escape(text))


class _JobPage(QWizardPage):
    """A page with one measurement: a button, a progress bar, a verdict; complete when it succeeded."""

    def __init__(self, wizard: SyncWizard, title: str, subtitle: str, button: str):
        super().__init__()
        self.owner = wizard
        self.setTitle(title)
        self.setSubTitle(subtitle)
        self.button = QPushButton(button)
        self.bar = QProgressBar()
        self.bar.setRange(0, 1)
        self.bar.setValue(0)
        self.verdict = StatusLine("not measured yet", lines=4)
        self.layout_ = QVBoxLayout(self)
        self.layout_.addWidget(self.button)
        self.layout_.addWidget(self.bar)
        self.layout_.addWidget(self.verdict)
        self.ok = False
        self.job: JobHandle | None = None
        self.button.clicked.connect(self.start)

    def work(self, token: CancelToken, progress):  # pragma: no cover - overridden
        raise NotImplementedError

    def show_result(self, result) -> bool:  # pragma: no cover - overridden
        raise NotImplementedError

    def start(self) -> None:
        """Run the page's measurement on the job runner."""
        if self.job is not None and self.job.running:
            return
        self.ok = False
        self.completeChanged.emit()
        self.button.setEnabled(False)
        self.bar.setRange(0, 0)
        _say(self.verdict, "measuring …")
        self.job = self.owner.runner.submit(self.title(), self.work, on_progress=self._progress,
                                            on_finished=self._finished, on_failed=self._failed,
                                            on_cancelled=lambda: _say(self.verdict, "cancelled"),
                                            on_done=self._done)

    def _progress(self, done: int, total: int) -> None:
        if total > 0:
            self.bar.setRange(0, total)
            self.bar.setValue(done)

    def _finished(self, result) -> None:
        self.ok = bool(self.show_result(result))
        self.completeChanged.emit()

    def _failed(self, message: str) -> None:
        _say(self.verdict, f"failed: {in_gui_words(message)}", RED)

    def _done(self) -> None:
        self.bar.setRange(0, 1)
        self.bar.setValue(1 if self.ok else 0)
        self.button.setEnabled(True)

    def isComplete(self) -> bool:  # noqa: N802 - Qt's name
        """Next is offered once the measurement succeeded."""
        return self.ok

    def cancel(self) -> None:
        """Cancel a running measurement."""
        if self.job is not None and self.job.running:
            self.job.cancel()


class WiringPage(QWizardPage):
    """The wiring checklist: every box ticked before Next."""

    def __init__(self, simulated: bool):
        super().__init__()
        self.setTitle("Wiring checklist")
        self.setSubTitle("The camera must be triggered by the projector (or the sync box) for every frame.")
        v = QVBoxLayout(self)
        if simulated:
            note = QLabel("Simulated rig: the wiring is simulated (TRIG_OUT_2 to Line0); tick the boxes to go on.")
            note.setWordWrap(True)
            v.addWidget(note)
        self.boxes = []
        for i, text in enumerate(WIRING):
            box = QCheckBox(text)
            self.registerField(f"wiring{i}*", box)
            self.boxes.append(box)
            v.addWidget(box)
        v.addStretch(1)


class TriggerPage(_JobPage):
    """Show a white pattern and read three frames: no frame means the trigger is not wired."""

    def __init__(self, wizard: SyncWizard):
        super().__init__(wizard, "Trigger test", "Shows a white pattern and waits for three triggered frames.",
                         "Test the trigger")

    def work(self, token, progress):
        from rig_drivers.errors import DeviceTimeoutError

        target = self.owner.target
        with target.session() as session:
            Hp, Wp = session.projector_size
            try:
                session.show(np.ones((session.slots, Hp, Wp), bool))
                frames = []
                for i in range(3):
                    token.check()
                    frames.extend(session.frames(1))
                    progress(i + 1, 3)
            except DeviceTimeoutError as exc:
                return False, (f"no frame within {session.timeout_s:g} s of showing the pattern: the camera is "
                               f"not triggered by the projector ({exc}). Check the wiring and the trigger line.")
            return True, trigger_verdict(frames, session.slots, session.settle_frames)

    def show_result(self, result) -> bool:
        ok, message = result
        _say(self.verdict, ("✓ " if ok else "✗ ") + message, GREEN if ok else RED)
        return ok


class PhasePage(_JobPage):
    """The phase sweep (measure_sync) with its leakage curve and delay sweep."""

    def __init__(self, wizard: SyncWizard):
        super().__init__(wizard, "Phase sweep",
                         "Plays a band code once per camera delay and measures how much of each slot's light "
                         "reaches the exposure (the leakage curve): phase and sub-slot delay.", "Run the phase sweep")
        self.leakage = pg.PlotWidget(title="leakage at delay 0")
        self.leakage.setBackground("#202020")
        self.leakage.setLabel("bottom", "projected slot")
        self.leakage.setLabel("left", "fraction of the slot's light")
        self.bars = pg.BarGraphItem(x=[], height=[], width=0.8, brush=(90, 160, 255, 200))
        self.leakage.addItem(self.bars)
        self.sweep = pg.PlotWidget(title="delay sweep")
        self.sweep.setBackground("#202020")
        self.sweep.setLabel("bottom", "camera trigger delay (µs)")
        self.sweep.setLabel("left", "slots of light lost")
        self.points = self.sweep.plot([], [], pen=None, symbol="o", symbolBrush=(255, 200, 80))
        plots = QHBoxLayout()
        plots.addWidget(self.leakage)
        plots.addWidget(self.sweep)
        self.layout_.addLayout(plots, 1)

    def work(self, token, progress):
        from flexvox_calibration.homography import calibrate_homography
        from flexvox_calibration.sync import measure_sync

        owner = self.owner
        K = owner.tile[0] * owner.tile[1]

        stages = 1 if owner.homography is None else 0  # the homography first, when measured here: one bar, 0→100 %

        shown = [0]

        def part(stage):
            def checked(done, total):  # stage s of the bar's (stages + 1) equal parts: it never goes back
                shown[0] = max(shown[0], int(1000 * (stage + min(done / max(total, 1), 1.0))))
                progress(shown[0], 1000 * (stages + 1))
                token.check()
            return checked

        with owner.target.session() as session:
            identity = session.identity
            h = owner.homography
            checked = part(stages)
            if h is None:
                hom = calibrate_homography(session, progress=part(0))
                if hom.homography is None or not hom.success:
                    return None, f"the homography (needed for the band code) failed: {hom.message}", identity
                h = hom.homography
            token.check()
            return h, measure_sync(session, h, K=K, progress=checked), identity

    def show_result(self, result) -> bool:
        h, sync, identity = result
        self.owner.identity = identity
        if h is None:
            _say(self.verdict, f"✗ {sync}", RED)
            return False
        self.owner.homography = h
        self.owner.sync = sync
        if sync.leakage:
            self.bars.setOpts(x=np.arange(len(sync.leakage)), height=np.asarray(sync.leakage), width=0.8)
        if sync.sweep:
            self.points.setData([p[0] for p in sync.sweep], [p[1] for p in sync.sweep])
        text = sync.message + "".join(f" Warning: {w}" for w in sync.warnings)
        ref = self.owner.reference
        if sync.success and ref is not None and ref.success:
            text += (f" (The Calibrate run measured {ref.recommended_camera_delay_us:.0f} µs and phase "
                     f"{ref.effective_phase_slots}: each sweep is a new measurement, so the sub-slot delay differs "
                     "by its noise, a few µs. Capture uses whichever you hand it: this profile once saved and "
                     "loaded, or the Calibrate run.)")
        _say(self.verdict, ("✓ " if sync.success else "✗ ") + text, GREEN if sync.success else RED)
        return sync.success


class DriftPage(_JobPage):
    """Drops and drift: 30 frames of a repeating sequence."""

    FRAMES = 30

    def __init__(self, wizard: SyncWizard):
        super().__init__(wizard, "Drop and drift test",
                         f"Reads {self.FRAMES} frames of a repeating sequence: frame-id gaps, late arrivals, and "
                         "the drift of the frame period against the sequence.", "Test drops and drift")

    def work(self, token, progress):
        from flexvox_calibration.sync import band_patterns, check_frames

        owner = self.owner
        K = owner.tile[0] * owner.tile[1]
        with owner.target.session() as session:
            bands, _ = band_patterns(owner.homography, session.camera_size, session.projector_size, K)
            token.check()
            return check_frames(session, bands, self.FRAMES)

    def show_result(self, check) -> bool:
        self.owner.frame_check = check
        _say(self.verdict, ("✓ " if check.success else "✗ ") + check.message, GREEN if check.success else RED)
        return True  # the verdict is saved with the profile, good or bad


class SavePage(QWizardPage):
    """Write the sync profile."""

    def __init__(self, wizard: SyncWizard):
        super().__init__()
        self.owner = wizard
        self.settings = wizard.settings
        self.setTitle("Save")
        self.setSubTitle("Writes the sync profile (phase, delay, drop/drift verdict) tied to this rig.")
        self.path = QLineEdit(self.settings.get_str(PROFILE_PATH, "") if self.settings is not None else "")
        self.path.setPlaceholderText("folder/sync-profile.json")
        self.browse_button = QPushButton("Browse…")
        self.button = QPushButton("Save sync profile")
        self.label = StatusLine(lines=2)
        v = QVBoxLayout(self)
        row = QHBoxLayout()
        row.addWidget(self.path, 1)
        row.addWidget(self.browse_button)
        v.addLayout(row)
        v.addWidget(self.button)
        v.addWidget(self.label)
        v.addStretch(1)
        self.button.clicked.connect(lambda: self.save(self.path.text().strip()))
        self.browse_button.clicked.connect(self._browse)
        self.written: Path | None = None

    def _browse(self) -> None:
        from PySide6.QtWidgets import QFileDialog

        start = self.path.text().strip() or "sync-profile.json"
        path, _ = QFileDialog.getSaveFileName(self, "Save the sync profile", start, "flexvox sync profile (*.json)",
                                              options=QFileDialog.Option.DontConfirmOverwrite)  # save asks
        if path:
            self.path.setText(path if path.endswith(".json") else path + ".json")

    def save(self, path) -> Path | None:
        """Write the profile; None (with the reason shown) when it cannot. An existing file is replaced only when
        the operator answers Replace to the question that names it."""
        from flexvox_calibration.errors import CalibrationError
        from flexvox_calibration.sync import save_sync_profile

        if self.owner.sync is None or not self.owner.sync.success:
            _say(self.label, "nothing to save: the phase sweep has not succeeded", RED)
            return None
        if not str(path):
            _say(self.label, "choose where to save (folder/name.json)", RED)
            return None
        target = Path(path).expanduser()
        if target.exists() and not replace_question(self, target, "sync profile"):
            _say(self.label, f"not saved: {target} is kept (choose another path)", AMBER)
            return None
        try:
            written = save_sync_profile(target, self.owner.sync, self.owner.identity,
                                        frame_check=self.owner.frame_check, overwrite=True)
        except CalibrationError as exc:
            _say(self.label, f"not saved: {in_gui_words(str(exc))}", RED)
            return None
        self.written = written
        if self.settings is not None:
            self.settings.set(PROFILE_PATH, str(written))
        _say(self.label, f"saved {written}", GREEN)
        return written


class SyncWizard(QWizard):
    """The synchronisation wizard.

    Parameters
    ----------
    target : CalibrationTarget
        The rig it measures (the simulated calibration rig, or the real rig).
    runner : JobRunner
    tile : (m, n)
        The shutter code's tile (K = m·n slots).
    homography : array (3, 3), optional
        From the Calibrate workspace's last run; measured on the phase page when None.
    reference : SyncResult, optional
        The Calibrate workspace's last sync measurement: the phase page says how its own compares.
    settings : AppSettings, optional
        Remembers the last profile saved: the Save page offers its path again.
    """

    def __init__(self, target: CalibrationTarget, runner: JobRunner, *, tile=(4, 4), homography=None,
                 reference=None, settings=None, parent: QWidget | None = None):
        super().__init__(parent)
        self.settings = settings
        self.reference = reference
        self.target = target
        self.runner = runner
        self.tile = tuple(tile)
        self.homography = homography
        self.sync = None
        self.frame_check = None
        self.identity = None
        """The rig identity the profile is tied to (read by the phase sweep's session)."""
        self.setWindowTitle("Synchronisation wizard")
        self.setOption(QWizard.WizardOption.NoBackButtonOnLastPage, True)
        self.wiring = WiringPage(target.simulated)
        self.trigger = TriggerPage(self)
        self.phase = PhasePage(self)
        self.drift = DriftPage(self)
        self.save_page = SavePage(self)
        for page in (self.wiring, self.trigger, self.phase, self.drift, self.save_page):
            self.addPage(page)
        self.resize(820, 640)

    def measuring(self) -> bool:
        """True while one of the pages measures."""
        return any(p.job is not None and p.job.running for p in (self.trigger, self.phase, self.drift))

    def cancel_jobs(self) -> None:
        """Cancel every running measurement."""
        for page in (self.trigger, self.phase, self.drift):
            page.cancel()

    def unsaved_work(self) -> list[str]:
        """The finished measurements that closing the wizard now would lose (not saved as a profile), in words."""
        if self.save_page.written is not None:
            return []
        out = []
        if self.sync is not None and self.sync.success:
            out.append(f"the phase sweep's result (phase {self.sync.effective_phase_slots}, camera trigger delay "
                       f"{self.sync.recommended_camera_delay_us:.0f} µs)")
        if self.frame_check is not None:
            out.append("the drop/drift test's verdict")
        return out

    def _may_close(self) -> bool:
        """Ask first when closing would lose finished measurements; True when the wizard may close."""
        lost = self.unsaved_work()
        return not lost or ask(self, "Close the synchronisation wizard?", "Closing the wizard now loses, not saved "
                               "as a sync profile:\n\n" + "\n".join(f"• {w}" for w in lost) + "\n\nClose anyway?",
                               accept="Close and lose them", reject="Keep working")

    def reject(self) -> None:
        """Cancel (or Esc, or the window's close box): ask first when finished measurements would be lost."""
        if self._may_close():
            super().reject()

    def accept(self) -> None:
        """Finish: ask first, as Cancel does, when the sweep or the drop/drift test is not saved."""
        if self._may_close():
            super().accept()

    def done(self, result: int) -> None:
        """Closing the wizard cancels what it measures."""
        self.cancel_jobs()
        super().done(result)
