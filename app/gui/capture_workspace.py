"""The Capture workspace (first slice): code, timing check, live view with histogram, saturation and counters.

Recording to disk from this window will use the capture service (``app/capture/``), passed as
``recorder`` in the constructor. It is not wired yet, so the Recording box says how to record
from a terminal instead of offering a button that would do nothing.
"""

from __future__ import annotations

import html
import logging

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QRadioButton,
    QScrollArea,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from app.gui.capture_plan import TILES, CapturePlan
from app.gui.image_panel import ImagePanel
from app.gui.live_source import LiveStartError, start_live, stop_live
from app.gui.live_stats import LiveStats, histogram, saturation_level, saturation_mask
from app.gui.live_view import LiveStream
from app.gui.rig_service import RigService
from app.gui.settings import AppSettings

_logger = logging.getLogger(__name__)

RECORDING_PENDING = ("Recording from this window is not wired yet. Record with the capture service from a "
                     "terminal — `flexvox capture --rig mock -o REC.zarr --frames N` — then open REC.zarr "
                     "in Review. The live view here does not record.")
DISPLAY_HZ = 30
"""The live image is redrawn at most this often, whatever the camera's rate."""
SATURATION_RGBA = (255, 0, 0, 170)


class CaptureWorkspace(QWidget):
    """Code choice, camera rate and exposure, the projector timing check, and the live view.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    recorder : object, optional
        The capture service's recorder (``app/capture/``); None until it exists.
    """

    def __init__(self, service: RigService, settings: AppSettings, recorder=None, parent: QWidget | None = None):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.recorder = recorder
        self.stats = LiveStats()
        self.stream = LiveStream(self)
        self._latest = None
        self._build()
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

        live = QGroupBox("Live view")
        self.live_button = QPushButton("Start live view")
        self.live_button.setCheckable(True)
        self.saturation_check = QCheckBox("show saturated pixels in red")
        self.saturation_check.setChecked(True)
        self.live_label = QLabel("stopped")
        self.live_label.setWordWrap(True)
        v = QVBoxLayout(live)
        v.addWidget(self.live_button)
        v.addWidget(self.saturation_check)
        v.addWidget(self.live_label)

        rec = QGroupBox("Recording")
        self.recording_label = QLabel(RECORDING_PENDING if self.recorder is None else "recorder ready")
        self.recording_label.setWordWrap(True)
        QVBoxLayout(rec).addWidget(self.recording_label)

        left = QWidget()
        lv = QVBoxLayout(left)
        for w in (code, timing, live, rec):
            lv.addWidget(w)
        lv.addStretch(1)
        scroll = QScrollArea()
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
        right = QWidget()
        rv = QVBoxLayout(right)
        rv.addWidget(self.image_panel, 1)
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
        self.live_button.setEnabled(t.ok or self.stream.running)

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
        try:
            note = start_live(self.service, self.plan())
        except LiveStartError as exc:
            self.live_label.setText(f"<span style='color:#c0392b'>cannot start: {html.escape(str(exc))}</span>")
            self._set_button(False)
            return False
        self.stats = LiveStats()
        self._latest = None
        self.stream.start(self.service.rig.camera, timeout_s=max(1.0, 3 / self.rate.value()))
        self.display_timer.start()
        self.live_label.setText(note or "waiting for frames …")
        self.image_panel.set_title("camera: live")
        self._set_button(True)
        return True

    def stop_live(self) -> None:
        """Stop the live view (devices stay connected)."""
        self.display_timer.stop()
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

    def _on_failed(self, message: str) -> None:
        self.service.record_error("camera", f"live view: {message}")
        self.stop_live()
        self.live_label.setText(f"<span style='color:#c0392b'>live view stopped: {html.escape(message)}</span>")

    def _redraw(self) -> None:
        f = self._latest
        if f is None:
            return
        self._latest = None
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
        self.image_panel.set_title(f"camera: frame {f.frame_id}")
        self.live_label.setText(self.stats.text())

    def shutdown(self) -> None:
        """Stop the live view (window closing)."""
        if self.stream.running:
            self.stop_live()
