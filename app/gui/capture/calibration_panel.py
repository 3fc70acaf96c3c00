"""The Capture workspace's "Calibration" box: which calibration recordings use, and its phase and delay.

A calibration reaches Capture the ways it reaches ``flexvox capture``, through
:mod:`flexvox_calibration.capture_setup` (the one loader): a calibration file, a sync profile (the
synchronisation wizard's; its phase and trigger delay replace the calibration's), or the
Calibrate workspace's fresh run ("Use for capture"). A file or run made for another rig, camera
or resolution is refused, in words, and the previous calibration is kept.

The calibration in use lives in the :class:`~flexvox_app.gui.models.capture_model.CaptureModel`: the panel sets
it (:meth:`~flexvox_app.gui.models.capture_model.CaptureModel.set_calibration`, refused in words while a recording
runs) and shows it. The box says what recordings use: the homography's origin (a file by its path and content hash),
the phase of the shutter patterns and the camera trigger delay that goes with it, and whether the
camera applies the delay itself (a camera with a trigger-delay feature) or the operator must set it
and tick "trigger delay set on the camera".

The calibration file in use (and a sync profile loaded on top) is remembered in the settings and
loaded again at the next start, checked against the rig like any file; a file that is refused then
is named with the reason. Before a recording, :meth:`CalibrationPanel.confirm_record` asks once
about what would spoil it: no calibration at all (the operator's explicit "Record uncalibrated"
counts as the answer), or a plan at another timing than the sync was measured at.

The calibration file in use is watched: when it changes on disk (the Calibrate workspace saved over
it, or anything else wrote it), the top line says so at once and "Use the new calibration" takes
the new content; until then recordings keep the calibration loaded (its hash names it), and Record
asks first.
"""

from __future__ import annotations

import html
import logging
from pathlib import Path

from PySide6.QtCore import QFileSystemWatcher, Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QGridLayout,
    QGroupBox,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.capture.rig_setup import trigger_delay_by
from flexvox_app.gui.models.capture_calibration import capture_identity
from flexvox_app.gui.models.capture_model import Action, CaptureModel
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.questions import ask
from flexvox_app.gui.widgets.rich_text import AMBER, RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine
from flexvox_calibration.capture_setup import (
    CalibrationRefused,
    CaptureCalibration,
    file_sha256,
    from_run,
    load_for_capture,
    load_sync_for_capture,
)

CALIBRATION_FILE = "capture/calibration_file"
"""Settings key: the calibration file in use ("" when none)."""
CALIBRATION_SHA256 = "capture/calibration_sha256"
SYNC_PROFILE_FILE = "capture/sync_profile_file"
"""Settings key: the sync profile loaded on top of it ("" when none)."""
_logger = logging.getLogger(__name__)

UNCALIBRATED = "uncalibrated"
"""The risk of recording without a calibration (see :meth:`CalibrationPanel.record_risks`)."""
REPLACED = "replaced"
"""The risk of recording with a calibration whose file was replaced on disk since it was loaded."""


