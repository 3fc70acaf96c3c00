"""The Capture workspace: code, timing check, live view with histogram, saturation and counters, recording.

Recording runs through :class:`app.capture.service.CaptureService` (built by
:func:`app.gui.models.recording.make_capture`, or the ``capture_factory`` given to the constructor).

Device ownership: a recording *owns* the devices. Record stops the live view first (its reader
thread and the capture's must not both read the camera); the capture service sets up the
projector, sync box and camera, reads and writes on its own threads, and stops the devices at
the end (those it opened it closes again). While it records, the display timer shows
``service.latest()`` (the newest frame, a reference swap: the display never slows capture) and
the counters come from ``service.stats()``. Starting (a real projector's pattern upload takes
seconds) and stopping (the writer drains its queue) run on the job runner, so the window never
waits on them.

Calibration: the "Calibration" box loads a calibration file (or takes the Calibrate
workspace's result, :meth:`CaptureWorkspace.use_outcome`), refusing one made for another rig or
resolution (:mod:`app.gui.models.capture_calibration`); recordings, the live view's patterns and the
projector output window then use its homography and sync phase.

Beside the raw view, a motion-aware preview of the newest frames (:mod:`app.gui.capture.live_preview`:
its own worker thread, newest wins, a bounded duty cycle) says the resolution and rate it runs
at. The projector output window (:mod:`app.gui.projector.window`) shows the packed patterns
full-screen and pixel-exact on a chosen screen, for a projector driven through its video input.
"""

from __future__ import annotations

import html
import logging
import time
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QRadioButton,
    QScrollArea,
    QSpinBox,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from app.gui.capture.live_preview import LivePreview
from app.gui.capture.live_view import LiveStream
from app.gui.models.capture_calibration import (
    ActiveCalibration,
    CalibrationRefused,
    capture_identity,
    from_outcome,
    load_for_capture,
)
from app.gui.models.capture_plan import TILES, CapturePlan
from app.gui.models.live_source import LiveStartError, projector_size, start_live, stop_live
from app.gui.models.live_stats import LiveStats, histogram, saturation_level, saturation_mask
from app.gui.models.recording import counters_text, make_capture, result_text, resync_clock
from app.gui.models.rig_service import RigService
from app.gui.projector.window import ProjectorWindow, ScreenPicker, packed_frames
from app.gui.widgets.image_panel import ImagePanel
from app.gui.widgets.qt_jobs import JobRunner
from app.gui.widgets.settings import AppSettings

_logger = logging.getLogger(__name__)

DISPLAY_HZ = 30
"""The live image is redrawn at most this often, whatever the camera's rate."""
SATURATION_RGBA = (255, 0, 0, 170)
COUNTERS_MS = 200
"""The recording counters are refreshed this often."""
STOP_TIMEOUT_S = 30.0
RED, GREEN, AMBER = "#c0392b", "#1e8449", "#b7950b"


def _coloured(text: str, colour: str) -> str:
    return f"<span style='color:{colour}'>{html.escape(text)}</span>"


