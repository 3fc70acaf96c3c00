"""The Capture workspace's live view: the camera's frames, a histogram, saturation, and a motion-aware preview.

:class:`LivePanel` owns the live view (:func:`flexvox_app.gui.models.live_source.start_live` sets the rig
up for the plan and its calibration, :class:`~flexvox_app.gui.capture.live_view.LiveStream` reads the
camera on a worker thread) and the display: the raw view redrawn at most :data:`DISPLAY_HZ`,
the histogram with the saturation level, and the motion-aware preview of the newest frames
(:mod:`flexvox_app.gui.capture.live_preview`: its own worker, newest wins, a bounded duty cycle, full resolution
over the whole frame or a region the operator drags on the live view).

The panel is a view over the :class:`~flexvox_app.gui.models.capture_model.CaptureModel`: it reads the plan and
the calibration there, takes the devices there (:attr:`~flexvox_app.gui.models.capture_model.Holder.LIVE`), and
shows the model's refusal of the live view. When a recording takes the devices the panel stops its live view; while
the recording runs the capture service owns them, and the panel shows
``capture.latest()`` (the newest frame, a reference swap that never slows capture) through
:meth:`LivePanel.follow_capture`.

Its widgets sit in two places: :attr:`LivePanel.controls` (a box for the controls column) and
:attr:`LivePanel.views` (the images, for the large area).
"""

from __future__ import annotations

import html
import math
import time

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, QRectF, Qt, QTimer, Signal
from PySide6.QtWidgets import QCheckBox, QComboBox, QGroupBox, QHBoxLayout, QPushButton, QVBoxLayout, QWidget

from flexvox_app.gui.capture.live_preview import LivePreview
from flexvox_app.gui.capture.live_view import LiveStream
from flexvox_app.gui.models.capture_model import Action, CaptureModel, Cause, Holder
from flexvox_app.gui.models.live_source import LiveStartError, start_live, stop_live
from flexvox_app.gui.models.live_stats import LiveStats, histogram, saturation_level, saturation_mask
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.widgets.adaptive_split import AdaptiveSplit
from flexvox_app.gui.widgets.image_panel import ImagePanel
from flexvox_app.gui.widgets.rich_text import RED, coloured
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine

DEBOUNCE_S = 0.6
"""A second click on Start/Stop live view sooner than this after the first is a double click: it is ignored (a
double click started the live view and stopped it after one frame)."""
DISPLAY_HZ = 30
"""The live image is redrawn at most this often, whatever the camera's rate."""
SATURATION_RGBA = (255, 0, 0, 170)


