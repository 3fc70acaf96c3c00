"""The Capture workspace: code and timing, calibration, live view, recording, projector output.

What Capture holds and decides is its :class:`~flexvox_app.gui.models.capture_model.CaptureModel` (Qt-free): the
plan, the calibration, who holds the devices (:class:`~flexvox_app.gui.models.capture_model.Holder`: nobody, the
live view, a recording, a calibration) and the refusals. The workspace composes its panels, views over that model,
and wires them:

- :class:`~flexvox_app.gui.capture.code_panel.CodePanel`: chooses the :class:`~flexvox_app.capture.plan.CapturePlan`
  (tile, multiplexed or a ``flexvox design -o`` file; rate and exposures; the timing check);
- :class:`~flexvox_app.gui.capture.calibration_panel.CalibrationPanel`: chooses the
  :class:`~flexvox_calibration.capture_setup.CaptureCalibration` (a calibration file, a sync profile or
  the Calibrate workspace's run), the phase and the camera trigger delay in use;
- :class:`~flexvox_app.gui.capture.live_panel.LivePanel`: the live view, histogram, saturation and the
  motion-aware preview (also of a running recording's frames);
- :class:`~flexvox_app.gui.capture.record_panel.RecordPanel`: Record and Stop through the capture
  service ``flexvox capture`` drives, counters, the end, "Open in Review";
- :class:`~flexvox_app.gui.capture.projector_panel.ProjectorPanel`: the packed patterns full-screen.

The live view, a recording and the projector window read the plan and the calibration from the model, so they
always use the same two (and the same patterns: :meth:`CapturePlan.patterns`). A recording owns the devices: taking
them in the model stops the live view first, and the live panel then shows the capture's newest frames.
"""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QWidget

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.gui.capture.calibration_panel import CalibrationPanel
from flexvox_app.gui.capture.code_panel import CodePanel
from flexvox_app.gui.capture.live_panel import LivePanel
from flexvox_app.gui.capture.projector_panel import ProjectorPanel
from flexvox_app.gui.capture.record_panel import RecordPanel
from flexvox_app.gui.models.capture_model import Action, CaptureModel, Holder
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.qt_jobs import JobRunner
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.workspace_layout import controls_beside_view
from flexvox_calibration.capture_setup import CaptureCalibration

_logger = logging.getLogger(__name__)


