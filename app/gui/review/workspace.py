"""The Review workspace: open a recording, play it, reconstruct, preview, compare and export."""

from __future__ import annotations

import html
import logging
import re
import time
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

from app.gui.models.expected_quality import expected, format_seconds
from app.gui.models.jobs import ReconstructionResult, chunk_frames_for, preview_window, run_reconstruction
from app.gui.models.machine_speed import SpeedModel, calibrate, estimate_seconds, is_current, settings_key
from app.gui.models.operator_words import in_gui_words
from app.gui.models.review_session import ReviewSession
from app.gui.review.compare_view import CompareView
from app.gui.review.method_form import MethodForm
from app.gui.review.motion_view import MotionView
from app.gui.widgets.adaptive_split import AdaptiveSplit
from app.gui.widgets.image_panel import ImagePanel
from app.gui.widgets.qt_jobs import JobHandle, JobRunner
from app.gui.widgets.questions import replace_question
from app.gui.widgets.rich_text import RED, coloured
from app.gui.widgets.settings import AppSettings
from app.gui.widgets.status_line import StatusLine
from app.gui.widgets.workspace_layout import controls_beside_view
from flexvox_core.output_files import OutputError, check_output
from flexvox_core.video_io import write_video

_logger = logging.getLogger(__name__)