class LivePanel(QObject):
    """The live view's controls, its images, and the logic that drives them.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
    model : CaptureModel
        The plan and calibration the live view shows, who holds the devices, and the live view's refusal.
    """

    shown_running = Signal(bool)
    """The button now says the live view runs (True) or is stopped (False)."""

    def __init__(self, service: RigService, settings: AppSettings, model: CaptureModel, *, parent: QWidget):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self.model = model
        self.stats = LiveStats()
        self.clock = time.monotonic
        """The clock the button's debounce reads (tests set their own)."""
        self._toggled_at = -math.inf
        self.stream = LiveStream(self)
        self._latest = None
        self._capture = None
        self._shown_seq = 0
        self.last_shown_id = None
        self.preview = LivePreview(self)
        self._preview_index = 0
        self._build(parent)
        self.preview.updated.connect(self._on_preview)
        self.preview.failed.connect(lambda message: self.preview_label.setText(
            coloured(f"preview stopped: {in_gui_words(message)}", RED)))
        self.stream.frame.connect(self._on_frame)
        self.stream.failed.connect(self._on_failed)
        model.refusal_changed.connect(self._on_refusal)
        model.holder_changed.connect(self._on_holder)

    def _build(self, parent) -> None:
        live = QGroupBox("Live view", parent)
        self.live_button = QPushButton("Start live view")
        self.live_button.setCheckable(True)
        self.saturation_check = QCheckBox("show saturated pixels in red")
        self.saturation_check.setChecked(True)
        self.preview_check = QCheckBox("preview with")
        self.preview_check.setToolTip("reconstruct the newest frames as they come, with the method beside")
        self.preview_check.setChecked(self.settings.get_bool("capture/preview", True))
        self.preview_method = QComboBox()
        for name, text in (("motion-aware", "motion-aware (a region)"),
                           ("nc", "nc (fast: whole frame)")):
            self.preview_method.addItem(text, name)
        self.preview_method.setToolTip("motion-aware shows motion best but takes about a second per run at "
                                       "640×480, so it previews a region you drag; nc (constant-tensor "
                                       "diffusion) previews the whole frame several times a second")
        self.preview_method.setCurrentIndex(max(0, self.preview_method.findData(
            self.settings.get_str("capture/preview_method", "motion-aware"))))
        self.live_label = StatusLine("stopped", lines=2)
        v = QVBoxLayout(live)
        v.addWidget(self.live_button)
        v.addWidget(self.saturation_check)
        preview = QHBoxLayout()  # one row: the check and its method
        preview.addWidget(self.preview_check)
        preview.addWidget(self.preview_method, 1)
        v.addLayout(preview)
        v.addWidget(self.live_label)
        self.controls = live

        self.image_panel = ImagePanel("camera: live view stopped")
        self.image_panel.clear("press Start live view")
        # The preview's region, when the whole frame does not fit its time budget: drag it to move it.
        self.region_roi = pg.ROI((0, 0), (1, 1), movable=True, resizable=False, rotatable=False, removable=False,
                                 pen=pg.mkPen((255, 200, 0), width=2))
        self.region_roi.setZValue(20)
        self.region_roi.setVisible(False)
        self.region_roi.setToolTip("the region the motion-aware preview reconstructs at full resolution: drag it")
        self.image_panel.view.addItem(self.region_roi)
        self.region_roi.sigRegionChangeFinished.connect(self._on_region_moved)
        self.hist = pg.PlotWidget()
        self.hist.setBackground("#202020")
        self.hist.setLabel("bottom", "pixel value")
        self.hist.setLabel("left", "pixels")
        self.hist.getAxis("left").enableAutoSIPrefix(False)  # counts, never "pixels (×0.001)"
        self.hist.setLimits(yMin=0)
        self.hist.setMaximumHeight(130)
        self.hist_curve = self.hist.plot([0, 1], [0], stepMode="center", fillLevel=0, brush=(90, 160, 255, 120))
        self.sat_line = pg.InfiniteLine(angle=90, pen=pg.mkPen((255, 60, 60), width=1, style=Qt.PenStyle.DashLine))
        self.hist.addItem(self.sat_line)
        self.preview_panel = ImagePanel("motion-aware preview")
        self.preview_panel.clear("starts with the live view")
        self.preview_label = StatusLine("preview: off", lines=3)
        preview_box = QWidget()
        pv = QVBoxLayout(preview_box)
        pv.setContentsMargins(0, 0, 0, 0)
        pv.addWidget(self.preview_panel, 1)
        pv.addWidget(self.preview_label)
        images = AdaptiveSplit(self.image_panel, preview_box)  # one above the other in a narrow view
        images.setSizes([500, 500])
        self.images = images
        views = QWidget(parent)
        rv = QVBoxLayout(views)
        rv.addWidget(images, 1)
        rv.addWidget(self.hist)
        self.views = views

        self.display_timer = QTimer(self)
        self.display_timer.setInterval(int(1000 / DISPLAY_HZ))
        self.display_timer.timeout.connect(self._redraw)
        self.live_button.toggled.connect(self._on_live_toggled)
        self.preview_check.toggled.connect(self._on_preview_toggled)
        self.preview_method.currentIndexChanged.connect(self._on_preview_method)
        self.preview.set_method(self.preview_method.currentData())

    # ------------------------------------------------------------------ live view
    @property
    def running(self) -> bool:
        """True while the live view runs."""
        return self.stream.running

    def _on_live_toggled(self, on: bool) -> None:
        now = self.clock()
        if now - self._toggled_at < DEBOUNCE_S:  # the second click of a double click
            self.set_button(self.running)
            return
        self._toggled_at = now
        if on:
            self.start()
        else:
            self.stop()
        # From the end of the action too: a busy machine may take longer than the debounce to start the live
        # view, and the second click of a double click is handled only then.
        self._toggled_at = self.clock()

    def start(self) -> bool:
        """Start the live view; False (with the reason shown) when it cannot start."""
        if self.stream.running:
            return True
        if not self.model.check(Action.LIVE):
            return False
        plan = self.model.plan
        try:
            note = start_live(self.service, plan, self.model.capture_calibration,
                              delay_set_by_hand=self.model.delay_set_by_hand)
        except LiveStartError as exc:
            self.model.refuse(Action.LIVE, f"cannot start: {in_gui_words(str(exc))}", Cause.DEVICE)
            return False
        self.model.take(Holder.LIVE)  # its refusal goes
        self.stats = LiveStats()
        self._latest = None
        self.stream.start(self.service.rig.camera, timeout_s=max(1.0, 3 / plan.camera_hz))
        self.display_timer.start()
        self.start_preview()
        self.live_label.setText(note or "waiting for frames …")
        self.image_panel.set_title("camera: live")
        self.set_button(True)
        return True

    def _on_refusal(self, action: Action, refusal) -> None:
        """Show the model's refusal of the live view; "stopped" once it no longer holds."""
        if action is not Action.LIVE:
            return
        if refusal is not None:
            self.live_label.setText(coloured(refusal.text, RED))
            self.set_button(False)
        elif not self.running:
            self.live_label.setText("stopped")

    def _on_holder(self, holder: Holder) -> None:
        """A recording takes the devices: the live view stops first (its reader and the capture's must not both read
        the camera)."""
        if holder is Holder.RECORDING and self.running:
            self.stop()

    def stop(self) -> None:
        """Stop the live view (devices stay connected)."""
        self.display_timer.stop()
        self.stop_preview()
        stopped = self.stream.stop()
        stop_live(self.service)
        self.model.release(Holder.LIVE)
        if stopped:
            self.live_label.setText(f"stopped · {self.stats.text()}")
        self.image_panel.set_title("camera: live view stopped")
        self.set_button(False)

    def restart(self) -> None:
        """Show the patterns of a new plan or calibration (when the live view runs)."""
        if self.stream.running:
            self.stop()
            self.start()

    def set_button(self, on: bool) -> None:
        """Put the button in the live view's state without acting on it."""
        self.live_button.blockSignals(True)
        self.live_button.setChecked(on)
        self.live_button.setText("Stop live view" if on else "Start live view")
        self.live_button.blockSignals(False)
        self.shown_running.emit(on)

    def _on_frame(self, frame) -> None:
        self.stats.update(frame)
        self._latest = frame
        self.preview.feed(frame)  # a list append; the reconstruction runs on the preview's own worker

    def _on_failed(self, message: str) -> None:
        message = in_gui_words(message)
        self.service.record_error("camera", f"live view: {message}")
        self.stop()
        self.live_label.setText(coloured(f"live view stopped: {message}", RED))

    # ------------------------------------------------------------------ a recording's frames
    def follow_capture(self, capture) -> None:
        """Show the frames a recording delivers (``capture.latest()``), with the preview."""
        self._capture = capture
        self._shown_seq = 0
        self.last_shown_id = None
        self.image_panel.set_title("recording: waiting for the first frame")
        self.start_preview()
        self.display_timer.start()

    def end_capture(self) -> None:
        """The recording ended: show its last frame and stop following it."""
        self._redraw()
        self.display_timer.stop()
        self.stop_preview()
        last = None if self.last_shown_id is None else self.frame_words(self.last_shown_id)
        self._capture = None
        self.image_panel.set_title("recording ended" if last is None else f"recording ended · last shown: {last}")

    def frame_words(self, frame_id: int) -> str:
        """A frame as the counters count it: during a recording its row ("frame 288 of 300"), else the camera's
        own number ("camera frame 3453")."""
        capture = self._capture
        first = None if capture is None else getattr(capture, "first_frame_id", None)
        if first is None:
            return f"camera frame {frame_id}"
        target = getattr(capture, "n_target", None)
        return f"frame {frame_id - first + 1}" + (f" of {target}" if target else "")

    # ------------------------------------------------------------------ drawing
    def _redraw(self) -> None:
        self._advance_preview()
        if self._capture is not None:
            f, seq = self._capture.latest()
            if f is None or seq == self._shown_seq:
                return
            self._shown_seq = seq
            self.preview.feed(f)
            self._show_frame(f, "recording")
            return
        f = self._latest
        if f is None:
            return
        self._latest = None
        self._show_frame(f, "camera")
        self.live_label.setText(self.stats.text())

    def _show_frame(self, f, what: str) -> None:
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
        self.last_shown_id = f.frame_id
        words = self.frame_words(f.frame_id)
        self.image_panel.set_title(f"{what}: {words.removeprefix('camera ')}" if what == "camera" else
                                   f"{what}: {words}")

    # ------------------------------------------------------------------ preview
    def _on_preview_toggled(self, on: bool) -> None:
        self.settings.set("capture/preview", on)
        if on and (self.stream.running or self._capture is not None):
            self.start_preview()
        elif not on:
            self.stop_preview()

    def _on_preview_method(self, _index: int) -> None:
        method = self.preview_method.currentData()
        self.settings.set("capture/preview_method", method)
        self.preview.set_method(method)
        self.region_roi.setVisible(False)  # the next run places its own region (or takes the whole frame)

    def start_preview(self) -> None:
        """Start the motion-aware preview of the plan's code (when its box is ticked)."""
        if not self.preview_check.isChecked():
            self.preview_label.setText("preview: off")
            return
        plan = self.model.plan
        try:
            code = plan.shutter_code
        except ValueError as exc:
            self.preview_label.setText(coloured(f"preview: {in_gui_words(str(exc))}", RED))
            return
        self.preview.set_code(code, plan.tile)
        self.preview.start()
        self._preview_index = 0
        self.preview_panel.clear("reconstructing the newest frames …")
        self.preview_panel.set_title(f"{self.preview.method} preview: waiting for frames")
        self.preview_label.setText(self.preview.text())

    def stop_preview(self) -> None:
        """Stop the preview (its last picture stays)."""
        was = self.preview.enabled
        self.preview.stop()
        self.region_roi.setVisible(False)
        if self.preview.result is None:  # it never showed a picture: it is not reconstructing anything now
            self.preview_panel.clear("starts with the live view")
            self.preview_panel.set_title(f"{self.preview.method} preview")
        if was:
            self.preview_label.setText(self.preview.text().replace(" preview", " preview (stopped)", 1)
                                       if self.preview.result is not None else "preview: off")

    def _on_preview(self, result) -> None:
        self._preview_index = 0
        self.preview_label.setText(html.escape(self.preview.text()))
        self._show_region(result)
        self._advance_preview()

    def _show_region(self, result) -> None:
        """Draw the preview's region on the live view (hidden when it is the whole frame)."""
        if result.whole_frame:
            self.region_roi.setVisible(False)
            return
        r = result.region
        self.region_roi.blockSignals(True)  # placing it is not the operator moving it
        self.region_roi.setPos((r.x0, r.y0), update=False)
        self.region_roi.setSize((r.x1 - r.x0, r.y1 - r.y0))
        self.region_roi.blockSignals(False)
        self.region_roi.maxBounds = QRectF(0, 0, result.frame_shape[1], result.frame_shape[0])
        self.region_roi.setVisible(True)

    def _on_region_moved(self) -> None:
        """The operator dragged the region: the next preview run takes it on there."""
        pos, size = self.region_roi.pos(), self.region_roi.size()
        self.preview.set_centre(pos.y() + size.y() / 2, pos.x() + size.x() / 2)

    def _advance_preview(self) -> None:
        r = self.preview.result
        if r is None:
            return
        K = r.video.shape[0]
        k = self._preview_index % K
        self._preview_index = k + 1
        self.preview_panel.set_image(r.video[k], levels=r.levels)
        where = "" if r.whole_frame else f" · region at ({r.region.x0}, {r.region.y0})"
        frame = self.frame_words(r.frame_id)
        self.preview_panel.set_title(f"{r.method} preview: {frame}, sub-frame {k + 1}/{K}{where}")

    def shutdown(self) -> bool:
        """Stop everything; False when the preview's worker did not stop within 5 s."""
        if self.stream.running:
            self.stop()
        self.display_timer.stop()
        return self.preview.shutdown(5000)