class CaptureWorkspace(QWidget):
    """The Capture workspace (see the module docstring).

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner, optional
        Starts and stops recordings off the GUI thread (default: one of its own).
    capture_factory : callable, optional
        ``(rig, plan, path, **options) -> CaptureService`` (default the capture service itself).
    held_elsewhere : callable, optional
        ``() -> str | None``: why the Calibrate workspace holds the rig (None: it does not), asked before the live
        view or a recording starts; while it names a reason the model's holder is ``Holder.CALIBRATING``.
    """

    recording_finished = Signal(object)
    """The :class:`~flexvox_app.capture.service.CaptureResult` (None when the capture did not stop in time)."""
    open_requested = Signal(object)
    """A recording's path the operator wants to review."""
    calibration_changed = Signal(object)
    """The :class:`~flexvox_calibration.capture_setup.CaptureCalibration` now used (None: uncalibrated)."""

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner | None = None, *,
                 capture_factory=None, held_elsewhere=None, parent: QWidget | None = None):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.runner = runner or JobRunner(parent=self)
        self.model = CaptureModel(held_elsewhere=held_elsewhere)
        """The plan, the calibration, who holds the devices and the refusals."""
        self.code = CodePanel(settings, self.model)
        self.calibration_panel = CalibrationPanel(service, settings, self.model)
        self.live_panel = LivePanel(service, settings, self.model, parent=self)
        self.record_panel = RecordPanel(service, settings, self.runner, self.model, confirm=self._confirm_record,
                                        capture_factory=capture_factory, parent=self)
        self.projector = ProjectorPanel(service, self.runner, self.model)
        self._layout()
        self.model.plan_changed.connect(lambda _plan: self._plan_changed())
        self.model.calibration_changed.connect(self._calibration_changed)
        self.model.holder_changed.connect(lambda _holder: self._update_buttons())
        self.record_panel.started.connect(self.live_panel.follow_capture)
        self.record_panel.started.connect(lambda _: self.calibration_panel.forget_refusal())
        self.live_panel.live_button.toggled.connect(lambda on: on and self.calibration_panel.forget_refusal())
        self.record_panel.finished.connect(self._recording_ended)
        self.record_panel.changed.connect(self._update_buttons)
        self.record_panel.open_requested.connect(self.open_requested)
        self.record_panel.path_edit.textChanged.connect(
            lambda _: self.model.recheck(settings_changed=True, actions=(Action.RECORD,)))
        service.subscribe(self._on_devices)
        self.destroyed.connect(lambda *_: service.unsubscribe(self._on_devices))
        self._plan_changed()
        self.calibration_panel.restore()

    def _layout(self) -> None:
        # The actions (live view, Record, Stop, Open in Review) and the calibration's one line stay in view;
        # the code, timing, calibration details and projector output scroll below them.
        self.controls_scroll = controls_beside_view(
            self, (self.code, self.calibration_panel, self.projector), self.live_panel.views,
            actions=(self.calibration_panel.top, self.live_panel.controls, self.record_panel.box),
            min_width=350, max_width=420)

    # ------------------------------------------------------------------ what everything uses
    def plan(self) -> CapturePlan:
        """The plan the controls describe (the model's)."""
        return self.model.plan

    @property
    def calibration(self) -> CaptureCalibration | None:
        """The calibration chosen (None: uncalibrated)."""
        return self.model.calibration

    def capture_calibration(self) -> CaptureCalibration:
        """What recordings, the live view and the projector window use (uncalibrated when none was chosen)."""
        return self.model.capture_calibration

    def set_tile(self, tile: tuple[int, int]) -> None:
        """Choose a tile offered in the list."""
        self.code.set_tile(tile)

    def _plan_changed(self) -> None:
        self.projector.patterns_changed()
        self._update_buttons()
        self.recheck_refusals(settings_changed=True)

    def _calibration_changed(self, calibration) -> None:
        self.live_panel.restart()  # the projector shows the new patterns
        self.projector.patterns_changed()
        self.calibration_changed.emit(calibration)
        self.recheck_refusals(settings_changed=True)

    def _on_devices(self, _role: str) -> None:
        self.model.refresh()  # who holds the rig may have changed; refusals that said it was held may go

    def recheck_refusals(self, *, settings_changed: bool = False) -> None:
        """Take refusals off the screen that no longer hold (the rig is free again; the plan or calibration they
        were about changed)."""
        self.model.recheck(settings_changed=settings_changed)

    def _update_buttons(self) -> None:
        ok = self.plan().timing().ok
        recording = self.model.recording
        self.live_panel.live_button.setEnabled((ok and not recording) or self.live_panel.running)
        self.record_panel.update_buttons(ok)
        self.code.set_locked(recording)
        self.calibration_panel.set_locked(recording)

    # ------------------------------------------------------------------ calibration
    def load_calibration(self, path) -> bool:
        """Use the calibration file at ``path``; False (with the reason shown, the previous one kept) when refused
        (also while a recording runs)."""
        return self.calibration_panel.load_calibration(path)

    def load_sync_profile(self, path) -> bool:
        """Use a sync profile's phase and trigger delay; False (with the reason shown) when refused."""
        return self.calibration_panel.load_sync_profile(path)

    def use_outcome(self, outcome, saved_path=None) -> bool:
        """Use the Calibrate workspace's result; False (with the reason shown) when refused.

        A result saved to ``saved_path`` is used as that file (named by its path and content hash, and
        restored at the next start); one not saved, as the run.
        """
        if saved_path is not None:
            return self.load_calibration(saved_path)
        run = None if outcome is None else outcome.run
        identity = None if outcome is None else outcome.identity
        return self.calibration_panel.use_run(run, identity, outcome=outcome)

    def outcome_saved(self, outcome, path) -> bool:
        """The Calibrate workspace saved ``outcome`` to ``path``: when recordings use that run, they now use the
        file (its path and content hash). True when Capture switched to the file."""
        if self.calibration_panel.file_in_use is not None and path is not None and \
                Path(path).expanduser().resolve() == self.calibration_panel.file_in_use:
            self.calibration_panel.check_file()  # saved over the file in use: said at once, the new one offered
        if outcome is None or self.calibration_panel.run_outcome is not outcome or self.model.recording:
            return False
        return self.calibration_panel.load_calibration(path)

    def clear_calibration(self) -> bool:
        """Record uncalibrated (identity homography, phase 0, no trigger delay); False (with the reason shown) while
        a recording runs."""
        return self.calibration_panel.clear()

    @property
    def calibration_error(self) -> str:
        """Why the last calibration offered was refused ("" when it was taken)."""
        return self.calibration_panel.error

    # ------------------------------------------------------------------ live view and recording
    @property
    def live(self) -> bool:
        """True while the live view runs."""
        return self.live_panel.running

    @property
    def holder(self) -> Holder:
        """Who holds the devices now (the model's)."""
        return self.model.holder

    def start_live(self) -> bool:
        """Start the live view; False (with the reason shown) when it cannot start."""
        return self.live_panel.start()

    def stop_live(self) -> None:
        """Stop the live view (devices stay connected)."""
        self.live_panel.stop()

    @property
    def recording(self) -> bool:
        """True from Record until the capture has ended."""
        return self.model.recording

    @property
    def capture(self):
        """The running (or last) capture service, None before the first recording."""
        return self.record_panel.capture

    @property
    def last_result(self):
        """How the last recording ended."""
        return self.record_panel.last_result

    def record(self) -> bool:
        """Start recording; False (with the reason shown) when it cannot start."""
        return self.record_panel.record()

    def stop_recording(self) -> None:
        """Stop the recording early (it keeps every frame captured)."""
        self.record_panel.stop()

    def _confirm_record(self, plan) -> bool:
        return self.calibration_panel.confirm_record(plan, self)

    def _recording_ended(self, result) -> None:
        self.live_panel.end_capture()
        self.recording_finished.emit(result)

    def closing_losses(self) -> list[str]:
        """What closing the window would stop now: a recording (its frames so far are kept)."""
        capture = self.capture
        if not self.recording or capture is None:
            return []
        written = capture.stats().rows_written
        return [f"the recording to {capture.path} stops ({written} frames written so far are kept; it ends "
                "“stopped”, not after the frames asked for)"]

    def shutdown(self) -> None:
        """Stop the live view and any recording (window closing: waits, bounded, for the recording to end)."""
        self.projector.close_window()
        if not self.live_panel.shutdown():
            _logger.error("the live preview did not stop within 5 s")
        self.record_panel.shutdown()
