"""The Capture workspace's "Recording" box: where, how many frames, Record and Stop, counters, the end.

Recording runs through :class:`flexvox_app.capture.service.CaptureService` (built by
:func:`flexvox_app.gui.models.recording.make_capture`, or the ``capture_factory`` given), the service
``flexvox capture`` drives, with the plan and calibration of the workspace's
:class:`~flexvox_app.gui.models.capture_model.CaptureModel`, whose refusal of a recording the panel shows.

Device ownership: a recording *owns* the devices. :meth:`RecordPanel.record` takes them in the model
(:attr:`~flexvox_app.gui.models.capture_model.Holder.RECORDING`), which stops the live view first (its reader
thread and the capture's must not both read the camera); the capture service sets up the projector, sync box and
camera, reads and writes on its own threads, and stops the devices at the end. Starting (a real projector's
pattern upload takes seconds) and stopping (the writer drains its queue) run on the job runner,
so the window never waits on them. The counters and the end come as the capture's events
(``progress``, ``finished``), handed to the GUI thread by
:class:`~flexvox_app.gui.capture.capture_signals.CaptureSignals`.
"""

from __future__ import annotations

import html
import logging
import time
from pathlib import Path

from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.capture.capture_signals import CaptureSignals
from flexvox_app.gui.models.capture_model import Action, CaptureModel, Cause, Holder
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.recording import counters_text, ground_truth_cost, make_capture, result_text
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.collapsible import Collapsible
from flexvox_app.gui.widgets.qt_jobs import JobRunner
from flexvox_app.gui.widgets.questions import replace_question
from flexvox_app.gui.widgets.rich_text import GREEN, RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine

_logger = logging.getLogger(__name__)

STOP_TIMEOUT_S = 30.0



