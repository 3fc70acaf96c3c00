"""The Calibrate workspace's results: every step's numbers and verdict, the homography's residual map, the
shutter's map of wrong pixels, the sync leakage and delay sweep, and the live co-location view, as tabs."""

from __future__ import annotations

import html

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QScrollArea, QTabWidget, QVBoxLayout, QWidget

from flexvox_app.gui.calibrate.colocation_view import ColocationView
from flexvox_app.gui.models.calibration_model import CalibrationOutcome, summary_rows, verdict
from flexvox_app.gui.widgets.image_panel import ImagePanel
from flexvox_app.gui.widgets.rich_text import AMBER, GREEN, GREY, RED

UNDECODED_RGBA = (60, 60, 90, 255)
WRONG_RGB = (230, 40, 40)
RIGHT_RGB = (70, 110, 70)


def _colour(good: bool | None) -> str:
    return GREY if good is None else (GREEN if good else RED)


def results_html(outcome: CalibrationOutcome, note: str = "") -> str:
    """The results page (rich text): one table per step with its verdict and message; ``note`` first (in amber)
    when these results are not the newest run's."""
    parts = [f"<p style='color:{AMBER}'><b>{html.escape(note)}</b></p>"] if note else []
    when = f" at {outcome.finished_at}" if outcome.finished_at else ""
    if outcome.success:
        said = f"calibration succeeded in {outcome.seconds:.1f} s{when}"
        then = ": save it, or use it for capture"
    else:
        said = f"calibration stopped after {outcome.seconds:.1f} s{when}: the {outcome.report.get('failed', 'last')} " \
               "step failed"
        then = ""
    parts.append(f"<p><b style='color:{GREEN if outcome.success else RED}'>{html.escape(said)}</b>"
                 f"{html.escape(then)}</p>")
    for title, figures, status, message in summary_rows(outcome):
        word, good = verdict(status)
        rows = "".join(f"<tr><td>{html.escape(k)}</td><td><b>{html.escape(v)}</b></td></tr>" for k, v in figures)
        parts.append(f"<h3>{html.escape(title)} <span style='color:{_colour(good)}'>{html.escape(word)}</span></h3>"
                     f"<table cellspacing='4'>{rows}</table><p>{html.escape(message)}</p>")
    for note in outcome.notes:
        parts.append(f"<p style='color:{GREY}'>Note: {html.escape(note)}.</p>")
    return "".join(parts)


class ResultsView(QTabWidget):
    """Tabs: Results, (homography) Residuals, Shutter (wrong pixels), Sync (leakage, delay sweep), Co-location live."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.results = QLabel("<p>Run the calibration: co-location check, homography, shutter masks, "
                              "synchronisation, drops and drift. The figures appear here.</p>")
        self.results.setWordWrap(True)
        self.results.setTextFormat(Qt.TextFormat.RichText)
        self.results.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
        self.results.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.results.setContentsMargins(12, 8, 12, 8)
        results_scroll = QScrollArea()
        results_scroll.setWidget(self.results)
        results_scroll.setWidgetResizable(True)

        self.residuals = ImagePanel("homography residuals: not measured yet", colormap="inferno")
        self.wrong_panel = ImagePanel("shutter: not verified yet")
        self.leakage_plot = pg.PlotWidget(title="leakage: light of each slot that reached the exposure (delay 0)")
        self.leakage_plot.setBackground("#202020")
        self.leakage_plot.setLabel("bottom", "projected slot")
        self.leakage_plot.setLabel("left", "fraction of the slot's light")
        self.leakage_bars = pg.BarGraphItem(x=[], height=[], width=0.8, brush=(90, 160, 255, 200))
        self.leakage_plot.addItem(self.leakage_bars)
        self.sweep_plot = pg.PlotWidget(title="delay sweep: slots of light lost against the camera delay")
        self.sweep_plot.setBackground("#202020")
        self.sweep_plot.setLabel("bottom", "camera trigger delay (µs)")
        self.sweep_plot.setLabel("left", "slots lost")
        self.sweep_points = self.sweep_plot.plot([], [], pen=None, symbol="o", symbolBrush=(255, 200, 80))
        self.sweep_fit = self.sweep_plot.plot([], [], pen=pg.mkPen((120, 200, 255), width=1))
        sync_page = QWidget()
        sv = QVBoxLayout(sync_page)
        sv.addWidget(self.leakage_plot)
        sv.addWidget(self.sweep_plot)
        self.colocation_view = ColocationView()
        self.addTab(results_scroll, "Results")
        self.addTab(self.residuals, "Residuals")
        self.addTab(self.wrong_panel, "Shutter")
        self.addTab(sync_page, "Sync")
        self.addTab(self.colocation_view, "Co-location")
        self.setTabToolTip(self.count() - 1, "co-location live: the camera with the projector's grid, while you "
                                             "adjust the beam splitter")

    def show_message(self, text: str) -> None:
        """Say ``text`` on the results page instead of a run's results."""
        self.results.setText(f"<p>{html.escape(text)}</p>")

    def show_outcome(self, outcome: CalibrationOutcome, *, note: str = "") -> None:
        """Show a run's figures, maps and plots (``note``: why these are not the newest run's)."""
        self.results.setText(results_html(outcome, note))
        hom = outcome.homography
        if hom is not None and np.isfinite(hom.residual_map).any():
            rmap = hom.residual_map
            finite = np.isfinite(rmap)
            top = float(np.percentile(rmap[finite], 99.5)) or 1.0
            self.residuals.set_image(np.where(finite, rmap, 0.0).astype(np.float32), levels=(0.0, top))
            over = np.zeros((*rmap.shape, 4), np.uint8)
            over[~finite] = UNDECODED_RGBA
            self.residuals.set_overlay(over)
            self.residuals.set_title(f"homography residual |H(projector point) − camera pixel| (px): RMS "
                                     f"{hom.rms_px:.3f} px, {hom.coverage:.1%} decoded, {hom.inliers} inliers "
                                     "(blue-grey: not decoded)")
        else:
            self.residuals.clear("no homography fit")
            self.residuals.set_title("homography residuals: no fit")
        ver = outcome.shutter
        if ver is not None:
            rgb = np.zeros((*ver.wrong.shape, 3), np.uint8)
            rgb[ver.decodable] = RIGHT_RGB
            rgb[ver.wrong] = WRONG_RGB
            self.wrong_panel.set_image(rgb)
            self.wrong_panel.set_title(f"shutter: {int(ver.wrong.sum())} camera pixels see another slot (red) of "
                                       f"{int(ver.decodable.sum())} decodable (green); accuracy {ver.accuracy:.3%}")
        else:
            self.wrong_panel.clear("the run stopped before the shutter step")
            self.wrong_panel.set_title("shutter: not verified")
        sync = outcome.sync
        if sync is not None and sync.leakage:
            k = np.arange(len(sync.leakage))
            self.leakage_bars.setOpts(x=k, height=np.asarray(sync.leakage), width=0.8)
        else:
            self.leakage_bars.setOpts(x=[], height=[], width=0.8)
        if sync is not None and sync.sweep:
            d = np.array([p[0] for p in sync.sweep])
            lost = np.array([p[1] for p in sync.sweep])
            self.sweep_points.setData(d, lost)
            if np.isfinite(sync.slope) and np.isfinite(sync.offset_slots):
                self.sweep_fit.setData(d, sync.offset_slots + sync.slope * d / sync.period_us)
            else:
                self.sweep_fit.setData([], [])
        else:
            self.sweep_points.setData([], [])
            self.sweep_fit.setData([], [])