class CalibrationPanel(QGroupBox):
    """Load a calibration or a sync profile, or go uncalibrated; show the phase and delay in use.

    Parameters
    ----------
    service : RigService
        The capture rig (a calibration must match its identity).
    settings : AppSettings
        Remembers the calibration file in use; :meth:`restore` loads it again.
    model : CaptureModel
        Holds the calibration in use (its ``calibration_changed`` says when it changed) and the plan shown.
    """

    file_replaced = Signal(str)
    """The calibration file in use changed on disk: a line for the status bar."""

    def __init__(self, service: RigService, settings: AppSettings, model: CaptureModel, parent=None):
        super().__init__("Calibration", parent)
        self.service = service
        self.settings = settings
        self.model = model
        self.error = ""
        """Why the last calibration offered was refused ("" when it was taken)."""
        self.note = ""
        """What the start-up said of the calibration it restored ("" when nothing to say)."""
        self.run_outcome = None
        """The Calibrate workspace's outcome in use when it came from a run not (yet) saved, else None."""
        self.accepted: set[str] = set()
        """The risks the operator already accepted for this calibration (see :meth:`record_risks`)."""
        self.file_changed = False
        """The calibration file restored at start differs from the one last used (its hash changed)."""
        self.offered_profile: Path | None = None
        """The sync profile the wizard saved since flexvox started, until it is loaded."""
        self.file_in_use: Path | None = None
        """The calibration file the calibration in use was loaded from (None: a run, or uncalibrated)."""
        self.replaced = ""
        """How the file in use changed on disk since it was loaded ("" when it did not): "changed" or
        "removed"."""
        self.watcher = QFileSystemWatcher(self)
        self.watcher.fileChanged.connect(lambda _: self.check_file())
        self.watcher.directoryChanged.connect(lambda _: self.check_file())
        self.label = QLabel()
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.status_label = StatusLine(lines=2)
        """Two lines for the workspace's actions: calibrated or not, the phase and delay, or the next step."""
        self.load_button = QPushButton("Load calibration…")
        self.sync_button = QPushButton("Load sync profile…")
        self.sync_button.setToolTip("the synchronisation wizard's profile: its phase and camera trigger delay")
        self.clear_button = QPushButton("Drop the calibration…")
        self.clear_button.setToolTip("stop using the calibration: recordings and the live view then use the identity "
                                     "homography, phase 0 and no trigger delay (it asks first; the file stays)")
        self.delay_check = QCheckBox("trigger delay set on the camera (it cannot be told one)")
        self.delay_check.setToolTip("this camera has no trigger-delay feature: set the delay shown above in its "
                                    "vendor's tool, then tick this")
        self.use_new_button = QPushButton("Use the new calibration")
        self.use_new_button.setToolTip("the calibration file in use changed on disk: load it again, checked against "
                                       "this rig")
        self.use_new_button.setVisible(False)
        self.use_new_button.clicked.connect(self.use_new_file)
        self.top = QWidget()
        """The line that stays in view: :attr:`status_label` and, when the file in use changed, the offer."""
        t = QVBoxLayout(self.top)
        t.setContentsMargins(0, 0, 0, 0)
        t.setSpacing(2)
        t.addWidget(self.status_label)
        t.addWidget(self.use_new_button)
        row = QGridLayout()  # two a line: the controls column is narrow
        for i, b in enumerate((self.load_button, self.sync_button, self.clear_button)):
            row.addWidget(b, i // 2, i % 2)
        v = QVBoxLayout(self)
        v.addWidget(self.label)
        v.addLayout(row)
        v.addWidget(self.delay_check)
        self.load_button.clicked.connect(self._ask_calibration)
        self.sync_button.clicked.connect(self._ask_sync_profile)
        self.clear_button.clicked.connect(self.ask_clear)
        self.delay_check.toggled.connect(self._on_delay_toggled)
        model.plan_changed.connect(lambda _plan: self._show())
        self._show()

    @property
    def calibration(self) -> CaptureCalibration | None:
        """The calibration recordings use (None: uncalibrated, the identity map and phase 0): the model's."""
        return self.model.calibration

    def _on_delay_toggled(self, on: bool) -> None:
        self.model.delay_set_by_hand = on
        self._show()

    # ------------------------------------------------------------------ choosing
    def _identity(self):
        from rig_drivers.errors import DeviceError

        try:
            return capture_identity(self.service)
        except (DeviceError, OSError) as exc:
            raise CalibrationRefused(f"cannot read this rig's camera and projector sizes: {exc}") from exc

    def _ask(self, title: str, key: str, kind: str = "flexvox calibration") -> str:
        start = self.settings.last_folder(key)
        path, _ = QFileDialog.getOpenFileName(self, title, start, f"{kind} (*.json)")
        if path:
            self.settings.remember_folder(path, key)
        return path

    def _ask_calibration(self) -> None:
        path = self._ask("Load calibration", "capture/calibration_dir")
        if path:
            self.load_calibration(path)

    def _ask_sync_profile(self) -> None:
        path = self._ask("Load sync profile", "capture/calibration_dir", "flexvox sync profile")
        if path:
            self.load_sync_profile(path)

    def _held(self) -> bool:
        """True (with the model's words shown) while the calibration may not change (a recording runs)."""
        refusal = self.model.refusal(Action.CALIBRATION)
        if refusal is not None:
            self.refuse(refusal.text)
        return refusal is not None

    def _take(self, make, *, calibration_file=None, sync_file=None, outcome=None) -> bool:
        if self._held():
            return False
        try:
            calibration = make()
        except CalibrationRefused as exc:
            self.error = in_gui_words(str(exc))
            self._show()
            return False
        self.error, self.note = "", ""
        self.file_changed = False
        self.run_outcome = outcome
        self.accepted.clear()
        if calibration_file is not None:
            self._remember(calibration_file, "", calibration)
            self._watch(Path(calibration_file).expanduser().resolve() if calibration_file else None)
        if sync_file is not None:
            self.settings.set(SYNC_PROFILE_FILE, str(sync_file))
        self.model.set_calibration(calibration)  # calibration_changed: the workspace follows
        self._show()
        return True

    def _remember(self, calibration_file, sync_file, calibration: CaptureCalibration | None) -> None:
        """Keep the files in use for the next start ("" forgets them)."""
        path = str(Path(calibration_file).expanduser().resolve()) if calibration_file else ""
        self.settings.set(CALIBRATION_FILE, path)
        self.settings.set(CALIBRATION_SHA256, calibration.sha256 if path and calibration else "")
        self.settings.set(SYNC_PROFILE_FILE, str(sync_file))

    def load_calibration(self, path) -> bool:
        """Use a calibration file; False (reason shown, previous one kept) when refused."""
        return self._take(lambda: load_for_capture(path, self._identity()), calibration_file=path)

    def load_sync_profile(self, path) -> bool:
        """Use a sync profile's phase and trigger delay with the current homography; False when refused."""
        path = str(Path(path).expanduser().resolve())
        return self._take(lambda: load_sync_for_capture(path, self._identity(), base=self.calibration),
                          sync_file=path, outcome=self.run_outcome)

    def use_run(self, run, run_identity, *, outcome=None) -> bool:
        """Use a fresh calibration run (the Calibrate workspace's ``outcome``, not saved); False (with the reason)
        when refused. A run is no file: the next start cannot restore it."""
        return self._take(lambda: from_run(run, run_identity, self._identity()), calibration_file="",
                          outcome=outcome)

    def ask_clear(self) -> bool:
        """"Drop the calibration…": ask first, naming the calibration in use and what recordings use instead; True
        when it was dropped."""
        if self.calibration is None:
            return False
        if not ask(self, "Drop the calibration?",
                   f"Recordings and the live view now use: {self.calibration.describe()}.\n\n"
                   "Dropped, they use the identity projector-to-camera map, phase 0 and no trigger delay: on this "
                   "rig most pixels would see the wrong slot. A calibration file stays on disk (“Load "
                   "calibration…” takes it again); a run not saved is lost.",
                   accept="Drop the calibration", reject="Keep it"):
            return False
        self.clear()
        return True

    def clear(self) -> bool:
        """Record uncalibrated (the operator's choice: Record does not ask about it again); False (with the reason
        shown) while a recording runs."""
        if self._held():
            return False
        self.error, self.note, self.run_outcome = "", "", None
        self.file_changed = False
        self.accepted = {UNCALIBRATED}
        self._remember("", "", None)
        self._watch(None)
        self.model.set_calibration(None)
        self._show()
        return True

    def restore(self) -> bool:
        """Load the calibration file (and sync profile) in use at the last start, checked against this rig.

        Returns True when one was restored; a file that is refused now is named with the reason (and
        uncalibrated stays).
        """
        path = self.settings.get_str(CALIBRATION_FILE, "")
        sync = self.settings.get_str(SYNC_PROFILE_FILE, "")
        if not path and not sync:
            return False
        remembered = self.settings.get_str(CALIBRATION_SHA256, "")
        ok = self.load_calibration(path) if path else True
        if ok and sync:
            ok = self.load_sync_profile(sync)
        if not ok:
            self.error = f"the calibration last used was not restored: {self.error}"
            self._show()
            return False
        notes = [f"restored at start: {path or sync}, checked against this rig"]
        if path and remembered and self.calibration.sha256 != remembered:
            notes.append("the file changed since it was last used")
            self.file_changed = True
        self.note = "; ".join(notes)
        self._show()
        _logger.info("calibration restored: %s", self.note)
        return True

    def refuse(self, message: str) -> None:
        """Show why a calibration could not be taken now (e.g. a recording runs)."""
        self.error = message
        self._show()

    def offer_sync_profile(self, path) -> None:
        """The sync wizard saved a profile: say so here, and how to record with it (it is not taken unasked)."""
        self.offered_profile = Path(path)
        self._show()

    # ------------------------------------------------------------------ the file in use, on disk
    def _watch(self, path: Path | None) -> None:
        """Watch ``path`` (the file just loaded; None: no file) and its folder (a save replaces the file by a
        rename, which ends a watch on the file itself)."""
        old = self.watcher.files() + self.watcher.directories()
        if old:
            self.watcher.removePaths(old)
        self.file_in_use, self.replaced = path, ""
        if path is not None:
            self.watcher.addPaths([str(path), str(path.parent)])

    def check_file(self) -> bool:
        """Compare the file in use with what was loaded from it; say so on the top line and offer "Use the new
        calibration" when it changed on disk. True when it did."""
        path, cal = self.file_in_use, self.calibration
        if path is None or cal is None or not cal.sha256:
            return False
        try:
            now = file_sha256(path)
        except OSError:
            now = ""
        replaced = "" if now == cal.sha256 else ("changed" if now else "removed")
        if now and str(path) not in self.watcher.files():
            self.watcher.addPath(str(path))  # written anew: watch the new file
        if replaced != self.replaced:
            self.replaced = replaced
            if replaced:
                self.file_replaced.emit(f"the calibration file in use {'changed on disk' if now else 'was removed'}: "
                                        f"{path.name}" + (" — Capture offers the new calibration" if now else
                                                          " — Capture keeps the one loaded"))
                _logger.warning("the calibration file in use %s on disk: %s (loaded: sha256 %s, now %s)", replaced,
                                path, cal.sha256[:16], now[:16] or "no file")
            self._show()
        return bool(replaced)

    def use_new_file(self) -> bool:
        """Load the calibration file in use again (its new content, checked against this rig; a sync profile loaded
        on top stays on top); False when refused (the reason is shown and the calibration loaded before stays)."""
        sync = self.settings.get_str(SYNC_PROFILE_FILE, "")
        if self.file_in_use is None or not self.load_calibration(self.file_in_use):
            return False
        if sync:  # the sync profile loaded on top stays on top
            self.load_sync_profile(sync)
        _logger.info("Capture now uses the new content of %s", self.file_in_use)
        return True

    def forget_refusal(self) -> None:
        """The last refused load is old news once the live view or a recording starts with what is in use."""
        if self.error:
            self.error = ""
            self._show()

    def set_locked(self, locked: bool) -> None:
        """Grey the buttons out while a recording runs (Drop has nothing to drop when uncalibrated)."""
        for w in (self.load_button, self.sync_button, self.clear_button, self.delay_check, self.use_new_button):
            w.setEnabled(not locked)
        self.clear_button.setEnabled(not locked and self.calibration is not None)

    # ------------------------------------------------------------------ what recordings use
    def capture_calibration(self) -> CaptureCalibration:
        """What recordings use (uncalibrated when none was chosen): the model's."""
        return self.model.capture_calibration

    @property
    def delay_set_by_hand(self) -> bool:
        """The operator confirmed the trigger delay is set on a camera that cannot be told it."""
        return self.model.delay_set_by_hand

    def record_risks(self, plan: CapturePlan) -> list[str]:
        """What would spoil a recording of ``plan``, in words: no calibration (:data:`UNCALIBRATED`), its file
        changed on disk since it was loaded (:data:`REPLACED`), or a sync measured at another timing. Empty when
        nothing does."""
        if self.calibration is None:
            return [UNCALIBRATED]
        replaced = [REPLACED] if self.check_file() else []
        return replaced + [in_gui_words(w) for w in self.calibration.for_plan(plan.K, plan.period_us)[2]]

    def confirm_record(self, plan: CapturePlan, parent=None) -> bool:
        """Ask once about each risk of :meth:`record_risks` the operator has not accepted; False when one was
        declined (nothing is recorded)."""
        for risk in self.record_risks(plan):
            if risk in self.accepted:
                continue
            if risk == REPLACED:
                if not self._confirm_replaced(parent):
                    return False
                if self.replaced == "removed":
                    self.accepted.add(REPLACED)
                    continue
                return self.confirm_record(plan, parent)  # the new calibration's own risks
            if risk == UNCALIBRATED:
                title = "Record uncalibrated?"
                text = ("No calibration is in use: the shutter patterns assume the identity projector-to-camera map, "
                        "phase 0 and no trigger delay, so on this rig most pixels would see the wrong slot.\n\n"
                        "Calibrate (Calibrate workspace, then “Use for capture”) or load a calibration file; or "
                        "record uncalibrated anyway.")
                accept = "Record uncalibrated"
            else:
                title = "Record at another timing than the sync was measured at?"
                text = f"{risk[0].upper()}{risk[1:]}.\n\nRecord anyway?"
                accept = "Record anyway"
            if not ask(parent or self, title, text, accept=accept, reject="Cancel"):
                return False
            self.accepted.add(risk)
        return True

    def _confirm_replaced(self, parent) -> bool:
        """Record asks before it uses a calibration whose file changed on disk: yes takes the new content."""
        gone = self.replaced == "removed"
        text = (f"The calibration file in use, {self.file_in_use}, "
                + ("was removed" if gone else "changed on disk") + " since Capture loaded it. Recordings still use "
                f"the calibration loaded then (sha256 {self.calibration.sha256[:16]})"
                + ("." if gone else ", not the new one.\n\nUse the new calibration (checked against this rig) and "
                   "record?"))
        if gone:
            return ask(parent or self, "Record with a calibration whose file is gone?", text + "\n\nRecord anyway?",
                       accept="Record anyway", reject="Cancel")
        if not ask(parent or self, "Use the new calibration?", text, accept="Use the new calibration and record",
                   reject="Cancel"):
            return False
        return self.use_new_file()

    def _show(self) -> None:
        cal = self.capture_calibration()
        lines = []
        uncalibrated_line = "uncalibrated: run Calibrate and “Use for capture”, or load a calibration below"
        short = coloured(uncalibrated_line, AMBER) if self.calibration is None else "<b>calibrated</b>"
        if self.calibration is None:
            lines.append("<b>uncalibrated</b>: identity homography, phase 0, no trigger delay — a real rig (and the "
                         "simulated one) needs its calibration: run it in Calibrate and “Use for capture”, or load "
                         "the file")
        else:
            lines.append(f"<b>active</b>: {html.escape(cal.describe())}")
        if self.note:
            lines.append(html.escape(self.note))
        plan = self.model.plan
        phase, delay, warnings = cal.for_plan(plan.K, plan.period_us)
        by = trigger_delay_by(self.service.rig.camera.capabilities, delay, self.delay_set_by_hand)
        needs_hand = by in ("operator", None)
        if by == "none":
            lines.append(f"recordings use phase <b>{phase}</b>, no camera trigger delay")
        else:
            how = {"camera": "set by the camera", "operator": "set by you on the camera ✓"}.get(
                by, "this camera cannot be told it: set it in the camera's own tool and tick the box below")
            lines.append(f"recordings use phase <b>{phase}</b> and a <b>{delay:.0f} µs</b> camera trigger delay "
                         f"({html.escape(how)})")
        warnings = [in_gui_words(w) for w in warnings]
        lines += [coloured(f"• {w}", AMBER) for w in warnings if self.calibration is not None]
        if self.calibration is not None:
            numbers = f"phase {phase}" + (f", {delay:.0f} µs trigger delay" if by != "none" else "")
            if warnings:  # the timing changed since the sync was measured: not what "calibrated" promises
                short = coloured(f"calibrated at another timing: {numbers} is a guess — {warnings[0]}", AMBER)
            else:
                short += f": {html.escape(numbers)}"
            if needs_hand and not self.delay_set_by_hand:
                short += coloured(" — set the delay on the camera (Calibration below)", AMBER)
        self.delay_check.setVisible(needs_hand)
        if self.offered_profile is not None and self.settings.get_str(SYNC_PROFILE_FILE, "") != str(
                self.offered_profile.expanduser().resolve()):
            lines.append(f"the synchronisation wizard saved {html.escape(str(self.offered_profile))}: “Load sync "
                         "profile…” records with its phase and trigger delay")
            if self.calibration is None:  # calibrated, the profile is an alternative, said below
                short += " · " + coloured("the wizard's sync profile is not loaded (Calibration below)", AMBER)
        if self.error:
            lines.append(coloured(f"refused: {self.error}", RED))
        self.label.setText("<br>".join(lines))
        if self.calibration is not None and self.file_changed:
            short += coloured(" — the file changed since it was last used", AMBER)
        if self.calibration is not None and self.replaced:
            what = "was removed" if self.replaced == "removed" else "changed on disk"
            offer = "" if self.replaced == "removed" else ": “Use the new calibration” takes it"
            line = f"the calibration file in use {what}; recordings still use the one loaded{offer}"
            lines.append(coloured(html.escape(line), AMBER))
            short += " — " + coloured(html.escape(f"its file {what}: recordings use the one loaded"
                                                  + (" until “Use the new calibration”" if offer else "")), AMBER)
        self.use_new_button.setVisible(self.replaced == "changed")
        if self.error:  # after what is in use: the refusal changed nothing
            short += " · " + coloured(f"not loaded: {self.error}", RED)
        self.clear_button.setEnabled(self.calibration is not None and self.load_button.isEnabled())
        self.status_label.setText(short)
