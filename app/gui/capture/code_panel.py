"""The Capture workspace's code and timing: which code, how fast, and whether the projector accepts it.

The plan is a :class:`flexvox_app.capture.plan.CapturePlan` (the one ``flexvox capture`` builds): a tile's
designed identity code, its S-matrix multiplexed code, or a ``flexvox design -o`` file; the
camera rate and exposure; the pattern exposure. The panel is a view over the
:class:`~flexvox_app.gui.models.capture_model.CaptureModel`: each change of its controls sets the model's plan
(:meth:`~flexvox_app.gui.models.capture_model.CaptureModel.set_plan`, which says so through ``plan_changed``).
"""

from __future__ import annotations

import html
from functools import cache
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QRadioButton,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.capture.plan import TILES, CapturePlan
from flexvox_app.gui.models.capture_model import CaptureModel
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.widgets.collapsible import Collapsible
from flexvox_app.gui.widgets.rich_text import AMBER, GREEN, RED
from flexvox_app.gui.widgets.settings import AppSettings

MULTIPLEXED_TIP = ("S-matrix code (K = 3, 7, 15: 1x3, 1x7, 3x5), each pixel open in (K+1)/2 slots, "
                   "reconstructed from its own forward model: it pays in dim light only (balls, 3x5 tile, "
                   "bench_multiplex_light.py: +1.4 to +7.6 dB over the identity code at 50 electrons per unit or "
                   "fewer, 150 with 10 e- read noise) and loses 0.5 to 3.1 dB in brighter light")
"""The multiplexed choice's tooltip: where multiplexing wins (docs/reconstruction.md, "Multiplexed codes")."""


@cache
def no_s_matrix(K: int) -> str:
    """Why no S-matrix code of K slots exists ("" when one does)."""
    from flexvox_core.multiplex import s_matrix

    try:
        s_matrix(int(K))
    except ValueError as exc:
        return str(exc)
    return ""