def export_slug(method) -> str:
    """A file-name fragment naming the method and its options, e.g. ``diffusion-tensor-0.05-0.05-1-n-5``."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "-", method.label()).strip("-")


MAX_DRAWS_HZ = 30
"""Playback draws at most this many pictures a second; faster speeds skip sub-frames between them."""


def playback_advance(elapsed_s: float, speed: float, step: int, carried: float = 0.0) -> tuple[int, float]:
    """Sub-frames to advance after ``elapsed_s`` at ``speed`` sub-frames/s, in whole ``step`` s, and the part
    carried to the next tick.

    Examples
    --------
    >>> playback_advance(1.0, 240.0, 16)   # real time at 15 Hz × 16: a second is 15 raw frames
    (240, 0.0)
    >>> playback_advance(0.05, 12.0, 1, 0.5)
    (1, 0.10000000000000009)
    """
    total = carried + max(0.0, elapsed_s) * speed
    n = int(total // step) * step
    return n, total - n


EXPORT_FILTER = "TIFF stack (*.tif);;MP4 video, 8-bit (*.mp4);;NumPy array (*.npy);;Zarr store (*.zarr)"
PREVIEW_DELAY_MS = 250
"""Knob changes within this time make one preview, not many."""


class ReviewWorkspace(QWidget):
    """Post-capture review.

    Parameters
    ----------
    settings : AppSettings
    runner : JobRunner
        Runs loading, reconstructions, previews and exports off the GUI thread.
    quality_table : dict or None
        The shipped bench figures (:func:`app.gui.models.expected_quality.load_table`).
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
        self.session: ReviewSession | None = None
        self.results: list[ReconstructionResult] = []
        self.shown: ReconstructionResult | None = None
        self.comparison: ReconstructionResult | None = None
        """The slider's preview shown beside :attr:`shown` (the chosen method's full result), or None."""
        self.exported: tuple[Path, ReconstructionResult] | None = None
        """The last export: its path and the full result written."""
        self._written: list[ReconstructionResult] = []
        """Every full result exported (the others are lost when the window closes)."""
        self.job: JobHandle | None = None
        self.preview_job: JobHandle | None = None
        self._preview_generation = 0
        self._truth = None
        self._expected_for_job: float | None = None
        self._closed = False
        self._last_tick, self._carried = 0.0, 0.0
        self._speed_jobs: dict[str, JobHandle] = {}
        self._build()
        self.form.changed.connect(self._on_form_changed)
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
        self.form = MethodForm(self.settings)
        self.preview_check = QCheckBox("live preview around the current frame")
        self.preview_check.setChecked(self.settings.get_bool("review/preview", True))
        self.expected_label = StatusLine(lines=3)
        self.reconstruct_button = QPushButton("Reconstruct")
        self.cancel_button = QPushButton("Cancel")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.result_label = StatusLine(lines=2)
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
        self.fps.setValue(self.settings.get_int("review/fps", 12))
        self.fps.setSuffix(" sub-frames/s")
        self.fps.setToolTip("playback speed in sub-frames per second (a camera frame is K sub-frames; raw frames "
                            "advance a whole frame at a time)")
        self.real_time = QCheckBox("real time")
        self.real_time.setToolTip("play at the recording's own speed: its sub-frame rate (camera rate × K)")
        self.real_time.setChecked(self.settings.get_bool("review/real_time", False))
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
        self.timer.timeout.connect(self._tick)
        self.preview_timer = QTimer(self)
        self.preview_timer.setSingleShot(True)
        self.preview_timer.setInterval(PREVIEW_DELAY_MS)
        self.preview_timer.timeout.connect(self.request_preview)

        self.open_button.clicked.connect(self._ask_open)
        self.reconstruct_button.clicked.connect(self.reconstruct)
        self.cancel_button.clicked.connect(self.cancel)
        self.export_button.clicked.connect(self._ask_export)
        self.play_button.toggled.connect(self.set_playing)
        self.frame_slider.valueChanged.connect(self._on_frame)
        self.fps.valueChanged.connect(self._on_fps)
        self.real_time.toggled.connect(self._on_real_time)
        self.fps.setEnabled(not self.real_time.isChecked())
        self.preview_check.toggled.connect(self._on_preview_toggled)
        self.raw_panel.clear("open a recording (File ▸ Open, or flexvox app REC.zarr)")
        self.recon_panel.clear("")

    # ------------------------------------------------------------------ opening
    def _ask_open(self) -> None:
        start = self.settings.last_folder("review/last_dir")
        path = QFileDialog.getExistingDirectory(self, "Open a recording (.zarr folder)", start)
        if path:
            self.open_recording(path)

    def open_recording(self, path) -> JobHandle:
        """Open ``path`` off the GUI thread; ``session_opened`` fires when it is ready."""
        path = Path(path)
        self.path_label.setText(f"opening {path} …")
        return self.runner.submit("open", lambda token, progress: ReviewSession.open(path),
                                  on_finished=self._opened, on_failed=self._open_failed)

    def _open_failed(self, message: str) -> None:
        message = in_gui_words(message)
        self.path_label.setText(coloured(f"cannot open: {message}", RED))
        self.status.emit(f"cannot open: {message}")

    def _opened(self, session: ReviewSession) -> None:
        self.set_playing(False)
        self.cancel()
        self.session = session
        self.results = []
        self.shown = None
        self._set_comparison(None)
        self._written = []
        self._truth = session.truth() if session.has_ground_truth else None
        self.settings.remember_folder(session.path, "review/last_dir")
        self.settings.set("review/last_recording", str(session.path))
        self.path_label.setText(str(session.path))
        text = session.summary()
        if session.blocked:
            text += "<br>" + coloured(f"cannot reconstruct: {session.blocked}", RED)
        self.summary_label.setText(text)
        rate = self.subframe_hz()
        self.real_time.setText(f"real time ({rate:.4g}/s)" if rate else "real time")
        self.real_time.setEnabled(rate is not None)
        self.form.set_divisions(session.divisions())
        self._levels = session.raw_levels()
        self.frame_slider.blockSignals(True)
        self.frame_slider.setRange(0, session.n_subframes - 1)
        self.frame_slider.setValue(0)
        self.frame_slider.blockSignals(False)
        self.recon_panel.clear("")
        self.motion_view.set_length(session.n_subframes)
        self.motion_view.set_result(None, session.K)
        self.compare_view.set_results([], session.K, self._truth)
        self._show(0)
        self._refresh_expected()
        self._refresh_enabled()
        self.session_opened.emit(session)
        self.status.emit(f"opened {session.path.name}")
        self._schedule_preview()

    # ------------------------------------------------------------------ playback
    @property
    def subframe(self) -> int:
        """The current sub-frame index s (camera frame s // K)."""
        return self.frame_slider.value()

    def set_playing(self, playing: bool) -> None:
        """Start or stop playback."""
        playing = bool(playing) and self.session is not None
        if self.play_button.isChecked() != playing:
            self.play_button.blockSignals(True)
            self.play_button.setChecked(playing)
            self.play_button.blockSignals(False)
        self.play_button.setText("Pause" if playing else "Play")
        if playing:
            self._last_tick, self._carried = time.monotonic(), 0.0
            self.timer.start(self._interval_ms())
        else:
            self.timer.stop()
            self._schedule_preview()

    @property
    def playing(self) -> bool:
        """True while playback runs."""
        return self.timer.isActive()

    def _step(self) -> int:
        # Raw frames advance a whole frame; a shown reconstruction advances one sub-frame.
        return 1 if self.shown is not None else self.session.K

    def subframe_hz(self) -> float | None:
        """The recording's sub-frame rate (its real time), None when it does not say."""
        if self.session is None:
            return None
        rate = self.session.recording.attrs.get("rates", {}).get("subframe_hz")
        return float(rate) if rate else None

    def speed(self) -> float:
        """Playback speed in sub-frames per second: the recording's own rate in real time, else the speed box's."""
        rate = self.subframe_hz()
        return rate if self.real_time.isChecked() and rate else float(self.fps.value())

    def _interval_ms(self) -> int:
        """Time between two pictures: one step at the speed, but never more than :data:`MAX_DRAWS_HZ` a second."""
        return max(round(1000 / MAX_DRAWS_HZ), round(1000 * self._step() / self.speed()))

    def _tick(self, now: float | None = None) -> None:
        if self.session is None:
            return
        now = time.monotonic() if now is None else now
        n, self._carried = playback_advance(now - self._last_tick, self.speed(), self._step(), self._carried)
        self._last_tick = now
        if n:
            self.frame_slider.setValue((self.subframe + n) % self.session.n_subframes)

    def _on_fps(self, value: int) -> None:
        self.settings.set("review/fps", value)
        if self.timer.isActive():
            self.timer.setInterval(self._interval_ms())

    def _on_real_time(self, on: bool) -> None:
        self.settings.set("review/real_time", on)
        self.fps.setEnabled(not on)
        if self.timer.isActive():
            self.timer.setInterval(self._interval_ms())

    def _on_frame(self, s: int) -> None:
        self._show(s)
        if not self.playing and (not self._covers(self.shown, s)
                                 or self.comparison is not None and not self._covers(self.comparison, s)):
            self._schedule_preview()

    def _covers(self, r: ReconstructionResult | None, s: int) -> bool:
        if r is None or self.session is None:
            return False
        i = s - r.first_frame * self.session.K
        return 0 <= i < r.video.shape[0]

    def _show(self, s: int) -> None:
        if self.session is None:
            return
        K = self.session.K
        f = s // K
        self.raw_panel.set_image(self.session.raw[f], levels=self._levels)
        self.raw_panel.set_title(f"raw camera frame {f + 1}/{self.session.n_frames} (all {K} slots in one exposure)")
        self.frame_label.setText(f"frame {f + 1}/{self.session.n_frames} · "
                                 f"sub-frame {s + 1}/{self.session.n_subframes}")
        r = self.shown
        if self._covers(r, s):
            i = s - r.first_frame * K
            self.recon_panel.set_image(r.video[i], levels=(0, 1))
            kind = "preview" if r.extra.get("preview") else "reconstruction"
            self.recon_panel.set_title(f"{kind}: {r.method.label()} · sub-frame {s + 1}")
        elif r is not None:
            self.recon_panel.clear("outside the preview window: pause to recompute it here")
        c = self.comparison
        if self._covers(c, s):
            self.slider_panel.set_image(c.video[s - c.first_frame * K], levels=(0, 1))
            self.slider_panel.set_title(f"slider preview: {c.method.label()} · sub-frame {s + 1}")
        elif c is not None:
            self.slider_panel.clear("outside the preview window: pause to recompute it here")
        self.motion_view.show_subframe(s)
        self.compare_view.show_subframe(s)

    # ------------------------------------------------------------------ preview
    def _on_preview_toggled(self, on: bool) -> None:
        self.settings.set("review/preview", on)
        if on:
            self._schedule_preview()

    def _on_form_changed(self) -> None:
        self.form.set_beside(self.full_result_of(self.form.method()) is not None)
        self._refresh_expected()
        self._refresh_enabled()
        self._schedule_preview()

    def _schedule_preview(self) -> None:
        s = self.session
        if not self._closed and s is not None and s.frames is not None and self.preview_check.isChecked():
            self.preview_timer.start()

    def request_preview(self) -> JobHandle | None:
        """Recompute the current settings on a small window of frames around the current one."""
        s = self.session
        if s is None or s.frames is None or self._closed:
            return None
        if self.preview_job is not None and self.preview_job.running:
            self.preview_job.cancel()
        self._preview_generation += 1
        gen = self._preview_generation
        method = self.form.preview_method()
        chosen = self.full_result_of(self.form.method())
        beside = self.form.comparing and chosen is not None
        if not beside:
            self._set_comparison(None)
        if chosen is not None and (beside or method == chosen.method):
            if self.shown is not chosen:  # the result itself, never a preview of it
                self.set_shown(chosen)
            if not beside:
                return None
        a, b = preview_window(s.n_frames, self.subframe // s.K, half_width=1, missing=s.missing)
        frames, code = s.input(method)
        frames, truth = frames[a:b], s.truth(a, b)
        missing = None if s.missing is None else s.missing[a:b]

        def work(token, progress):
            r = run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=b - a,
                                   first_frame=a, truth=truth, missing=missing)
            r.extra["preview"] = True
            return r

        self.preview_job = self.runner.submit(
            "preview", work, on_finished=lambda r, g=gen: self._preview_done(r, g, beside),
            on_failed=lambda msg: self.result_label.setText(f"preview failed: {html.escape(in_gui_words(msg))}"))
        return self.preview_job

    def _preview_done(self, result: ReconstructionResult, generation: int, beside: bool = False) -> None:
        if generation != self._preview_generation:
            return  # a newer request superseded it
        if beside:
            self._set_comparison(result)
        else:
            self.set_shown(result)

    def _set_comparison(self, result: ReconstructionResult | None) -> None:
        """Show the slider's preview beside the chosen method's result (None: hide it)."""
        self.comparison = result
        self.slider_panel.setVisible(result is not None)
        if result is None:
            self.slider_panel.clear("")
        elif self.session is not None:
            self._show(self.subframe)

    def set_shown(self, result: ReconstructionResult | None) -> None:
        """Show ``result`` in the reconstruction panel; the motion panel shows the flow of the result that has
        one (the shown one, else the newest full motion-aware result)."""
        self.shown = result
        if self.session is not None:
            self.motion_view.set_result(self.flow_result(), self.session.K, shown=result)
            self._show(self.subframe)
        self._refresh_enabled()

    def flow_result(self) -> ReconstructionResult | None:
        """The result whose flow and TR map the Motion tab shows: the shown one when it has a flow, else the
        newest full result with one (a preview of another method never hides a full motion-aware result)."""
        if self.shown is not None and self.shown.flow is not None:
            return self.shown
        return next((r for r in reversed(self.results) if r.flow is not None), None)

    # ------------------------------------------------------------------ full reconstruction
    def reconstruct(self) -> JobHandle | None:
        """Reconstruct every frame with the current settings (off-thread, cancellable)."""
        s = self.session
        if s is None or s.frames is None or self.busy:
            return None
        method = self.form.method()
        chunk = chunk_frames_for(method, s.n_frames, s.K)
        (frames, code), truth, missing = s.input(method), self._truth, s.missing

        def work(token, progress):
            return run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=chunk,
                                      truth=truth, missing=missing)

        self.progress.setRange(0, s.n_frames)
        self.progress.setValue(0)
        self._expected_for_job = self.expected_seconds()
        self.result_label.setText(f"reconstructing with {method.label()} …")
        self.job = self.runner.submit(
            "reconstruct", work, on_progress=lambda done, total: self.progress.setValue(done),
            on_finished=self._reconstructed, on_cancelled=self._reconstruction_cancelled,
            on_failed=lambda msg: self.result_label.setText(
                coloured(f"reconstruction failed: {in_gui_words(msg)}", RED)),
            on_done=self._refresh_enabled)
        self._refresh_enabled()
        return self.job

    @property
    def busy(self) -> bool:
        """True while a full reconstruction runs (its outcome is set the moment it ends)."""
        return self.job is not None and self.job.outcome is None

    def cancel(self) -> None:
        """Cancel a running reconstruction (the preview is cancelled too); it stops after its current chunk."""
        if self.busy and not self.job.token.cancelled:
            self.result_label.setText("cancelling … (the current chunk of frames finishes first)")
            self.cancel_button.setEnabled(False)
        for h in (self.job, self.preview_job):
            if h is not None and h.running:
                h.cancel()

    def _reconstruction_cancelled(self) -> None:
        self.progress.setValue(0)
        self.result_label.setText("cancelled; nothing was kept")
        self.status.emit("reconstruction cancelled")

    def _reconstructed(self, result: ReconstructionResult) -> None:
        self.results.append(result)
        self.progress.setValue(self.progress.maximum())
        vox = result.video.size / max(result.seconds, 1e-9) / 1e6
        text = f"{result.method.label()}: {result.video.shape[0]} sub-frames in {result.seconds:.2f} s " \
               f"({vox:.2g} M voxels/s)"
        if result.psnr is not None:
            text += f"; PSNR vs ground truth {result.psnr:.2f} dB"
        expected_s, self._expected_for_job = self._expected_for_job, None
        if expected_s is not None:
            text += f" (expected ≈ {format_seconds(expected_s)})"
        H, W = result.video.shape[1:]
        _logger.info("reconstruction %s of %d sub-frames of %dx%d: measured %.3f s, expected %s", result.method.label(),
                     result.video.shape[0], W, H, result.seconds,
                     "unknown (not timed yet)" if expected_s is None else f"{expected_s:.3f} s")
        self.result_label.setText(text)
        self.set_shown(result)
        self.form.set_beside(self.full_result_of(self.form.method()) is not None)
        self.compare_view.set_results(self.results, self.session.K, self._truth)
        self.result_added.emit(result)
        self.status.emit(text)

    # ------------------------------------------------------------------ export
    def _ask_export(self) -> None:
        r = self.export_candidate()
        if r is None:
            return
        start = self.settings.last_folder("review/export_dir")
        name = str(Path(start) / f"{self.session.path.stem}-{export_slug(r.method)}.tif")
        path, _ = QFileDialog.getSaveFileName(self, "Export the reconstruction", name, EXPORT_FILTER,
                                              options=QFileDialog.Option.DontConfirmOverwrite)  # export asks
        if path:
            self.export(path)

    def export_candidate(self) -> ReconstructionResult | None:
        """What the reconstruction panel shows (a full result or a preview), else the newest full result."""
        if self.shown is not None:
            return self.shown
        return self.results[-1] if self.results else None

    def full_result_of(self, method) -> ReconstructionResult | None:
        """The newest full reconstruction made with exactly ``method`` (None: none yet)."""
        return next((r for r in reversed(self.results) if r.method == method), None)

    def export(self, path, *, overwrite: bool | None = None) -> JobHandle | None:
        """Write what the panel shows, over every frame, to ``path`` (.tif, .mp4, .npy, .zarr) off the GUI thread.

        A full reconstruction is written as it is. A preview is written as the full reconstruction with the same
        method and options: an existing one, or one made now (with progress and Cancel) and then kept in the
        results. A .zarr export carries the method, its options and the source in its ``flexvox`` attributes;
        the message names the method and its options whatever the format. An existing ``path`` is replaced when
        ``overwrite`` is True, kept when it is False, and otherwise when the operator says so (the question names
        it).
        """
        r = self.export_candidate()
        s = self.session
        if r is None or s is None:
            self.export_label.setText("nothing to export: reconstruct, or preview, first")
            return None
        if r.extra.get("preview") and (s.frames is None or self.busy):
            self.export_label.setText(coloured("not exported: wait for the running reconstruction to end", RED)
                                      if s.frames is not None else "not exported: this recording cannot be "
                                      "reconstructed")
            return None
        path = Path(path)
        self.settings.remember_folder(path, "review/export_dir")
        if overwrite is None and path.exists() and path.resolve() != s.path.resolve():  # the recording: refused
            if not replace_question(self, path, "export"):
                self.export_label.setText(f"not exported: {html.escape(str(path))} is kept (choose another path)")
                return None
            overwrite = True
        overwrite = bool(overwrite)
        try:  # never onto the recording under review; the folder must take the file
            check_output(path, overwrite=overwrite, inputs=[s.path])
        except OutputError as exc:
            self.export_label.setText(coloured(f"not exported: {in_gui_words(str(exc))}", RED))
            return None
        method = r.method
        full = r if not r.extra.get("preview") else self.full_result_of(method)
        fps = float(self.fps.value())
        (frames, code), truth, missing = s.input(method), self._truth, s.missing
        chunk = chunk_frames_for(method, s.n_frames, s.K)
        source = str(s.path)
        rate = s.recording.attrs.get("rates", {}).get("subframe_hz")
        time_step = 1.0 / float(rate) if rate else None  # Fiji and OME-Zarr readers then show seconds

        def work(token, progress):
            result = full
            if result is None:
                result = run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=chunk,
                                            truth=truth, missing=missing)
                token.check()
            attrs = {"source": source, "method": method.as_dict(), "method_label": method.label(),
                     "seconds": result.seconds, "subframes": int(result.video.shape[0])}
            write_video(path, result.video, fps=fps, attrs=attrs, overwrite=overwrite, time_step=time_step,
                        interpolated=result.extra.get("interpolated"))
            return result, path

        what = f"{method.label()} ({s.n_frames} frames, {s.n_subframes} sub-frames)"
        if full is None:
            self.export_label.setText(f"reconstructing all frames with {what} to export what is shown …")
            self.progress.setRange(0, s.n_frames)
            self.progress.setValue(0)
        else:
            self.export_label.setText(f"writing {path.name}: {what} …")
        handle = self.runner.submit(
            "export", work, on_progress=lambda done, total: self.progress.setValue(done),
            on_finished=lambda out: self._exported(out, full is None, what),
            on_cancelled=lambda: self.export_label.setText("export cancelled; nothing was written"),
            on_failed=lambda msg: self.export_label.setText(coloured(f"export failed: {in_gui_words(msg)}", RED)),
            on_done=self._refresh_enabled)
        if full is None:
            self.job = handle  # Cancel stops it; Reconstruct waits for it
            self._refresh_enabled()
        return handle

    def _exported(self, out, reconstructed: bool, what: str) -> None:
        result, path = out
        if reconstructed:
            self._reconstructed(result)
        self.exported = (path, result)
        self._written.append(result)
        self.export_label.setText(f"wrote {path}: {what}")
        self.status.emit(f"exported {path.name}: {what}")

    # ------------------------------------------------------------------ state
    def unexported(self) -> list[ReconstructionResult]:
        """The full reconstructions never exported (closing the window loses them)."""
        return [r for r in self.results if not any(r is w for w in self._written)]

    def closing_losses(self) -> list[str]:
        """What closing the window would stop or lose now: a reconstruction or export running, results not
        exported."""
        out = []
        if self.busy:
            out.append("the reconstruction running stops; what it computed is lost")
        lost = self.unexported()
        if lost:
            names = "; ".join(r.method.label() for r in lost)
            out.append(f"{len(lost)} reconstruction{'s' if len(lost) > 1 else ''} not exported "
                       f"{'are' if len(lost) > 1 else 'is'} lost: {names}")
        return out

    def shutdown(self) -> None:
        """The window closes: stop playback and the preview timer for good, and cancel the jobs.

        After this no timer restarts and no job is submitted (the job runner shuts down next)."""
        self._closed = True
        self.timer.stop()
        self.preview_timer.stop()
        self.set_playing(False)
        self.preview_timer.stop()
        self.cancel()

    def speed_model(self, name: str, K: int) -> SpeedModel | None:
        """This machine's calibrated speed of method ``name`` at K slots (None: not measured by this version)."""
        model = SpeedModel.from_json(self.settings.get_str(settings_key(name, K), ""))
        return model if is_current(model) else None

    def expected_seconds(self) -> float | None:
        """Expected seconds of a full reconstruction with the form's method on this machine (None: not known yet)."""
        s = self.session
        if s is None:
            return None
        method = self.form.method()
        model = self.speed_model(method.name, s.K)
        if model is None:
            return None
        H, W = s.shape
        return estimate_seconds(model, self.table, method, s.code, n_frames=s.n_frames, H=H, W=W)

    def _calibrate_speed(self, name: str, code) -> None:
        """Time method ``name`` on this machine (off the GUI thread, once per method and K; kept in the settings)."""
        K = int(code.shape[2])
        key = settings_key(name, K)
        job = self._speed_jobs.get(key)
        if self._closed or (job is not None and job.outcome in (None, "finished")):
            return

        def done(model: SpeedModel) -> None:
            self.settings.set(key, model.to_json())
            self._refresh_expected()

        self._speed_jobs[key] = self.runner.submit(
            "machine speed", lambda token, progress: calibrate(name, code, cancel=token), on_finished=done,
            on_failed=lambda msg: _logger.warning("timing %s on this machine failed: %s", name, msg))

    def _refresh_expected(self) -> None:
        s = self.session
        if s is None:
            self.expected_label.setText("open a recording to see the expected time and quality")
            return
        method = self.form.method()
        e = expected(self.table, method, s.code, voxels=s.n_subframes * s.shape[0] * s.shape[1])
        seconds = self.expected_seconds()
        if seconds is None:
            self._calibrate_speed(method.name, s.code)
            time_text = "timing this machine …"
        else:
            time_text = f"≈ {format_seconds(seconds)} on this machine"
        if e is None:
            self.expected_label.setText(f"<b>expected</b> {time_text}; no bench figures for the quality")
            self.expected_label.setToolTip("")
            return
        self.expected_label.setText(f"<b>expected</b> {time_text}, {e.quality_text()}<br><small>{e.basis}</small>")
        self.expected_label.setToolTip("time: this recording's size on this machine, from a calibration run of the "
                                       "method here (cached in the settings); quality: measured by the bench on the "
                                       "built-in scenes, not on this recording")

    def _refresh_enabled(self) -> None:
        can = self.session is not None and self.session.frames is not None
        self.reconstruct_button.setEnabled(can and not self.busy)
        name = self.form.method().name
        self.reconstruct_button.setText(f"Reconstruct: {name}")
        self.reconstruct_button.setToolTip(f"reconstruct every frame of the recording with {name}")
        self.cancel_button.setEnabled(self.busy)
        self.export_button.setEnabled(self.export_candidate() is not None)
        self.play_button.setEnabled(self.session is not None)
        if self.session is None:
            self._refresh_expected()