class CaptureWorkspace(QWidget):
    """Code choice, camera rate and exposure, the projector timing check, the live view and recording.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    runner : JobRunner, optional
        Starts and stops recordings off the GUI thread (default: one of its own).
    capture_factory : callable, optional
        ``(rig, code, path, **options) -> CaptureService`` (default the capture service itself).
    rig_guard : callable, optional
        ``() -> str | None``: a reason the rig is busy elsewhere (a calibration), checked before
        the live view or a recording starts.
    """

    recording_finished = Signal(object)
    """The :class:`~app.capture.service.CaptureResult` (None when the capture did not stop in time)."""
    open_requested = Signal(object)
    """A recording's path the operator wants to review."""
    calibration_changed = Signal(object)
    """The :class:`~app.gui.models.capture_calibration.ActiveCalibration` now used (None: identity, uncalibrated)."""

    def __init__(self, service: RigService, settings: AppSettings, runner: JobRunner | None = None, *,
                 capture_factory=None, rig_guard=None, parent: QWidget | None = None):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.runner = runner or JobRunner(parent=self)
        self.capture_factory = capture_factory
        self.rig_guard = rig_guard
        self.stats = LiveStats()
        self.stream = LiveStream(self)
        self._latest = None
        self.capture = None
        """The running (or last) :class:`CaptureService`, None before the first recording."""
        self.last_result = None
        self._recording = False
        self._shown_seq = 0
        self._stop_job = None
        self._start_job = None
        self._last_shown_id = None
        self.calibration: ActiveCalibration | None = None
        """The calibration recordings use (None: identity homography, phase 0)."""
        self.projector_window = None
        """The open :class:`~app.gui.projector.window.ProjectorWindow`, or None."""
        self._projector_job = None
        self._calibration_error = ""
        self.preview = LivePreview(self)
        self._preview_index = 0
        self._build()
        self.preview.updated.connect(self._on_preview)
        self.preview.failed.connect(lambda message: self.preview_label.setText(
            _coloured(f"preview stopped: {message}", RED)))
        self.stream.frame.connect(self._on_frame)
        self.stream.failed.connect(self._on_failed)
        self._plan_changed()

    # ------------------------------------------------------------------ layout
    def _build(self) -> None:
        code = QGroupBox("Shutter code")
        self.tile_box = QComboBox()
        for m, n in TILES:
            self.tile_box.addItem(f"{m}×{n} (K = {m * n})", f"{m}x{n}")
        saved = self.settings.get_str("capture/tile", "4x4")
        idx = self.tile_box.findData(saved)
        self.tile_box.setCurrentIndex(idx if idx >= 0 else TILES.index((4, 4)))
        self.identity = QRadioButton("identity (one slot per pixel)")
        self.multiplexed = QRadioButton("multiplexed (S-matrix)")
        (self.multiplexed if self.settings.get_bool("capture/multiplexed", False) else self.identity).setChecked(True)
        self.code_label = QLabel()
        self.code_label.setWordWrap(True)
        self.resolutions_label = QLabel()
        self.resolutions_label.setWordWrap(True)
        self.resolutions_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(code)
        f.addRow("tile", self.tile_box)
        f.addRow(self.identity)
        f.addRow(self.multiplexed)
        f.addRow(self.code_label)
        f.addRow(self.resolutions_label)

        timing = QGroupBox("Camera and projector timing")
        self.rate = QDoubleSpinBox()
        self.rate.setRange(0.5, 1000)
        self.rate.setDecimals(2)
        self.rate.setSuffix(" Hz")
        self.rate.setValue(self.settings.get_float("capture/camera_hz", 15.0))
        self.auto_exposure = QCheckBox("camera exposure = one sequence (K × period)")
        self.auto_exposure.setChecked(self.settings.get_bool("capture/auto_exposure", True))
        self.exposure = QDoubleSpinBox()
        self.exposure.setRange(10, 10_000_000)
        self.exposure.setDecimals(0)
        self.exposure.setSuffix(" µs")
        self.exposure.setValue(self.settings.get_float("capture/exposure_us", 66_656))
        self.projector_exposure = QDoubleSpinBox()
        self.projector_exposure.setRange(0, 10_000_000)
        self.projector_exposure.setDecimals(0)
        self.projector_exposure.setSuffix(" µs")
        self.projector_exposure.setSpecialValueText("= period (video port)")
        self.projector_exposure.setValue(self.settings.get_float("capture/projector_exposure_us", 0))
        self.timing_label = QLabel()
        self.timing_label.setWordWrap(True)
        self.timing_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(timing)
        f.addRow("camera rate", self.rate)
        f.addRow(self.auto_exposure)
        f.addRow("camera exposure", self.exposure)
        f.addRow("pattern exposure", self.projector_exposure)
        f.addRow(self.timing_label)

        cal = QGroupBox("Calibration")
        self.calibration_label = QLabel()
        self.calibration_label.setWordWrap(True)
        self.calibration_label.setTextFormat(Qt.TextFormat.RichText)
        self.calibration_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.load_calibration_button = QPushButton("Load calibration…")
        self.clear_calibration_button = QPushButton("Uncalibrated")
        self.clear_calibration_button.setToolTip("record with the identity homography and phase 0")
        row = QHBoxLayout()
        row.addWidget(self.load_calibration_button)
        row.addWidget(self.clear_calibration_button)
        cv = QVBoxLayout(cal)
        cv.addWidget(self.calibration_label)
        cv.addLayout(row)

        proj = QGroupBox("Projector output (video input)")
        self.screen_box = ScreenPicker()
        self.projector_button = QPushButton("Show patterns full-screen")
        self.projector_button.setCheckable(True)
        self.projector_label = QLabel("closed · the packed patterns (24 masks per RGB frame) go full-screen on "
                                      "the chosen screen, pixel for pixel; Esc closes")
        self.projector_label.setWordWrap(True)
        self.projector_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(proj)
        f.addRow("screen", self.screen_box)
        f.addRow(self.projector_button)
        f.addRow(self.projector_label)

        live = QGroupBox("Live view")
        self.live_button = QPushButton("Start live view")
        self.live_button.setCheckable(True)
        self.saturation_check = QCheckBox("show saturated pixels in red")
        self.saturation_check.setChecked(True)
        self.preview_check = QCheckBox("motion-aware preview of the newest frames")
        self.preview_check.setChecked(self.settings.get_bool("capture/preview", True))
        self.live_label = QLabel("stopped")
        self.live_label.setWordWrap(True)
        v = QVBoxLayout(live)
        v.addWidget(self.live_button)
        v.addWidget(self.saturation_check)
        v.addWidget(self.preview_check)
        v.addWidget(self.live_label)

        rec = QGroupBox("Recording")
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
        self.overwrite_check = QCheckBox("replace an existing recording")
        self.truth_check = QCheckBox("store the scene's ground truth (simulated rig)")
        self.truth_check.setChecked(self.service.simulated)
        self.truth_check.setVisible(self.service.simulated)
        self.record_button = QPushButton("● Record")
        self.stop_button = QPushButton("■ Stop")
        self.stop_button.setEnabled(False)
        buttons = QHBoxLayout()
        buttons.addWidget(self.record_button)
        buttons.addWidget(self.stop_button)
        self.counters_label = QLabel("not recording")
        self.counters_label.setWordWrap(True)
        self.recording_label = QLabel("not recorded yet")
        self.recording_label.setWordWrap(True)
        self.recording_label.setTextFormat(Qt.TextFormat.RichText)
        self.recording_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.review_button = QPushButton("Open in Review")
        self.review_button.setEnabled(False)
        f = QFormLayout()
        f.addRow("path", path_row)
        f.addRow("frames", self.frames_box)
        rv = QVBoxLayout(rec)  # word-wrapped labels get their full height in a box layout, not a form
        rv.addLayout(f)
        for w in (self.overwrite_check, self.truth_check):
            rv.addWidget(w)
        rv.addLayout(buttons)
        for w in (self.counters_label, self.recording_label, self.review_button):
            rv.addWidget(w)

        left = QWidget()
        lv = QVBoxLayout(left)
        for w in (code, timing, cal, live, rec, proj):
            lv.addWidget(w)
        lv.addStretch(1)
        scroll = QScrollArea()
        self.controls_scroll, self.recording_box, self.projector_box = scroll, rec, proj
        scroll.setWidget(left)
        scroll.setWidgetResizable(True)
        scroll.setMinimumWidth(380)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)

        self.image_panel = ImagePanel("camera: live view stopped")
        self.image_panel.clear("press Start live view")
        self.hist = pg.PlotWidget()
        self.hist.setBackground("#202020")
        self.hist.setLabel("bottom", "pixel value")
        self.hist.setLabel("left", "pixels")
        self.hist.setMaximumHeight(200)
        self.hist_curve = self.hist.plot([0, 1], [0], stepMode="center", fillLevel=0, brush=(90, 160, 255, 120))
        self.sat_line = pg.InfiniteLine(angle=90, pen=pg.mkPen((255, 60, 60), width=1, style=Qt.PenStyle.DashLine))
        self.hist.addItem(self.sat_line)
        self.preview_panel = ImagePanel("motion-aware preview")
        self.preview_panel.clear("starts with the live view")
        self.preview_label = QLabel("preview: off")
        self.preview_label.setWordWrap(True)
        self.preview_label.setTextFormat(Qt.TextFormat.RichText)
        preview_box = QWidget()
        pv = QVBoxLayout(preview_box)
        pv.setContentsMargins(0, 0, 0, 0)
        pv.addWidget(self.preview_panel, 1)
        pv.addWidget(self.preview_label)
        views = QSplitter()
        views.addWidget(self.image_panel)
        views.addWidget(preview_box)
        views.setSizes([500, 500])
        right = QWidget()
        rv = QVBoxLayout(right)
        rv.addWidget(views, 1)
        rv.addWidget(self.hist)

        split = QSplitter()
        split.addWidget(scroll)
        split.addWidget(right)
        split.setStretchFactor(1, 1)
        split.setSizes([400, 900])
        QHBoxLayout(self).addWidget(split)

        self.display_timer = QTimer(self)
        self.display_timer.setInterval(int(1000 / DISPLAY_HZ))
        self.display_timer.timeout.connect(self._redraw)

        for sig in (self.tile_box.currentIndexChanged, self.identity.toggled, self.rate.valueChanged,
                    self.auto_exposure.toggled, self.exposure.valueChanged, self.projector_exposure.valueChanged):
            sig.connect(self._plan_changed)
        self.live_button.toggled.connect(self._on_live_toggled)
        self.browse_button.clicked.connect(self._browse)
        self.record_button.clicked.connect(self.record)
        self.stop_button.clicked.connect(self.stop_recording)
        self.review_button.clicked.connect(self._ask_review)
        self.path_edit.textChanged.connect(lambda text: self.settings.set("capture/recording_path", text))
        self.frames_box.valueChanged.connect(lambda n: self.settings.set("capture/frames", n))
        self.load_calibration_button.clicked.connect(self._ask_calibration)
        self.clear_calibration_button.clicked.connect(self.clear_calibration)
        self.projector_button.toggled.connect(self._on_projector_toggled)
        self.preview_check.toggled.connect(self._on_preview_toggled)
        self.counters_timer = QTimer(self)
        self.counters_timer.setInterval(COUNTERS_MS)
        self.counters_timer.timeout.connect(self._poll_capture)

    # ------------------------------------------------------------------ plan
    def plan(self) -> CapturePlan:
        """The plan the controls describe."""
        pe = int(self.projector_exposure.value())
        return CapturePlan(tile=self.tile(), multiplexed=self.multiplexed.isChecked(),
                           camera_hz=self.rate.value(),
                           camera_exposure_us=None if self.auto_exposure.isChecked() else self.exposure.value(),
                           projector_exposure_us=pe or None)

    def tile(self) -> tuple[int, int]:
        """The chosen tile (m, n)."""
        m, n = self.tile_box.currentData().split("x")
        return int(m), int(n)

    def set_tile(self, tile: tuple[int, int]) -> None:
        """Choose a tile offered in the list."""
        idx = self.tile_box.findData(f"{tile[0]}x{tile[1]}")
        if idx < 0:
            raise ValueError(f"`tile` must be one of {', '.join(f'{m}x{n}' for m, n in TILES)}; got {tile!r}")
        self.tile_box.setCurrentIndex(idx)

    def _plan_changed(self, *_) -> None:
        m, n = self.tile()
        s = self.settings
        s.set("capture/tile", f"{m}x{n}")
        s.set("capture/multiplexed", self.multiplexed.isChecked())
        s.set("capture/camera_hz", self.rate.value())
        s.set("capture/auto_exposure", self.auto_exposure.isChecked())
        s.set("capture/exposure_us", self.exposure.value())
        s.set("capture/projector_exposure_us", self.projector_exposure.value())
        self.exposure.setEnabled(not self.auto_exposure.isChecked())
        plan = self.plan()
        try:
            self.code_label.setText(plan.code_summary())
            rows = "".join(f"<tr><td>{d.label}</td><td align='right'>{d.tr}</td><td align='right'>{d.sr}</td></tr>"
                           for d in plan.resolutions())
            self.resolutions_label.setText(
                "<b>[TR, SR] after capture</b><table cellspacing='6'><tr><th>block</th><th>TR</th><th>SR</th></tr>"
                f"{rows}</table>")
        except ValueError as exc:
            self.code_label.setText(f"<span style='color:#c0392b'>{html.escape(str(exc))}</span>")
            self.resolutions_label.setText("")
        t = plan.timing()
        if self.auto_exposure.isChecked():
            self.exposure.blockSignals(True)
            self.exposure.setValue(t.sequence_us)
            self.exposure.blockSignals(False)
        lines = [f"pattern period {t.period_us} µs, exposure {t.projector_exposure_us} µs; "
                 f"{plan.K} patterns = {t.sequence_us / 1000:.3f} ms per camera frame"]
        lines += [f"<span style='color:#c0392b'>✗ {html.escape(e)}</span>" for e in t.errors]
        lines += [f"<span style='color:#b7950b'>• {html.escape(n)}</span>" for n in t.notes]
        if t.ok:
            lines.insert(1, "<span style='color:#1e8449'>✓ the projector accepts this timing "
                            "(exposure = period, or ≤ period − 230 µs)</span>")
        self.timing_label.setText("<br>".join(lines))
        self._show_calibration()
        self._update_buttons()

    # ------------------------------------------------------------------ live view
    def _on_live_toggled(self, on: bool) -> None:
        if on:
            self.start_live()
        else:
            self.stop_live()

    def start_live(self) -> bool:
        """Start the live view; False (with the reason shown) when it cannot start."""
        if self.stream.running:
            return True
        busy = self._busy_reason()
        if busy:
            self.live_label.setText(_coloured(f"cannot start: {busy}", RED))
            self._set_button(False)
            return False
        try:
            note = start_live(self.service, self.plan(), self._live_calibration())
        except LiveStartError as exc:
            self.live_label.setText(f"<span style='color:#c0392b'>cannot start: {html.escape(str(exc))}</span>")
            self._set_button(False)
            return False
        self.stats = LiveStats()
        self._latest = None
        self.stream.start(self.service.rig.camera, timeout_s=max(1.0, 3 / self.rate.value()))
        self.display_timer.start()
        self._start_preview()
        self.live_label.setText(note or "waiting for frames …")
        self.image_panel.set_title("camera: live")
        self._set_button(True)
        return True

    def stop_live(self) -> None:
        """Stop the live view (devices stay connected)."""
        self.display_timer.stop()
        self._stop_preview()
        stopped = self.stream.stop()
        stop_live(self.service)
        if stopped:
            self.live_label.setText(f"stopped · {self.stats.text()}")
        self.image_panel.set_title("camera: live view stopped")
        self._set_button(False)

    @property
    def live(self) -> bool:
        """True while the live view runs."""
        return self.stream.running

    def _set_button(self, on: bool) -> None:
        self.live_button.blockSignals(True)
        self.live_button.setChecked(on)
        self.live_button.setText("Stop live view" if on else "Start live view")
        self.live_button.blockSignals(False)

    def _on_frame(self, frame) -> None:
        self.stats.update(frame)
        self._latest = frame
        self.preview.feed(frame)  # a list append; the reconstruction runs on the preview's own worker

    def _on_failed(self, message: str) -> None:
        self.service.record_error("camera", f"live view: {message}")
        self.stop_live()
        self.live_label.setText(f"<span style='color:#c0392b'>live view stopped: {html.escape(message)}</span>")

    def _redraw(self) -> None:
        self._advance_preview()
        if self._recording and self.capture is not None:
            f, seq = self.capture.latest()
            if f is None or seq == self._shown_seq:
                return
            self._shown_seq = seq
            self.preview.feed(f)
            self._show_frame(f)
            return
        f = self._latest
        if f is None:
            return
        self._latest = None
        self._show_frame(f)
        self.live_label.setText(self.stats.text())

    def _show_frame(self, f) -> None:
        img = f.image
        top = saturation_level(img)
        self.image_panel.set_image(img, levels=(0, top))
        if self.saturation_check.isChecked():
            mask = saturation_mask(img, top)
            rgba = np.zeros((*img.shape, 4), np.uint8)
            rgba[mask] = SATURATION_RGBA
            self.image_panel.set_overlay(rgba)
        else:
            self.image_panel.set_overlay(None)
        counts, edges = histogram(img, top=top)
        self.hist_curve.setData(edges, counts)
        self.sat_line.setValue(top)
        what = "recording" if self._recording else "camera"
        self._last_shown_id = f.frame_id
        self.image_panel.set_title(f"{what}: frame {f.frame_id}")

    # ------------------------------------------------------------------ recording
    @property
    def recording(self) -> bool:
        """True from Record until the capture has ended."""
        return self._recording

    def _busy_reason(self) -> str | None:
        if self._recording:
            return "a recording is running"
        return self.rig_guard() if self.rig_guard is not None else None

    def _update_buttons(self) -> None:
        ok = self.plan().timing().ok
        self.live_button.setEnabled((ok and not self._recording) or self.stream.running)
        self.record_button.setEnabled(ok and not self._recording)
        self.stop_button.setEnabled(self._recording and self._stop_job is None)
        for w in (self.path_edit, self.browse_button, self.frames_box, self.overwrite_check, self.truth_check,
                  self.tile_box, self.identity, self.multiplexed, self.rate, self.auto_exposure,
                  self.projector_exposure, self.load_calibration_button, self.clear_calibration_button):
            w.setEnabled(not self._recording)
        self.exposure.setEnabled(not self._recording and not self.auto_exposure.isChecked())

    def _browse(self) -> None:
        start = self.path_edit.text() or str(Path.home() / "recording.zarr")
        path, _ = QFileDialog.getSaveFileName(self, "Record to", start, "Zarr recordings (*.zarr)")
        if path:
            self.path_edit.setText(path if path.endswith(".zarr") else path + ".zarr")

    def _say(self, text: str, colour: str | None = None) -> None:
        self.recording_label.setText(_coloured(text, colour) if colour else html.escape(text))

    def record(self) -> bool:
        """Start recording to the chosen path; False (with the reason shown) when it cannot start.

        The live view is stopped first (the capture service owns the devices while it records).
        """
        from app.capture.service import CaptureError

        if self._recording:
            return False
        text = self.path_edit.text().strip()
        if not text:
            self._say("choose a recording path first (folder/name.zarr)", RED)
            return False
        plan = self.plan()
        if not plan.timing().ok:
            self._say("cannot record: " + "; ".join(plan.timing().errors), RED)
            return False
        busy = self.rig_guard() if self.rig_guard is not None else None
        if busy:
            self._say(f"cannot record: {busy}", RED)
            return False
        if self.stream.running:
            self.stop_live()
        frames = self.frames_box.value() or None
        options = {} if self.capture_factory is None else {"factory": self.capture_factory}
        try:
            capture = make_capture(self.service, plan, Path(text).expanduser(), frames=frames,
                                   calibration=self.capture_calibration(),
                                   overwrite=self.overwrite_check.isChecked(),
                                   ground_truth=self.service.simulated and self.truth_check.isChecked(), **options)
        except (CaptureError, ValueError) as exc:
            self._say(f"cannot record: {exc}", RED)
            return False
        self.capture = capture
        self.last_result = None
        self._recording = True
        self._shown_seq = 0
        self._last_shown_id = None
        self._stop_job = None
        self.review_button.setEnabled(False)
        self._update_buttons()
        self._say(f"starting: setting up the rig for {capture.path.name} …")
        self.counters_label.setText("starting …")
        self.image_panel.set_title("recording: waiting for the first frame")
        resync_clock(self.service)
        self._start_job = self.runner.submit("capture start", lambda token, progress: capture.start(),
                           on_finished=lambda _: self._on_capture_started(capture),
                           on_failed=lambda message: self._on_capture_start_failed(capture, message))
        return True

    def _on_capture_started(self, capture) -> None:
        if capture is not self.capture:
            return
        for role in ("projector", "camera", "sync"):
            self.service.notify(role)
        target = f"{capture.n_target} frames" if capture.n_target else "until Stop"
        self._say(f"recording to {capture.path} ({target}, {1 / capture.frame_period_s:.3f} Hz; calibration: "
                  f"{capture.calibration.source})")
        self._start_preview()
        self.display_timer.start()
        self.counters_timer.start()
        self._poll_capture()

    def _on_capture_start_failed(self, capture, message: str) -> None:
        if capture is not self.capture:
            return
        self._recording = False
        self._update_buttons()
        self.counters_label.setText("not recording")
        self._say(f"cannot record: {message}", RED)
        self.image_panel.set_title("camera: live view stopped")
        for role in ("projector", "camera", "sync"):
            self.service.notify(role)

    def stop_recording(self) -> None:
        """Stop the recording early (it keeps every frame captured); the end is reported when it has stopped."""
        capture, start = self.capture, self._start_job
        if not self._recording or capture is None or self._stop_job is not None:
            return
        self._say("stopping: writing the frames still queued …")

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
        self._update_buttons()

    def _poll_capture(self) -> None:
        capture = self.capture
        if capture is None:
            return
        self.counters_label.setText(counters_text(capture.stats(), capture.n_target))
        if capture.result is not None and self._stop_job is None:
            self._finish(capture, capture.result)

    def _finish(self, capture, result, error: str | None = None) -> None:
        if capture is not self.capture or not self._recording:
            return
        self.counters_timer.stop()
        self._redraw()  # the last frame
        self.display_timer.stop()
        self._stop_preview()
        self._recording = False
        self._stop_job = None
        self.last_result = result
        if result is not None:
            self.counters_label.setText(counters_text(result.stats, capture.n_target))
        if error is not None:
            self._say(f"recording failed: {error}", RED)
        else:
            self._say(result_text(result, capture.path), GREEN if result is not None and result.ok else RED)
        self.review_button.setEnabled(result is not None and result.frames_in_recording is not None
                                      and result.frames_in_recording > 0)
        self.image_panel.set_title("recording ended" if self._last_shown_id is None
                                   else f"recording ended · last frame shown: {self._last_shown_id}")
        self._update_buttons()
        for role in ("projector", "camera", "sync"):
            self.service.notify(role)
        self.recording_finished.emit(result)

    def _ask_review(self) -> None:
        if self.capture is not None:
            self.open_requested.emit(self.capture.path)

    def shutdown(self) -> None:
        """Stop the live view and any recording (window closing: waits, bounded, for the recording to end)."""
        self.close_projector_window()
        if self.stream.running:
            self.stop_live()
        if not self.preview.shutdown(5000):
            _logger.error("the live preview did not stop within 5 s")
        capture, start = self.capture, self._start_job
        if self._recording and capture is not None:
            deadline = time.monotonic() + STOP_TIMEOUT_S
            while start is not None and start.outcome is None and time.monotonic() < deadline:
                time.sleep(0.02)  # the rig is being set up on a worker: let it finish, then stop it
            if start is not None and start.outcome == "finished":
                result = capture.stop(timeout_s=STOP_TIMEOUT_S)
                _logger.info("recording stopped at shutdown: %s",
                             "did not stop in time" if result is None else result.message)
        self.counters_timer.stop()
        self.display_timer.stop()

    # ------------------------------------------------------------------ calibration
    def capture_calibration(self):
        """The :class:`~app.capture.service.CaptureCalibration` a recording of the current plan uses."""
        from app.capture.service import CaptureCalibration

        if self.calibration is None:
            return CaptureCalibration()
        plan = self.plan()
        return self.calibration.capture_calibration(plan.K, plan.period_us)

    def _live_calibration(self):
        return None if self.calibration is None else self.capture_calibration()

    def _identity(self):
        from rig_drivers.errors import DeviceError

        try:
            return capture_identity(self.service)
        except (DeviceError, OSError) as exc:
            raise CalibrationRefused(f"cannot read this rig's camera and projector sizes: {exc}") from exc

    def _ask_calibration(self) -> None:
        start = self.settings.get_str("capture/calibration_dir", str(Path.home()))
        path, _ = QFileDialog.getOpenFileName(self, "Load calibration", start, "Calibration (*.json)")
        if path:
            self.settings.set("capture/calibration_dir", str(Path(path).parent))
            self.load_calibration(path)

    def load_calibration(self, path) -> bool:
        """Use the calibration file at ``path``; False (with the reason shown, the previous one kept) when refused."""
        try:
            active = load_for_capture(path, self._identity())
        except CalibrationRefused as exc:
            self._refuse(str(exc))
            return False
        self._set_calibration(active)
        return True

    def use_outcome(self, outcome, path=None) -> bool:
        """Use the Calibrate workspace's result (saved at ``path``, if it was); False (with the reason) when refused."""
        try:
            active = from_outcome(outcome, self._identity(), path=path)
        except CalibrationRefused as exc:
            self._refuse(str(exc))
            return False
        self._set_calibration(active)
        return True

    def clear_calibration(self) -> None:
        """Record uncalibrated (identity homography, phase 0)."""
        self._set_calibration(None)

    def _set_calibration(self, active: ActiveCalibration | None) -> None:
        if self._recording:
            self._refuse("a recording is running: the calibration changes after it")
            return
        self.calibration = active
        self._calibration_error = ""
        self._show_calibration()
        if self.stream.running:  # the projector shows the new patterns
            self.stop_live()
            self.start_live()
        if self.projector_window is not None:
            self.close_projector_window()
            self.projector_label.setText(_coloured("closed: the calibration changed; show the patterns again", AMBER))
        self.calibration_changed.emit(active)

    @property
    def calibration_error(self) -> str:
        """Why the last calibration offered was refused ("" when it was taken)."""
        return self._calibration_error

    def _refuse(self, message: str) -> None:
        self._calibration_error = message
        self._show_calibration()

    def _show_calibration(self) -> None:
        active = self.calibration
        if active is None:
            lines = ["<b>uncalibrated</b>: identity homography, phase 0 (right for the co-located simulated rig)"]
        else:
            plan = self.plan()
            phase, warning = active.phase_for(plan.K, plan.period_us)
            lines = [f"<b>active</b>: {html.escape(active.describe())}",
                     f"recordings use its homography and phase {phase}"]
            if warning:
                lines.append(_coloured(f"• {warning}", AMBER))
        error = self._calibration_error
        if error:
            lines.append(_coloured(f"refused: {error}", RED))
        self.calibration_label.setText("<br>".join(lines))

    # ------------------------------------------------------------------ projector output window
    def chosen_screen(self):
        """The QScreen picked in the combo box (None: no screens)."""
        return self.screen_box.chosen()

    def _on_projector_toggled(self, on: bool) -> None:
        if on:
            self.open_projector_window()
        else:
            self.close_projector_window()

    def _set_projector_button(self, on: bool) -> None:
        self.projector_button.blockSignals(True)
        self.projector_button.setChecked(on)
        self.projector_button.setText("Close projector window" if on else "Show patterns full-screen")
        self.projector_button.blockSignals(False)

    def open_projector_window(self) -> bool:
        """Pack the current patterns (on the job runner) and show them full-screen on the chosen screen.

        False (with the reason shown) when the plan's code cannot be made or no screen exists.
        """
        if self._projector_job is not None and self._projector_job.running:
            return True
        screen = self.chosen_screen()
        if screen is None:
            self.projector_label.setText(_coloured("no screen to show the patterns on", RED))
            self._set_projector_button(False)
            return False
        plan = self.plan()
        try:
            code = plan.code
            camera_size = tuple(int(v) for v in self.service.rig.camera.sensor_shape)
        except (ValueError, OSError) as exc:
            self.projector_label.setText(_coloured(f"cannot make the patterns: {exc}", RED))
            self._set_projector_button(False)
            return False
        psize = projector_size(self.service.rig.projector)
        cal = self.capture_calibration()
        phase = cal.phase_slots % plan.K
        self.projector_label.setText(f"packing {plan.K} masks of {psize[1]}×{psize[0]} …")
        self._set_projector_button(True)

        def job(token, progress):
            return packed_frames(code, camera_size, psize, homography=cal.homography, phase_slots=phase)

        self._projector_job = self.runner.submit(
            "projector patterns", job, on_finished=lambda frames: self._show_projector(frames, screen, plan.K),
            on_failed=lambda message: (self.projector_label.setText(_coloured(f"cannot make the patterns: {message}",
                                                                              RED)),
                                       self._set_projector_button(False)))
        return True

    def _show_projector(self, frames, screen, K: int) -> None:
        if not self.projector_button.isChecked():
            return  # closed while packing
        self.close_projector_window(keep_text=True)
        window = ProjectorWindow(frames, screen=screen)
        window.closed.connect(self._on_projector_closed)
        self.projector_window = window
        window.open()
        n = frames.shape[0]
        cycle = (f"{n} frames cycled every {window.timer.interval()} ms (K = {K} > 24; not locked to vsync: "
                 "prefer K ≤ 24 for the video input)" if n > 1 else f"1 frame: K = {K} masks in its bit-planes")
        text = [f"showing on {html.escape(screen.name() or 'screen')}: {frames.shape[2]}×{frames.shape[1]} pixels, "
                f"{cycle}; Esc closes"]
        warning = window.size_warning()
        if warning:
            text.append(_coloured(f"• {warning}", AMBER))
        self.projector_label.setText("<br>".join(text))
        self._set_projector_button(True)

    def close_projector_window(self, keep_text: bool = False) -> None:
        """Close the projector output window if it is open."""
        window, self.projector_window = self.projector_window, None
        if window is not None:
            window.closed.disconnect(self._on_projector_closed)
            window.close()
            window.deleteLater()
            if not keep_text:
                self.projector_label.setText("closed")
        self._set_projector_button(False)

    def _on_projector_closed(self) -> None:
        window, self.projector_window = self.projector_window, None
        if window is not None:
            window.deleteLater()
        self.projector_label.setText("closed (Esc)")
        self._set_projector_button(False)

    # ------------------------------------------------------------------ live preview
    def _on_preview_toggled(self, on: bool) -> None:
        self.settings.set("capture/preview", on)
        if on and (self.stream.running or self._recording):
            self._start_preview()
        elif not on:
            self._stop_preview()

    def _start_preview(self) -> None:
        if not self.preview_check.isChecked():
            self.preview_label.setText("preview: off")
            return
        from flexvox_core.multiplex import multiplexed_code

        plan = self.plan()
        try:
            code = multiplexed_code(plan.tile) if plan.multiplexed else plan.code
        except ValueError as exc:
            self.preview_label.setText(_coloured(f"preview: {exc}", RED))
            return
        self.preview.set_code(code, plan.tile)
        self.preview.start()
        self._preview_index = 0
        self.preview_panel.clear("reconstructing the newest frames …")
        self.preview_panel.set_title("motion-aware preview: waiting for frames")
        self.preview_label.setText(self.preview.text())

    def _stop_preview(self) -> None:
        was = self.preview.enabled
        self.preview.stop()
        if was:
            self.preview_label.setText(self.preview.text().replace("preview:", "preview (stopped):", 1)
                                       if self.preview.result is not None else "preview: off")

    def _on_preview(self, result) -> None:
        self._preview_index = 0
        self.preview_label.setText(html.escape(self.preview.text()))
        self._advance_preview()

    def _advance_preview(self) -> None:
        r = self.preview.result
        if r is None:
            return
        K = r.video.shape[0]
        k = self._preview_index % K
        self._preview_index = k + 1
        self.preview_panel.set_image(r.video[k], levels=r.levels)
        self.preview_panel.set_title(f"motion-aware preview: frame {r.frame_id}, sub-frame {k + 1}/{K}")