class CodePanel(QWidget):
    """The "Shutter code" and "Camera and projector timing" boxes.

    Parameters
    ----------
    settings : AppSettings
        Remembers the choices between sessions.
    model : CaptureModel
        Holds the plan the controls describe.
    """

    def __init__(self, settings: AppSettings, model: CaptureModel, parent: QWidget | None = None):
        super().__init__(parent)
        self.settings = settings
        self.model = model
        self.code_file: Path | None = None
        """The ``flexvox design -o`` file in use (None: the tile's code)."""
        self._file_code = None
        self.file_error = ""
        code = QGroupBox("Shutter code")
        self.tile_box = QComboBox()
        for m, n in TILES:
            self.tile_box.addItem(f"{m}×{n} (K = {m * n})", f"{m}x{n}")
        saved = settings.get_str("capture/tile", "4x4")
        idx = self.tile_box.findData(saved)
        self.tile_box.setCurrentIndex(idx if idx >= 0 else TILES.index((4, 4)))
        self.identity = QRadioButton("identity (one slot per pixel)")
        self.multiplexed = QRadioButton("multiplexed (S-matrix)")
        self.multiplexed.setToolTip(MULTIPLEXED_TIP)
        (self.multiplexed if settings.get_bool("capture/multiplexed", False) else self.identity).setChecked(True)
        self.file_button = QPushButton("Code from file…")
        self.file_button.setToolTip("a code written by flexvox design -o (identity or multiplexed)")
        self.tile_code_button = QPushButton("Use the tile's code")
        self.tile_code_button.setEnabled(False)
        file_row = QHBoxLayout()
        file_row.addWidget(self.file_button)
        file_row.addWidget(self.tile_code_button)
        self.code_label = QLabel()
        self.code_label.setWordWrap(True)
        self.code_label.setTextFormat(Qt.TextFormat.RichText)
        self.resolutions_label = QLabel()
        self.resolutions_label.setWordWrap(True)
        self.resolutions_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(code)
        f.addRow("tile", self.tile_box)
        f.addRow(self.identity)
        f.addRow(self.multiplexed)
        f.addRow(file_row)
        f.addRow(self.code_label)
        self.resolutions = Collapsible("[TR, SR] after capture", self.resolutions_label, settings=settings,
                                       key="capture/show_resolutions")
        f.addRow(self.resolutions)

        timing = QGroupBox("Camera and projector timing")
        self.rate = QDoubleSpinBox()
        self.rate.setRange(0.5, 1000)
        self.rate.setDecimals(2)
        self.rate.setSuffix(" Hz")
        self.rate.setValue(settings.get_float("capture/camera_hz", 15.0))
        self.auto_exposure = QCheckBox("auto exposure: one sequence less read-out")
        self.auto_exposure.setToolTip("camera exposure = one sequence (K × period) less 300 µs read-out")
        self.auto_exposure.setChecked(settings.get_bool("capture/auto_exposure", True))
        self.exposure = QDoubleSpinBox()
        self.exposure.setRange(10, 10_000_000)
        self.exposure.setDecimals(0)
        self.exposure.setSuffix(" µs")
        self.exposure.setValue(settings.get_float("capture/exposure_us", 66_656))
        self.projector_exposure = QDoubleSpinBox()
        self.projector_exposure.setRange(0, 10_000_000)
        self.projector_exposure.setDecimals(0)
        self.projector_exposure.setSuffix(" µs")
        self.projector_exposure.setSpecialValueText("= period (video port)")
        self.projector_exposure.setValue(settings.get_float("capture/projector_exposure_us", 0))
        self.timing_label = QLabel()
        self.timing_label.setWordWrap(True)
        self.timing_label.setTextFormat(Qt.TextFormat.RichText)
        f = QFormLayout(timing)
        f.addRow("camera rate", self.rate)
        f.addRow(self.auto_exposure)
        f.addRow("camera exposure", self.exposure)
        f.addRow("pattern exposure", self.projector_exposure)
        f.addRow(self.timing_label)

        v = QVBoxLayout(self)
        v.setContentsMargins(0, 0, 0, 0)
        v.addWidget(code)
        v.addWidget(timing)
        for sig in (self.tile_box.currentIndexChanged, self.identity.toggled, self.rate.valueChanged,
                    self.auto_exposure.toggled, self.exposure.valueChanged, self.projector_exposure.valueChanged):
            sig.connect(self._on_changed)
        self.file_button.clicked.connect(self._ask_code_file)
        self.tile_code_button.clicked.connect(self.use_tile_code)
        self._on_changed()

    # ------------------------------------------------------------------ the plan
    def plan(self) -> CapturePlan:
        """The plan in use (the model's, which the controls describe)."""
        return self.model.plan

    def _described(self) -> CapturePlan:
        """The plan the controls describe."""
        pe = int(self.projector_exposure.value())
        timing = dict(camera_hz=self.rate.value(),
                      camera_exposure_us=None if self.auto_exposure.isChecked() else self.exposure.value(),
                      projector_exposure_us=pe or None)
        if self._file_code is not None:
            return CapturePlan.from_code(self._file_code, code_file=self.code_file, **timing)
        return CapturePlan(tile=self.tile(), multiplexed=self.multiplexed.isChecked(), **timing)

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

    def load_code_file(self, path) -> bool:
        """Use the code of a ``flexvox design -o`` file; False (with the reason shown, the code kept) when refused."""
        from flexvox_core.code_file import CodeFileError, load_shutter_code

        path = Path(path).expanduser()
        try:
            code = load_shutter_code(path)
        except CodeFileError as exc:
            self.file_error = in_gui_words(str(exc))
            self._on_changed()
            return False
        self.code_file, self._file_code, self.file_error = path, code, ""
        self.settings.remember_folder(path, "capture/code_dir")
        self._on_changed()
        return True

    def use_tile_code(self) -> None:
        """Back to the tile's designed (or multiplexed) code."""
        self.code_file, self._file_code, self.file_error = None, None, ""
        self._on_changed()

    def _ask_code_file(self) -> None:
        start = self.settings.last_folder("capture/code_dir")
        path, _ = QFileDialog.getOpenFileName(self, "Code from file", start, "flexvox codes (*.json)")
        if path:
            self.load_code_file(path)

    def set_locked(self, locked: bool) -> None:
        """Grey the controls out while a recording runs."""
        from_file = self._file_code is not None
        for w in (self.rate, self.auto_exposure, self.projector_exposure, self.file_button):
            w.setEnabled(not locked)
        for w in (self.tile_box, self.identity, self.multiplexed):
            w.setEnabled(not locked and not from_file)
        m, n = self.tile()
        reason = no_s_matrix(m * n)
        if reason:
            self.multiplexed.setEnabled(False)
        self.multiplexed.setText(f"multiplexed (S-matrix): none for K = {m * n}" if reason else
                                 "multiplexed (S-matrix)")
        self.multiplexed.setToolTip(f"not for this tile: {reason}" if reason else MULTIPLEXED_TIP)
        self.tile_code_button.setEnabled(not locked and from_file)
        self.exposure.setEnabled(not locked and not self.auto_exposure.isChecked())

    # ------------------------------------------------------------------ what the controls say
    def _on_changed(self, *_) -> None:
        m, n = self.tile()
        if self.multiplexed.isChecked() and no_s_matrix(m * n):  # none for this tile: the identity code, said
            for b in (self.identity, self.multiplexed):
                b.blockSignals(True)
            self.identity.setChecked(True)
            for b in (self.identity, self.multiplexed):
                b.blockSignals(False)
        s = self.settings
        s.set("capture/tile", f"{m}x{n}")
        s.set("capture/multiplexed", self.multiplexed.isChecked())
        s.set("capture/camera_hz", self.rate.value())
        s.set("capture/auto_exposure", self.auto_exposure.isChecked())
        s.set("capture/exposure_us", self.exposure.value())
        s.set("capture/projector_exposure_us", self.projector_exposure.value())
        self.set_locked(False)
        plan = self._described()
        lines = []
        try:
            lines.append(html.escape(plan.code_summary()))
            rows = "".join(f"<tr><td>{d.label}</td><td align='right'>{d.tr}</td><td align='right'>{d.sr}</td></tr>"
                           for d in plan.resolutions())
            self.resolutions_label.setText(
                "<table cellspacing='6'><tr><th>block</th><th>TR</th><th>SR</th></tr>"
                f"{rows}</table>")
        except ValueError as exc:
            lines.append(f"<span style='color:{RED}'>{html.escape(in_gui_words(str(exc)))}</span>")
            self.resolutions_label.setText("")
        if self.file_error:
            lines.append(f"<span style='color:{RED}'>refused: {html.escape(self.file_error)}</span>")
        self.code_label.setText("<br>".join(lines))
        t = plan.timing()
        if self.auto_exposure.isChecked():
            self.exposure.blockSignals(True)
            self.exposure.setValue(t.camera_exposure_us)
            self.exposure.blockSignals(False)
        lines = [f"pattern period {t.period_us} µs, exposure {t.projector_exposure_us} µs; "
                 f"{plan.K} patterns = {t.sequence_us / 1000:.3f} ms per camera frame"]
        lines += [f"<span style='color:{RED}'>✗ {html.escape(e)}</span>" for e in t.errors]
        lines += [f"<span style='color:{AMBER}'>• {html.escape(n)}</span>" for n in t.notes]
        if t.ok:
            lines.insert(1, f"<span style='color:{GREEN}'>✓ the projector accepts this timing "
                            "(exposure = period, or ≤ period − 230 µs)</span>")
        self.timing_label.setText("<br>".join(lines))
        self.model.set_plan(plan)
