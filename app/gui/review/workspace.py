"""The Review workspace: open a recording, play it, reconstruct, preview, compare and export.

The widget shows a :class:`~flexvox_app.gui.models.review_model.ReviewModel` (Qt-free: the recording open, and its
parts: playback, preview scheduling, the jobs and the export), connected to each part's signals, and forwards the
operator's actions to the part they concern. It keeps what needs Qt:
the controls and the views, the file dialogs and the questions, the playback timer and the short wait that
gathers knob changes into one preview, and the method form, whose choices it hands to the model.
"""

from __future__ import annotations

import html
import re
from pathlib import Path

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSlider,
    QSpinBox,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.models.device_words import short_where
from flexvox_app.gui.models.expected_quality import format_seconds
from flexvox_app.gui.models.jobs import ReconstructionResult
from flexvox_app.gui.models.machine_speed import SpeedModel
from flexvox_app.gui.models.review_model import Line, ReviewModel
from flexvox_app.gui.models.review_session import ReviewSession, not_a_recording
from flexvox_app.gui.review.compare_view import CompareView
from flexvox_app.gui.review.method_form import MethodForm
from flexvox_app.gui.review.motion_view import MotionView
from flexvox_app.gui.widgets.adaptive_split import AdaptiveSplit
from flexvox_app.gui.widgets.image_panel import ImagePanel
from flexvox_app.gui.widgets.qt_jobs import JobHandle, JobRunner
from flexvox_app.gui.widgets.questions import ask, replace_question
from flexvox_app.gui.widgets.rich_text import RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine
from flexvox_app.gui.widgets.workspace_layout import controls_beside_view


