"""The operator's whole session, played through the window's buttons on the simulated rig.

One script, two users: the session test (``tests/app/gui/test_operator_session.py``) plays it and checks
what an operator would check after each step, and ``make screenshots`` (:mod:`flexvox_app.gui.screenshots`)
plays it and photographs the window at the same steps, so the README's pictures show what the test
checked. The steps: connect the devices, calibrate, the sync wizard, save, use for capture, choose the
code, live view with its preview, record, open in Review, diffusion, motion-aware, the continuum slider,
the motion overlay, compare, export, cancel, quit.

:func:`outside_view`, :func:`clipped` and :func:`too_wide` are the checks: a primary action must lie inside
the window and inside the visible part of any scroll area around it; a label's text must fit its label; a
column's contents must fit its width.

File dialogs are not opened: the steps type the path into the field the dialog fills (a test cannot
answer a native dialog), and export takes its path as the dialog would return it.
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

from PySide6.QtCore import QPoint, QRect
from PySide6.QtWidgets import QAbstractButton, QApplication, QComboBox, QLabel, QScrollArea, QWidget, QWizard

from flexvox_app.gui.widgets.elided_label import ElidedLabel
from flexvox_app.gui.widgets.questions import answering

_logger = logging.getLogger(__name__)

SIZE = (1280, 800)
"""The window's size for the session (a laptop's screen)."""


class SessionError(RuntimeError):
    """A step of the session did not reach its end (the message says which and why)."""


# ---------------------------------------------------------------------- checks
def outside_view(window: QWidget, widgets) -> list[str]:
    """The widgets of ``widgets`` an operator cannot see without scrolling or resizing: hidden, outside the
    window, or outside the visible part of a scroll area that holds them. Returns their descriptions."""
    bad = []
    win = window.rect()
    for w in widgets:
        name = _describe(w)
        if not w.isVisible():
            bad.append(f"{name}: hidden")
            continue
        rect = QRect(w.mapTo(window, QPoint(0, 0)), w.size())
        if not win.contains(rect):
            bad.append(f"{name}: outside the window ({rect.getRect()} not in {win.getRect()})")
            continue
        parent = w.parentWidget()
        while parent is not None and parent is not window:
            if isinstance(parent, QScrollArea):
                port = parent.viewport()
                seen = QRect(port.mapTo(window, QPoint(0, 0)), port.size())
                if not seen.contains(rect):
                    bad.append(f"{name}: scrolled out of view")
                    break
            parent = parent.parentWidget()
    return bad


def clipped(widgets) -> list[str]:
    """The labels and combo boxes of ``widgets`` whose text does not fit them (descriptions).

    A one-line label needs ``fontMetrics().horizontalAdvance(text)`` (its size hint for rich text) within
    its width; a word-wrapped one its height for its width; an elided label (by design) is not checked;
    a combo box needs its current text within its width less the arrow.
    """
    bad = []
    for w in widgets:
        if not w.isVisible() or isinstance(w, ElidedLabel):
            continue
        if isinstance(w, QComboBox):
            need = w.fontMetrics().horizontalAdvance(w.currentText()) + 30
            if need > w.width():
                bad.append(f"{_describe(w)}: {w.currentText()!r} needs {need} px, has {w.width()}")
        elif isinstance(w, QLabel) and w.text():
            if w.wordWrap():
                need = w.heightForWidth(w.width())
                if need > w.height():
                    bad.append(f"{_describe(w)}: needs {need} px of height, has {w.height()}")
            else:
                need = max(w.fontMetrics().horizontalAdvance(w.text()) if w.textFormat().name == "PlainText"
                           else 0, w.minimumSizeHint().width())
                if need > w.width():
                    bad.append(f"{_describe(w)}: needs {need} px of width, has {w.width()}")
    return bad


def too_wide(areas) -> list[str]:
    """The scroll areas of ``areas`` whose contents are wider than their view (cut off at the right: their
    horizontal scroll bars are off). Returns their descriptions."""
    bad = []
    for area in areas:
        inner, port = area.widget().width(), area.viewport().width()
        if area.isVisible() and inner > port:
            bad.append(f"{_describe(area)}: contents {inner} px wide in a view of {port} px")
    return bad


def _describe(w: QWidget) -> str:
    text = w.text() if isinstance(w, QAbstractButton | QLabel) else ""
    return f"{type(w).__name__} {text[:40]!r}" if text else type(w).__name__


def flexvox_threads() -> list[str]:
    """Names of flexvox's own Python threads still alive (capture reader and writer, rig work), but for the
    process's per-item pool (:data:`flexvox_core.threads.POOL_THREAD_PREFIX`), whose threads are kept, idle, for the
    next ``for_each`` and hold no work between calls."""
    from flexvox_core.threads import POOL_THREAD_PREFIX

    return [t.name for t in threading.enumerate()
            if t.name.startswith("flexvox") and not t.name.startswith(POOL_THREAD_PREFIX) and t.is_alive()]


# ---------------------------------------------------------------------- the session
class OperatorSession:
    """The steps of the operator's session on ``window`` (a :class:`~flexvox_app.gui.main_window.MainWindow`).

    Parameters
    ----------
    window : MainWindow
    workdir : path
        Where the calibration, sync profile, recording and export are written.
    shot : callable, optional
        ``shot(name)`` after the steps the README shows (``make screenshots`` saves the window there).
    """

    def __init__(self, window, workdir, *, shot=None):
        self.window = window
        self.workdir = Path(workdir)
        self.shot = shot or (lambda name: None)
        self.app = QApplication.instance()
        self.recording_path: Path | None = None
        self.cancelling_text = ""
        """What the result line said right after Cancel."""
        self.projector_questions: list = []
        """The questions asked before the patterns went full-screen."""

    # ------------------------------------------------------------------ helpers
    def wait(self, condition, timeout_s: float = 60.0, what: str = "") -> None:
        """Process events until ``condition()`` holds; :class:`SessionError` after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise SessionError(f"{what or 'a step'} did not end within {timeout_s:g} s")
            self.app.processEvents()
            time.sleep(0.01)

    def settle(self, rounds: int = 5) -> None:
        """Let queued events and layouts run (before a check or a picture)."""
        for _ in range(rounds):
            self.app.processEvents()
            time.sleep(0.01)

    def click(self, button: QAbstractButton) -> None:
        """Click ``button`` as the operator would; :class:`SessionError` when it is disabled or hidden."""
        if not (button.isEnabled() and button.isVisible()):
            state = "disabled" if button.isVisible() else "hidden"
            raise SessionError(f"cannot click {button.text()!r}: it is {state}")
        button.click()

    # ------------------------------------------------------------------ Devices and Calibrate
    def connect_devices(self) -> None:
        """Connect every device from the Devices panel."""
        panel = self.window.devices
        for role, row in panel.rows.items():
            if row["button"].isEnabled() and row["button"].text() == "Connect":
                self.click(row["button"])
                self.settle(1)
                _logger.info("connected %s: %s", role, panel.state_text(role))

    def calibrate(self) -> None:
        """Run the whole calibration from the Calibrate workspace."""
        self.window.show_workspace("Calibrate")
        cal = self.window.calibrate
        self.click(cal.run_button)
        self.wait(lambda: not cal.running, 120, "the calibration")
        if cal.outcome is None or not cal.outcome.success:
            raise SessionError(f"the calibration failed: {cal.step_label.text()}")
        self.settle()
        self.shot("calibrate.png")
        for index, name in ((1, "calibrate_residuals.png"), (3, "calibrate_sync.png")):
            cal.results_view.setCurrentIndex(index)
            self.settle()
            self.shot(name)
        cal.results_view.setCurrentIndex(0)

    def colocation_live(self) -> None:
        """Tick co-location live, wait for a measurement, untick it."""
        live = self.window.calibrate.live_panel
        self.click(live.check)
        self.wait(lambda: live.colocation is not None, 60, "co-location live")
        self.settle()
        self.shot("calibrate_colocation.png")
        self.click(live.check)
        self.wait(lambda: not live.measuring, 30, "co-location live stopping")
        self.window.calibrate.results_view.setCurrentIndex(0)

    def sync_wizard(self):
        """Walk the synchronisation wizard: wiring, trigger test, phase sweep, drops and drift, save. Returns the
        wizard's page verdicts ``{page: text}`` (the wizard is closed)."""
        cal = self.window.calibrate
        self.click(cal.wizard_button)
        wizard = cal.wizard
        for box in wizard.wiring.boxes:
            box.setChecked(True)
        verdicts = {}
        for page in (wizard.trigger, wizard.phase, wizard.drift):
            self.click(wizard.button(QWizard.WizardButton.NextButton))
            self.click(page.button)
            self.wait(lambda p=page: p.job is not None and not p.job.running, 60, page.title())
            verdicts[page.title()] = page.verdict.text()
            if not page.isComplete():
                raise SessionError(f"{page.title()}: {page.verdict.text()}")
        self.click(wizard.button(QWizard.WizardButton.NextButton))
        wizard.save_page.path.setText(str(self.workdir / "sync-profile.json"))
        self.click(wizard.save_page.button)
        verdicts["Save"] = wizard.save_page.label.text()
        if wizard.save_page.written is None:
            raise SessionError(f"the sync profile was not saved: {verdicts['Save']}")
        self.click(wizard.button(QWizard.WizardButton.FinishButton))
        self.settle()
        return verdicts

    def save_calibration(self) -> Path:
        """Type the calibration's path and Save."""
        panel = self.window.calibrate.save_panel
        panel.path.setText(str(self.workdir / "rig-calibration.json"))
        self.click(panel.save_button)
        if panel.saved_path is None:
            raise SessionError(f"the calibration was not saved: {panel.label.text()}")
        return panel.saved_path

    def use_for_capture(self) -> None:
        """Hand the calibration to Capture ("Use for capture"); the window shows Capture."""
        self.click(self.window.calibrate.save_panel.use_button)
        if self.window.capture.calibration is None:
            raise SessionError(f"Capture refused the calibration: {self.window.capture.calibration_error}")

    # ------------------------------------------------------------------ Capture
    def choose_code(self, tile=(4, 4)) -> None:
        """Pick the tile's designed identity code in the Shutter code box."""
        code = self.window.capture.code
        code.tile_box.setCurrentIndex(code.tile_box.findData(f"{tile[0]}x{tile[1]}"))
        self.click(code.identity)

    def live_view(self, *, frames: int = 8, previews: int = 1) -> None:
        """Start live view (with the motion-aware preview) and wait for frames and previews."""
        self.window.show_workspace("Capture")
        live = self.window.capture.live_panel
        live.preview_check.setChecked(True)
        self.click(live.live_button)
        self.wait(lambda: live.stats.received >= frames and live.preview.runs >= previews, 60, "the live view")
        self.settle()
        self.shot("capture.png")

    def record(self, frames: int) -> Path:
        """Type a path and a frame count, Record, and wait for the end (the live view stops for it)."""
        capture = self.window.capture
        panel = capture.record_panel
        self.recording_path = self.workdir / "session.zarr"
        panel.path_edit.setText(str(self.recording_path))
        panel.frames_box.setValue(frames)
        self.click(panel.record_button)
        self.wait(lambda: capture.recording, 10, "the recording's start")
        self.wait(lambda: not capture.recording, 120, "the recording")
        result = capture.last_result
        if result is None or not result.ok:
            raise SessionError(f"the recording failed: {panel.recording_label.text()}")
        self.settle()
        self.shot("capture_recording.png")
        return self.recording_path

    def projector_window(self):
        """Show the patterns full-screen (on the only screen, answering the question that comes first); returns the
        window while it was open."""
        projector = self.window.capture.projector
        self.window.capture.controls_scroll.ensureWidgetVisible(projector)  # the operator scrolls down to it
        with answering(True) as self.projector_questions:
            self.click(projector.button)
        self.wait(lambda: projector.window is not None, 30, "the projector window")
        self.settle()
        self.shot("capture_projector.png")
        return projector.window

    def close_projector_window(self) -> None:
        """Close the projector output window."""
        self.click(self.window.capture.projector.button)

    # ------------------------------------------------------------------ Review
    def open_in_review(self) -> None:
        """"Open in Review" after the recording."""
        review = self.window.review
        self.click(self.window.capture.record_panel.review_button)
        self.wait(lambda: review.session is not None and review.session.path == self.recording_path, 30,
                  "opening the recording")

    def reconstruct(self, method: str, position: float | None = None):
        """Pick ``method`` (and the slider's position), Reconstruct all frames, wait for the result."""
        review = self.window.review
        review.form.set_method_name(method)
        if position is not None:
            review.form.set_position(position)
        n = len(review.results)
        self.click(review.reconstruct_button)
        job = review.job
        self.wait(lambda: len(review.results) > n or not job.running, 180, f"the {method} reconstruction")
        if len(review.results) == n:
            raise SessionError(f"the {method} reconstruction failed: {review.result_label.text()}")
        return review.results[-1]

    def go_to(self, subframe: int) -> None:
        """Move the player to ``subframe`` and wait for the preview there."""
        review = self.window.review
        review.frame_slider.setValue(subframe)
        self.wait_preview()

    def wait_preview(self) -> None:
        """Wait until no preview is pending or running."""
        review = self.window.review
        self.wait(lambda: not review.preview_timer.isActive()
                  and (review.preview_job is None or not review.preview_job.running), 60, "the preview")
        self.settle()

    def slide(self, position: float):
        """Move the continuum slider and wait for its preview; returns the preview (beside the chosen method's
        result when there is one)."""
        review = self.window.review
        review.form.set_position(position)
        self.wait_preview()
        return review.comparison or review.shown

    def motion_overlay(self, mode: str = "color") -> None:
        """Show the Motion tab, as colour wheel or quiver."""
        review = self.window.review
        review.tabs.setCurrentWidget(review.motion_view)
        self.click(review.motion_view.color if mode == "color" else review.motion_view.quiver)
        self.settle()

    def frames_tab(self) -> None:
        """Show the Frames tab."""
        review = self.window.review
        review.tabs.setCurrentIndex(0)
        self.settle()

    def compare(self) -> None:
        """Show the Compare tab (the two newest results)."""
        review = self.window.review
        review.tabs.setCurrentWidget(review.compare_view)
        self.settle()

    def export(self, name: str = "export.zarr"):
        """Export what is shown to ``workdir/name`` (the path the file dialog would return); returns
        ``(path, result written)``."""
        review = self.window.review
        path = self.workdir / name
        before = review.exported
        handle = review.export(path, overwrite=True)
        if handle is None:
            raise SessionError(f"not exported: {review.export_label.text()}")
        self.wait(lambda: not handle.running, 180, "the export")
        if review.exported is before:
            raise SessionError(f"not exported: {review.export_label.text()}")
        return review.exported

    def cancel(self, method: str = "motion-aware"):
        """Start a reconstruction and Cancel it at once; returns the cancelled job's handle."""
        review = self.window.review
        review.form.set_method_name(method)
        self.click(review.reconstruct_button)
        job = review.job
        self.click(review.cancel_button)
        self.cancelling_text = review.result_label.text()
        self.wait(lambda: job is None or not job.running, 60, "the cancel")
        self.settle()
        return job

    def quit(self, answer: bool = True) -> list:
        """File ▸ Quit, answering ``answer`` when the window asks first (it names what would be lost); returns the
        questions asked."""
        quit_action = next(a for a in self.window.menuBar().actions()[0].menu().actions() if "Quit" in a.text())
        with answering(answer) as asked:
            quit_action.trigger()
        self.settle()
        return asked