class RecordPanel(QObject):
    """Record the plan through the calibration into a recording, and say how it went.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner
    model : CaptureModel
        What a recording uses (the plan, the calibration, the trigger delay set by hand), who holds the devices,
        and the recording's refusal.
    confirm : callable
        ``(plan) -> bool``: asks the operator about what would spoil the recording (no calibration); False
        records nothing.
    capture_factory : callable, optional
        Builds the capture service (tests inject slow or failing writers).
    """

    started = Signal(object)
    """The running :class:`CaptureService` (its frames can now be shown)."""
    finished = Signal(object)
    """The :class:`~flexvox_app.capture.service.CaptureResult` (None when the capture did not stop in time)."""
    changed = Signal()
    """Recording began or ended (buttons elsewhere follow)."""
    open_requested = Signal(object)
    """A recording's path the operator wants to review."""

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner, model: CaptureModel, *,
                 confirm=lambda plan: True, capture_factory=None, parent: QWidget):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.runner = runner
        self.model = model
        self._confirm = confirm
        self.capture_factory = capture_factory
        self.capture = None
        """The running (or last) :class:`CaptureService`, None before the first recording."""
        self.last_result = None
        self._stop_job = None
        self._start_job = None
        self._before_refusal: str | None = None
        """The result line a refusal covers (None: no refusal is shown); it comes back when the refusal goes."""
        self.signals = CaptureSignals(self)
        """The running capture's events, on the GUI thread."""
        self.signals.progress.connect(self._on_progress)
        self.signals.finished.connect(self._on_finished)
        self._build(parent)
        model.refusal_changed.connect(self._on_refusal)

    @property
    def recording(self) -> bool:
        """True from Record until the capture has ended (the model's holder is a recording)."""
        return self.model.recording

    def _build(self, parent) -> None:
        rec = QGroupBox("Recording", parent)
        self.path_edit = QLineEdit(self.settings.get_str("capture/recording_path", ""))
        self.path_edit.setPlaceholderText("folder/name.zarr")
        self.browse_button = QPushButton("Browse…")
        path_row = QHBoxLayout()
        path_row.addWidget(self.path_edit, 1)
        path_row.addWidget(self.browse_button)
        self.frames_box = QSpinBox()
        self.frames_box.setRange(0, 10_000_000)
        self.frames_box.setSpecialValueText("until Stop")
        self.frames_box.setValue(self.settings.get_int("capture/frames", 150))
        self.durable_check = QCheckBox("flush each frame to disk (slower)")
        self.durable_check.setToolTip("survives a power cut: each frame's chunk and "
                                      "journal record reach the disk before the next frame, so a power cut loses at "
                                      "most the frame in flight. Without it, a killed program still loses nothing.")
        self.durable_check.setChecked(self.settings.get_bool("capture/durable", False))
        self.truth_check = QCheckBox("store the scene's ground truth (simulated rig)")
        self.truth_check.setChecked(self.service.simulated and self.settings.get_bool("capture/ground_truth", True))
        self.truth_check.setVisible(self.service.simulated)
        self.truth_cost = StatusLine("", lines=2)  # what the ground truth costs, shown while it is ticked
        self.truth_cost.setStyleSheet("color: gray")
        keep = self.truth_cost.sizePolicy()  # its room stays when hidden: Record and Open in Review never move
        keep.setRetainSizeWhenHidden(True)
        self.truth_cost.setSizePolicy(keep)
        self._finish_started: float | None = None
        self._with_truth = False
        self.record_button = QPushButton("● Record")
        self.stop_button = QPushButton("■ Stop")
        self.stop_button.setEnabled(False)
        buttons = QHBoxLayout()
        buttons.addWidget(self.record_button)
        buttons.addWidget(self.stop_button)
        self.counters_label = StatusLine("not recording", lines=2)
        self.recording_label = StatusLine("not recorded yet", lines=3)
        self.recording_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.review_button = QPushButton("Open in Review")
        self.review_button.setEnabled(False)
        f = QFormLayout()
        f.addRow("path", path_row)
        f.addRow("frames", self.frames_box)
        options = QWidget()
        ov = QVBoxLayout(options)
        ov.setContentsMargins(12, 0, 0, 0)
        for w in (self.durable_check, self.truth_check, self.truth_cost):
            ov.addWidget(w)
        self.options = Collapsible("options", options, settings=self.settings, key="capture/show_record_options")
        rv = QVBoxLayout(rec)  # word-wrapped labels get their full height in a box layout, not a form
        rv.addLayout(f)
        rv.addWidget(self.options)
        rv.addLayout(buttons)
        for w in (self.counters_label, self.recording_label, self.review_button):
            rv.addWidget(w)
        self.box = rec

        self.browse_button.clicked.connect(self._browse)
        self.record_button.clicked.connect(self.record)
        self.stop_button.clicked.connect(self.stop)
        self.review_button.clicked.connect(self._ask_review)
        self.path_edit.textChanged.connect(lambda text: self.settings.set("capture/recording_path", text))
        self.frames_box.valueChanged.connect(lambda n: self.settings.set("capture/frames", n))
        self.durable_check.toggled.connect(lambda on: self.settings.set("capture/durable", on))
        self.truth_check.toggled.connect(self._on_truth_toggled)
        self.frames_box.valueChanged.connect(lambda _: self.show_truth_cost())
        self.show_truth_cost()

    def _on_truth_toggled(self, on: bool) -> None:
        self.settings.set("capture/ground_truth", on)  # the next start keeps the operator's choice
        self.show_truth_cost()

    def show_truth_cost(self) -> None:
        """Say what the ground truth costs while it is ticked: size per frame and second, the longer finish."""
        sim = self.service.rig.simulated
        on = sim is not None and self.truth_check.isChecked()
        self.truth_cost.setVisible(on)
        if not on:
            return
        try:
            plan = self.model.plan
            K, hz = plan.K, plan.camera_hz
        except ValueError:
            return
        H, W = sim.camera.sensor_shape
        measured = self.settings.get_float("capture/truth_finish_s_per_frame", -1.0)
        self.truth_cost.setText(ground_truth_cost(K, H, W, hz, self.frames_box.value() or None,
                                                  measured if measured > 0 else None))

    @property
    def finishing(self) -> bool:
        """The recording has its last frame and is being finalised: Stop can do nothing more."""
        return self.recording and self._finish_started is not None

    def update_buttons(self, plan_ok: bool) -> None:
        """Enable what can be used now (``plan_ok``: the plan's timing is accepted)."""
        self.record_button.setEnabled(plan_ok and not self.recording)
        self.stop_button.setEnabled(self.recording and self._stop_job is None and not self.finishing)
        self.show_truth_cost()
        for w in (self.path_edit, self.browse_button, self.frames_box, self.durable_check, self.truth_check):
            w.setEnabled(not self.recording)

    def _browse(self) -> None:
        start = self.path_edit.text() or str(Path(self.settings.last_folder()) / "recording.zarr")
        path, _ = QFileDialog.getSaveFileName(self.box, "Record to", start, "Zarr recordings (*.zarr)",
                                              options=QFileDialog.Option.DontConfirmOverwrite)  # Record asks
        if path:
            self.settings.remember_folder(path)
            self.path_edit.setText(path if path.endswith(".zarr") else path + ".zarr")

    def say(self, text: str, colour: str | None = None) -> None:
        """Put ``text`` in the result line (a refusal shown there goes)."""
        self.model.clear(Action.RECORD)
        self.recording_label.setText(coloured(text, colour) if colour else html.escape(text))

    def _on_refusal(self, action: Action, refusal) -> None:
        """Show the model's refusal of a recording; the line before comes back once it no longer holds."""
        if action is not Action.RECORD:
            return
        if refusal is not None:
            if self._before_refusal is None:
                self._before_refusal = self.recording_label.text()
            self.recording_label.setText(coloured(refusal.text, RED))
        elif self._before_refusal is not None:
            self.recording_label.setText(self._before_refusal)
            self._before_refusal = None

    # ------------------------------------------------------------------ recording
    def record(self) -> bool:
        """Start recording to the chosen path; False (with the reason shown) when it cannot start."""
        from flexvox_app.capture.service import CaptureError

        if self.recording:
            return False
        text = self.path_edit.text().strip()
        if not text:
            self.model.refuse(Action.RECORD, "choose a recording path first (folder/name.zarr)")
            return False
        if not self.model.check(Action.RECORD):  # the plan's timing, the rig held elsewhere
            return False
        plan = self.model.plan
        path = Path(text).expanduser()
        overwrite = path.exists()
        if overwrite and not replace_question(self.box, path, "recording"):
            self.model.refuse(Action.RECORD, f"not recording: {path} is kept (choose another path)")
            return False
        if not self._confirm(plan):
            self.model.refuse(Action.RECORD, "not recording: you chose not to record with this calibration")
            return False
        self.model.take(Holder.RECORDING)  # the live view stops
        frames = self.frames_box.value() or None
        options = {} if self.capture_factory is None else {"factory": self.capture_factory}
        with_truth = self.service.simulated and self.truth_check.isChecked()
        try:
            capture = make_capture(self.service, plan, path, frames=frames,
                                   calibration=self.model.capture_calibration,
                                   delay_set_by_hand=self.model.delay_set_by_hand,
                                   overwrite=overwrite, durable=self.durable_check.isChecked(),
                                   ground_truth=with_truth, **options)
        except (CaptureError, ValueError) as exc:
            self.model.release(Holder.RECORDING)
            self.model.refuse(Action.RECORD, f"cannot record: {in_gui_words(str(exc))}",
                              Cause.DEVICE if isinstance(exc, CaptureError) else Cause.SETTINGS)
            return False
        self.capture = capture
        self.signals.follow(capture)  # before it starts: no event is missed
        self.settings.remember_folder(capture.path)
        self.last_result = None
        self._stop_job = None
        self._finish_started = None
        self._with_truth = with_truth
        self.review_button.setEnabled(False)
        self.changed.emit()
        self.say(f"starting: setting up the rig for {capture.path.name} …")
        self.counters_label.setText("starting …")
        self._start_job = self.runner.submit("capture start", lambda token, progress: capture.start(),
                                             on_finished=lambda _: self._on_started(capture),
                                             on_failed=lambda message: self._on_start_failed(capture, message))
        return True

    def _notify_devices(self) -> None:
        for role in ("projector", "camera", "sync"):
            self.service.notify(role)

    def _on_started(self, capture) -> None:
        if capture is not self.capture or not self.recording:
            return
        self._notify_devices()
        target = f"{capture.n_target} frames" if capture.n_target else "until Stop"
        self.say(f"recording to {capture.path} ({target}, {1 / capture.frame_period_s:.3f} Hz; calibration: "
                 f"{capture.calibration.source}; phase {capture.phase_slots}, trigger delay "
                 f"{capture.trigger_delay_us:.0f} µs)")
        self.started.emit(capture)

    def _on_start_failed(self, capture, message: str) -> None:
        if capture is not self.capture:
            return
        self.model.release(Holder.RECORDING)
        self.signals.release()
        self.counters_label.setText("not recording")
        self.say(f"cannot record: {in_gui_words(message)}", RED)
        self._notify_devices()
        self.changed.emit()

    def stop(self) -> None:
        """Stop the recording early (it keeps every frame captured); the end is reported when it has stopped."""
        capture, start = self.capture, self._start_job
        if not self.recording or capture is None or self._stop_job is not None:
            return
        depth = capture.stats().queue_depth
        self.say(f"stopping: writing the {depth} frame{'s' if depth != 1 else ''} still queued …" if depth else
                 "stopping: the camera stops; then the recording is finalised …")

        def stop(token, progress):
            while start is not None and start.outcome is None:  # still setting up: stop once it runs
                token.check()
                capture.wait(0.05)
            if start is not None and start.outcome != "finished":
                return None  # it never started; its failure is reported by the start job
            return capture.stop(timeout_s=STOP_TIMEOUT_S)

        def stopped(result) -> None:
            if start is not None and start.outcome != "finished":
                return
            self._finish(capture, result)

        self._stop_job = self.runner.submit("capture stop", stop, on_finished=stopped,
                                            on_failed=lambda m: self._finish(capture, None, m))
        self.changed.emit()

    def _on_progress(self, capture, stats) -> None:
        if capture is self.capture and self.recording:
            self.counters_label.setText(counters_text(stats, capture.n_target, capture.frame_period_s))
            if stats.finishing:
                if self._finish_started is None:
                    self._finish_started = time.monotonic()
                    self.changed.emit()  # Stop goes grey: there is nothing left to stop
                self.say(f"finishing {capture.path.name}: {stats.finishing} …")

    def _on_finished(self, capture, result) -> None:
        if self._stop_job is None:  # else Stop's job reports the end
            self._finish(capture, result)

    def _finish(self, capture, result, error: str | None = None) -> None:
        if capture is not self.capture or not self.recording:
            return
        self.signals.release()
        self.model.release(Holder.RECORDING)
        self._stop_job = None
        self.last_result = result
        if self._finish_started is not None and self._with_truth and result is not None and result.ok \
                and result.frames_in_recording:
            per_frame = (time.monotonic() - self._finish_started) / result.frames_in_recording
            self.settings.set("capture/truth_finish_s_per_frame", per_frame)
        self._finish_started = None
        if result is not None:
            self.counters_label.setText(counters_text(result.stats, capture.n_target, capture.frame_period_s))
        if error is not None:
            self.say(f"recording failed: {in_gui_words(error)}", RED)
        else:
            ok = result is not None and result.ok
            self.say(result_text(result, capture.path, capture.frame_period_s), GREEN if ok else RED)
        self.review_button.setEnabled(result is not None and result.frames_in_recording is not None
                                      and result.frames_in_recording > 0)
        self._notify_devices()
        self.changed.emit()
        self.finished.emit(result)

    def _ask_review(self) -> None:
        if self.capture is not None:
            self.open_requested.emit(self.capture.path)

    def shutdown(self) -> None:
        """The window closes: stop a running recording (waits, bounded, for it to end)."""
        capture, start = self.capture, self._start_job
        if self.recording and capture is not None:
            deadline = time.monotonic() + STOP_TIMEOUT_S
            while start is not None and start.outcome is None and time.monotonic() < deadline:
                time.sleep(0.02)  # the rig is being set up on a worker: let it finish, then stop it
            if start is not None and start.outcome == "finished":
                result = capture.stop(timeout_s=STOP_TIMEOUT_S)
                _logger.info("recording stopped at shutdown: %s",
                             "did not stop in time" if result is None else result.message)
                self.last_result = result
            self.model.release(Holder.RECORDING)
        self.signals.release()