def export_slug(method) -> str:
    """A file-name fragment naming the method and its options, e.g. ``diffusion-tensor-0.05-0.05-1-n-5``."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "-", method.label()).strip("-")


EXPORT_FILTER = "TIFF stack (*.tif);;MP4 video, 8-bit (*.mp4);;NumPy array (*.npy);;Zarr folder (*.zarr)"
PREVIEW_DELAY_MS = 250
"""Knob changes within this time make one preview, not many."""


def rich(line: Line) -> str:
    """A model's line as a status line's rich text: red when it says something failed."""
    return coloured(line.text, RED) if line.error else html.escape(line.text, quote=False)


class ReviewWorkspace(QWidget):
    """Post-capture review.

    Parameters
    ----------
    settings : AppSettings
    runner : JobRunner
        Runs loading, reconstructions, previews and exports off the GUI thread.
    quality_table : dict or None
        The shipped bench figures (:func:`flexvox_app.gui.models.expected_quality.load_table`).

    Attributes
    ----------
    model : ReviewModel
        What the workspace shows.
    """

    session_opened = Signal(object)
    result_added = Signal(object)
    status = Signal(str)

    def __init__(self, settings: AppSettings, runner: JobRunner, quality_table: dict | None,
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.settings = settings
        self.runner = runner
        self.table = quality_table
        self.model = ReviewModel(runner, settings, quality_table)
        self._levels = None
        self._build()
        self.form.changed.connect(self._on_form_changed)
        m = self.model
        p, j = m.playback, m.jobs
        m.path_changed.connect(lambda line: self.path_label.setText(rich(line)))
        m.opened.connect(self._opened)
        m.status.connect(self.status.emit)
        p.frame_changed.connect(self._show_frame)
        p.shown_changed.connect(self._show_shown)
        p.comparison_changed.connect(self._show_comparison)
        p.playing_changed.connect(self._show_playing)
        p.speed_changed.connect(self._speed_changed)
        m.preview.preview_wanted.connect(self.preview_timer.start)
        j.result_changed.connect(lambda line: self.result_label.setText(rich(line)))
        j.export_changed.connect(lambda line: self.export_label.setText(rich(line)))
        j.progress_changed.connect(self._show_progress)
        j.expected_changed.connect(self._refresh_expected)
        j.jobs_changed.connect(self._refresh_enabled)
        j.result_added.connect(self._result_added)
        j.estimate_changed.connect(lambda result: self.compare_view.update_labels())
        self._refresh_enabled()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        rec = QGroupBox("Recording")
        self.open_button = QPushButton("Open recording…")
        self.path_label = StatusLine("no recording open", lines=1)
        self.path_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.summary_label = StatusLine(lines=3)
        v = QVBoxLayout(rec)
        v.addWidget(self.open_button)
        v.addWidget(self.path_label)
        v.addWidget(self.summary_label)

        box = QGroupBox("Reconstruction")
        self.form = MethodForm(self.settings, offer_auto=True)
        self.preview_check = QCheckBox("live preview around the current frame")
        self.preview_check.setChecked(self.model.preview.preview_on)
        self.expected_label = StatusLine(lines=3)
        self.reconstruct_button = QPushButton("Reconstruct")
        self.cancel_button = QPushButton("Cancel")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.result_label = StatusLine(lines=3)  # an estimate (recordings without ground truth) adds a line
        buttons = QHBoxLayout()
        buttons.addWidget(self.reconstruct_button, 1)
        buttons.addWidget(self.cancel_button)
        self.export_button = QPushButton("Export shown reconstruction…")
        self.export_label = StatusLine(lines=2)
        v = QVBoxLayout(box)
        v.addWidget(self.form)
        v.addWidget(self.expected_label)
        v.addLayout(buttons)
        v.addWidget(self.progress)
        v.addWidget(self.result_label)
        v.addWidget(self.export_button)
        v.addWidget(self.export_label)
        details = QWidget()
        dv = QVBoxLayout(details)
        dv.setContentsMargins(0, 0, 0, 0)
        dv.addWidget(self.preview_check)
        dv.addWidget(self.form.options)

        self.raw_panel = ImagePanel("raw camera frame")
        self.recon_panel = ImagePanel("reconstruction")
        self.slider_panel = ImagePanel("slider preview")
        """The slider's fixed-tensor preview beside the chosen method's result (shown only then)."""
        self.slider_panel.hide()
        frames = AdaptiveSplit(self.raw_panel, self.recon_panel, self.slider_panel)  # stacked in a narrow view
        self.motion_view = MotionView()
        self.compare_view = CompareView()
        self.tabs = QTabWidget()
        self.tabs.addTab(frames, "Frames")
        self.tabs.addTab(self.motion_view, "Motion")
        self.tabs.addTab(self.compare_view, "Compare")

        self.play_button = QPushButton("Play")
        self.play_button.setCheckable(True)
        self.frame_slider = QSlider(Qt.Orientation.Horizontal)
        self.frame_slider.setRange(0, 0)
        self.frame_label = QLabel("")
        self.fps = QSpinBox()
        self.fps.setRange(1, 10_000)
        self.fps.setValue(self.model.playback.fps)
        self.fps.setSuffix(" sub-frames/s")
        self.fps.setToolTip("playback speed in sub-frames per second (a camera frame is K sub-frames; raw frames "
                            "advance a whole frame at a time)")
        self.real_time = QCheckBox("real time")
        self.real_time.setToolTip("play at the recording's own speed: its sub-frame rate (camera rate × K)")
        self.real_time.setChecked(self.model.playback.real_time)
        # The scrubber has the view's whole width, whatever the window's; Play, the position and the speed sit under it.
        player = QHBoxLayout()
        player.addWidget(self.play_button)
        player.addWidget(self.frame_label, 1)
        speed = QHBoxLayout()
        speed.addWidget(QLabel("speed"))
        speed.addWidget(self.fps)
        speed.addWidget(self.real_time)
        speed.addStretch(1)
        right = QWidget()
        rv = QVBoxLayout(right)
        rv.addWidget(self.tabs, 1)
        rv.addWidget(self.frame_slider)
        rv.addLayout(player)
        rv.addLayout(speed)

        # Open, Reconstruct, Cancel and Export stay in view; the method's knobs fold below them.
        self.controls_scroll = controls_beside_view(self, (details,), right, actions=(rec, box), min_width=330,
                                                    max_width=400)

        self.timer = QTimer(self)
        self.timer.timeout.connect(self.model.playback.tick)
        self.preview_timer = QTimer(self)
        self.preview_timer.setSingleShot(True)
        self.preview_timer.setInterval(PREVIEW_DELAY_MS)
        self.preview_timer.timeout.connect(self.request_preview)

        self.open_button.clicked.connect(self._ask_open)
        self.reconstruct_button.clicked.connect(self.reconstruct)
        self.cancel_button.clicked.connect(self.cancel)
        self.export_button.clicked.connect(self._ask_export)
        self.play_button.toggled.connect(self.set_playing)
        self.frame_slider.valueChanged.connect(self.model.playback.set_subframe)
        self.fps.valueChanged.connect(self.model.playback.set_fps)
        self.real_time.toggled.connect(self._on_real_time)
        self.fps.setEnabled(not self.real_time.isChecked())
        self.preview_check.toggled.connect(self.model.preview.set_preview_on)
        self.raw_panel.clear("open a recording (File ▸ Open, or flexvox app REC.zarr)")
        self.recon_panel.clear("")

    # ------------------------------------------------------------------ what the model holds
    @property
    def session(self) -> ReviewSession | None:
        """The recording open (None before one is)."""
        return self.model.session

    @property
    def results(self) -> list[ReconstructionResult]:
        """The full reconstructions, oldest first."""
        return self.model.jobs.results

    @property
    def shown(self) -> ReconstructionResult | None:
        """What the reconstruction panel shows: a full result or a preview."""
        return self.model.playback.shown

    @property
    def comparison(self) -> ReconstructionResult | None:
        """The slider's preview shown beside :attr:`shown`, or None."""
        return self.model.playback.comparison

    @property
    def exported(self) -> tuple[Path, ReconstructionResult] | None:
        """The last export: its path and the full result written."""
        return self.model.jobs.exported

    @property
    def job(self) -> JobHandle | None:
        """The full reconstruction (or the export reconstructing one) running or last run."""
        return self.model.jobs.job

    @property
    def preview_job(self) -> JobHandle | None:
        """The preview running or last run."""
        return self.model.preview.preview_job

    @property
    def busy(self) -> bool:
        """True while a full reconstruction runs."""
        return self.model.jobs.busy

    @property
    def subframe(self) -> int:
        """The current sub-frame index s (camera frame s // K)."""
        return self.model.playback.subframe

    @property
    def playing(self) -> bool:
        """True while playback runs."""
        return self.model.playback.playing

    def speed(self) -> float:
        """Playback speed in sub-frames per second (the playback's
        :meth:`~flexvox_app.gui.models.review_playback.PlaybackModel.speed`)."""
        return self.model.playback.speed()

    def full_result_of(self, method) -> ReconstructionResult | None:
        """The newest full reconstruction made with exactly ``method`` (None: none yet)."""
        return self.model.jobs.full_result_of(method)

    def flow_result(self) -> ReconstructionResult | None:
        """The result whose flow and TR map the Motion tab shows (the jobs'
        :meth:`~flexvox_app.gui.models.review_jobs.JobsModel.flow_result`)."""
        return self.model.jobs.flow_result()

    def export_candidate(self) -> ReconstructionResult | None:
        """What an export writes: the result shown, else the newest full result."""
        return self.model.jobs.export_candidate()

    def speed_model(self, name: str, K: int) -> SpeedModel | None:
        """This machine's calibrated speed of method ``name`` at K slots (None: not measured by this version)."""
        return self.model.jobs.speed_model(name, K)

    def expected_seconds(self) -> float | None:
        """Expected seconds of a full reconstruction with the form's method on this machine (None: not known yet)."""
        return self.model.jobs.expected_seconds(self.form.method())

    def closing_losses(self) -> list[str]:
        """What closing the window would stop or lose now (the jobs'
        :meth:`~flexvox_app.gui.models.review_jobs.JobsModel.closing_losses`)."""
        return self.model.jobs.closing_losses()

    # ------------------------------------------------------------------ the operator's actions
    def _ask_open(self) -> None:
        start = self.settings.last_folder("review/last_dir")
        path = QFileDialog.getExistingDirectory(self, "Open a recording (.zarr folder)", start)
        if path:
            self.open_recording(path)

    def open_recording(self, path) -> JobHandle | None:
        """Open ``path`` off the GUI thread; ``session_opened`` fires when it is ready. When opening it would stop
        a reconstruction or lose results not exported, ask first, naming them, as closing the window does; None
        when the operator keeps working, or when ``path`` is plainly no recording (refused before any question)."""
        name = Path(path).name
        refusal = not_a_recording(path)
        if refusal is not None:
            self.model.open_refused(path, refusal)
            return None
        losses = self.model.jobs.closing_losses()
        if losses and not ask(self, f"Open {name}?", f"Opening {name} now:\n\n" + "\n".join(
                f"• {line}" for line in losses) + f"\n\nOpen {name} anyway?", accept=f"Open {name}",
                reject="Keep working"):
            self.model.status.emit(f"{name} not opened: {self.model.session.path.name} stays open"
                                   if self.model.session is not None else f"{name} not opened")
            return None
        return self.model.open(path)

    def set_playing(self, playing: bool) -> None:
        """Start or stop playback."""
        self.model.playback.set_playing(playing)

    def _on_real_time(self, on: bool) -> None:
        self.fps.setEnabled(not on)
        self.model.playback.set_real_time(on)

    def _on_form_changed(self) -> None:
        self.form.set_beside(self.model.jobs.full_result_of(self.form.method()) is not None)
        self._refresh_expected()
        self._refresh_enabled()
        self.model.preview.want_preview()

    def request_preview(self) -> JobHandle | None:
        """Recompute the form's settings on a small window of frames around the current one."""
        return self.model.preview.request_preview(self.form.preview_method(), self.form.method(), self.form.comparing)

    def reconstruct(self) -> JobHandle | None:
        """Reconstruct every frame with the form's settings (off-thread, cancellable)."""
        return self.model.jobs.reconstruct(self.form.method(), auto_knob=self.form.auto_knob())

    def cancel(self) -> None:
        """Cancel a running reconstruction (the preview is cancelled too); it stops after its current chunk."""
        self.model.cancel()

    def _ask_export(self) -> None:
        r = self.model.jobs.export_candidate()
        if r is None:
            return
        start = self.settings.last_folder("review/export_dir")
        name = str(Path(start) / f"{self.session.path.stem}-{export_slug(r.method)}.tif")
        path, _ = QFileDialog.getSaveFileName(self, "Export the reconstruction", name, EXPORT_FILTER,
                                              options=QFileDialog.Option.DontConfirmOverwrite)  # export asks
        if path:
            self.export(path)

    def export(self, path, *, overwrite: bool | None = None) -> JobHandle | None:
        """Write what the panel shows, over every frame, to ``path`` (the jobs'
        :meth:`~flexvox_app.gui.models.review_jobs.JobsModel.export`); an existing
        ``path`` is replaced when ``overwrite`` is True, kept when it is False, and otherwise when the operator
        says so (the question names it)."""
        return self.model.jobs.export(path, overwrite=overwrite, ask=lambda p: replace_question(self, p, "export"))

    def shutdown(self) -> None:
        """The window closes: stop playback and the preview timer for good, and cancel the jobs.

        After this no timer restarts and no job is submitted (the job runner shuts down next)."""
        self.timer.stop()
        self.preview_timer.stop()
        self.model.shutdown()
        self.preview_timer.stop()

    # ------------------------------------------------------------------ showing the model
    def _show_progress(self, done: int, total: int) -> None:
        self.progress.setRange(0, total)
        self.progress.setValue(done)

    def _show_frame(self, s: int) -> None:
        self.frame_slider.blockSignals(True)
        self.frame_slider.setValue(s)
        self.frame_slider.blockSignals(False)
        self._show(s)

    def _show_shown(self, result: ReconstructionResult | None) -> None:
        p = self.model.playback
        if p.session is not None:
            self.motion_view.set_result(self.model.jobs.flow_result(), p.session.K, shown=result)
            self._show(p.subframe)
        self._refresh_enabled()

    def _show_comparison(self, result: ReconstructionResult | None) -> None:
        self.slider_panel.setVisible(result is not None)
        if result is None:
            self.slider_panel.clear("")
        elif self.model.session is not None:
            self._show(self.model.playback.subframe)

    def _speed_changed(self) -> None:
        p = self.model.playback
        if p.playing:
            self.timer.setInterval(p.interval_ms())

    def _show_session(self) -> None:
        session = self.model.session
        self.path_label.setText(rich(self.model.path_line))
        text = session.summary()
        if session.blocked:
            text += "<br>" + coloured(f"cannot reconstruct: {session.blocked}", RED)
        self.summary_label.setText(text)
        rate = self.model.playback.subframe_hz()
        self.real_time.setText(f"real time ({rate:.4g}/s)" if rate else "real time")
        self.real_time.setEnabled(rate is not None)
        self.form.set_divisions(session.divisions())
        self._levels = session.raw_levels()
        self.frame_slider.blockSignals(True)
        self.frame_slider.setRange(0, session.n_subframes - 1)
        self.frame_slider.setValue(self.model.playback.subframe)
        self.frame_slider.blockSignals(False)
        self.recon_panel.clear("")
        self.slider_panel.setVisible(False)
        self.slider_panel.clear("")
        self.motion_view.set_length(session.n_subframes)
        self.motion_view.set_result(None, session.K)
        self.compare_view.set_results([], session.K, self.model.jobs.truth)
        self._show(self.model.playback.subframe)
        self._refresh_expected()
        self._refresh_enabled()

    def _opened(self, session: ReviewSession) -> None:
        self._show_session()
        self.session_opened.emit(session)

    def _result_added(self, result: ReconstructionResult) -> None:
        j = self.model.jobs
        self.form.set_beside(j.full_result_of(self.form.method()) is not None)
        self.compare_view.set_results(j.results, self.model.session.K, j.truth)
        self.result_added.emit(result)

    def _show_playing(self, playing: bool) -> None:
        if self.play_button.isChecked() != playing:
            self.play_button.blockSignals(True)
            self.play_button.setChecked(playing)
            self.play_button.blockSignals(False)
        self.play_button.setText("Pause" if playing else "Play")
        if playing:
            self.timer.start(self.model.playback.interval_ms())
        else:
            self.timer.stop()

    def _show(self, s: int) -> None:
        m = self.model.playback
        if m.session is None:
            return
        session = m.session
        K = session.K
        f = s // K
        self.raw_panel.set_image(session.raw[f], levels=self._levels)
        self.raw_panel.set_title(f"raw camera frame {f + 1}/{session.n_frames} (all {K} slots in one exposure)")
        self.frame_label.setText(f"frame {f + 1}/{session.n_frames} · sub-frame {s + 1}/{session.n_subframes}")
        r = m.shown
        if m.covers(r, s):
            i = s - r.first_frame * K
            self.recon_panel.set_image(r.video[i], levels=(0, 1))
            kind = "preview" if r.extra.get("preview") else "reconstruction"
            self.recon_panel.set_title(f"{kind}: {r.method.label()} {short_where(r.device)} · sub-frame {s + 1}")
        elif r is not None:
            self.recon_panel.clear("outside the preview window: pause to recompute it here")
        c = m.comparison
        if m.covers(c, s):
            self.slider_panel.set_image(c.video[s - c.first_frame * K], levels=(0, 1))
            self.slider_panel.set_title(f"slider preview: {c.method.label()} {short_where(c.device)} · sub-frame "
                                        f"{s + 1}")
        elif c is not None:
            self.slider_panel.clear("outside the preview window: pause to recompute it here")
        self.motion_view.show_subframe(s)
        self.compare_view.show_subframe(s)

    def _refresh_expected(self) -> None:
        if self.model.session is None:
            self.expected_label.setText("open a recording to see the expected time and quality")
            return
        e, seconds = self.model.jobs.expected(self.form.method())
        time_text = "timing this machine …" if seconds is None else f"≈ {format_seconds(seconds)} on this machine"
        if e is None:
            self.expected_label.setText(f"<b>expected</b> {time_text}; no bench figures for the quality")
            self.expected_label.setToolTip("")
            return
        self.expected_label.setText(f"<b>expected</b> {time_text}, {e.quality_text()}<br><small>{e.basis}</small>")
        self.expected_label.setToolTip("time: this recording's size on this machine, from a calibration run of the "
                                       "method here (cached in the settings); quality: measured by the bench on the "
                                       "built-in scenes, not on this recording")

    def _refresh_enabled(self) -> None:
        m, j = self.model, self.model.jobs
        can = m.session is not None and m.session.frames is not None
        self.reconstruct_button.setEnabled(can and not j.busy)
        name = self.form.method().name
        self.reconstruct_button.setText(f"Reconstruct: {name}")
        self.reconstruct_button.setToolTip(f"reconstruct every frame of the recording with {name}")
        self.cancel_button.setEnabled(j.cancellable)
        self.export_button.setEnabled(j.export_candidate() is not None)
        self.play_button.setEnabled(m.session is not None)
        if m.session is None:
            self._refresh_expected()
