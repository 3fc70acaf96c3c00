"""The method picker with its knobs and the SR ↔ TR continuum slider; produces a :class:`Method`."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QSlider,
    QSpinBox,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from app.gui.models.continuum import continuum_division, continuum_tensor, describe
from app.gui.widgets.settings import AppSettings
from flexvox_core.flow import BACKENDS
from flexvox_core.motion.pipeline import DEFAULT_TIME as MA_TIME
from flexvox_core.motion.pipeline import SLOW_REACH
from flexvox_core.reconstruct.diffusion import DEFAULT_TIME, SOLVERS
from flexvox_core.reconstruct.run import METHODS, Method

SLIDER_STEPS = 100
DEFAULT_POSITION = 0.18
"""Slider position of the default tensor (≈ (0.15, 0.15, 1))."""


def _spin(lo: float, hi: float, value: float, step: float, decimals: int = 2) -> QDoubleSpinBox:
    s = QDoubleSpinBox()
    s.setRange(lo, hi)
    s.setDecimals(decimals)
    s.setSingleStep(step)
    s.setValue(value)
    return s


class MethodForm(QWidget):
    """Method combo, per-method knobs and the continuum slider.

    Parameters
    ----------
    settings : AppSettings
        Where the choices persist (``review/...`` keys).
    """

    changed = Signal()
    """Any knob changed (the Review workspace re-plans its preview and expectation)."""

    def __init__(self, settings: AppSettings, parent: QWidget | None = None):
        super().__init__(parent)
        self.settings = settings
        self._divisions: list = []
        self.method_box = QComboBox()
        self.method_box.addItems(METHODS)
        self.stack = QStackedWidget()

        rebin = QWidget()
        f = QFormLayout(rebin)
        self.interpolate = QCheckBox("interpolate between block centres")
        self.interpolate.setChecked(settings.get_bool("review/interpolate", True))
        f.addRow(self.interpolate)
        self.stack.addWidget(rebin)

        diff = QWidget()
        f = QFormLayout(diff)
        self.time = _spin(0.05, 20, settings.get_float("review/time", DEFAULT_TIME), 0.25)
        self.time.setToolTip("diffusion time n: an accuracy knob, not a convergence tolerance")
        self.solver = QComboBox()
        self.solver.addItems(SOLVERS)
        self.solver.setCurrentText(settings.get_str("review/solver", "nc"))
        f.addRow("diffusion time n", self.time)
        f.addRow("solver", self.solver)
        self.stack.addWidget(diff)

        gap = QWidget()
        f = QFormLayout(gap)
        self.iterations = QSpinBox()
        self.iterations.setRange(1, 500)
        self.iterations.setValue(settings.get_int("review/iterations", 40))
        f.addRow("iterations", self.iterations)
        self.stack.addWidget(gap)

        ma = QWidget()
        f = QFormLayout(ma)
        self.flow = QComboBox()
        self.flow.addItems(BACKENDS)
        self.flow.setCurrentText(settings.get_str("review/flow", "dis"))
        self.ma_time = _spin(0.25, 20, settings.get_float("review/ma_time", MA_TIME), 0.5)
        self.refine = _spin(0, 10, settings.get_float("review/refine", 0.0), 0.5)
        self.passes = QSpinBox()
        self.passes.setRange(1, 4)
        self.passes.setValue(settings.get_int("review/passes", 1))
        self.slow_reach = _spin(0, 4, settings.get_float("review/slow_reach", SLOW_REACH), 0.25)
        self.slow_reach.setToolTip("how far slowly moving voxels gather samples along their trajectory, in "
                                   "sampling periods each way (0: off, faster where the whole picture drifts)")
        f.addRow("optical flow", self.flow)
        f.addRow("diffusion time n", self.ma_time)
        f.addRow("refinement time", self.refine)
        f.addRow("passes", self.passes)
        f.addRow("slow-drift reach", self.slow_reach)
        self.stack.addWidget(ma)

        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, SLIDER_STEPS)
        self.slider.setValue(round(settings.get_float("review/continuum", DEFAULT_POSITION) * SLIDER_STEPS))
        self.slider.setToolTip("from high spatial resolution (left) to high temporal resolution (right)")
        ends = QHBoxLayout()
        ends.addWidget(QLabel("high SR"))
        ends.addWidget(self.slider, 1)
        ends.addWidget(QLabel("high TR"))
        self.slider_text = QLabel()
        self.slider_text.setWordWrap(True)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        top = QFormLayout()
        top.addRow("method", self.method_box)
        layout.addLayout(top)
        layout.addLayout(ends)
        layout.addWidget(self.slider_text)
        layout.addWidget(self.stack)

        self.method_box.setCurrentText(settings.get_str("review/method", "diffusion"))
        self.stack.setCurrentIndex(self.method_box.currentIndex())
        for w, sig in ((self.method_box, "currentIndexChanged"), (self.slider, "valueChanged"),
                       (self.interpolate, "toggled"), (self.time, "valueChanged"),
                       (self.solver, "currentIndexChanged"), (self.iterations, "valueChanged"),
                       (self.flow, "currentIndexChanged"), (self.ma_time, "valueChanged"),
                       (self.refine, "valueChanged"), (self.passes, "valueChanged"),
                       (self.slow_reach, "valueChanged")):
            getattr(w, sig).connect(self._on_change)
        self._refresh()

    # ------------------------------------------------------------------ state
    @property
    def position(self) -> float:
        """Continuum slider position p in [0, 1] (0 = high SR, 1 = high TR)."""
        return self.slider.value() / SLIDER_STEPS

    def set_position(self, p: float) -> None:
        """Move the continuum slider."""
        self.slider.setValue(round(p * SLIDER_STEPS))

    def set_method_name(self, name: str) -> None:
        """Pick a method by name."""
        if name not in METHODS:
            raise ValueError(f"`name` must be one of {', '.join(METHODS)}; got {name!r}")
        self.method_box.setCurrentText(name)

    def set_divisions(self, divisions) -> None:
        """The divisions the current recording's code supports (re-binning's choices)."""
        self._divisions = list(divisions)
        self._refresh()

    def method(self) -> Method:
        """The :class:`Method` the form describes."""
        name = self.method_box.currentText()
        if name == "rebin":
            block = continuum_division(self.position, self._divisions) if self._divisions else None
            return Method("rebin", block=block, interpolate=self.interpolate.isChecked())
        if name == "gap-tv":
            return Method("gap-tv", iterations=self.iterations.value())
        if name == "motion-aware":
            reach = self.slow_reach.value()
            return Method("motion-aware", flow=self.flow.currentText(), time=self.ma_time.value(),
                          refine_time=self.refine.value(), passes=self.passes.value(),
                          slow_reach=None if reach == SLOW_REACH else reach)
        return Method("diffusion", tensor=continuum_tensor(self.position), time=self.time.value(),
                      solver=self.solver.currentText())

    # ------------------------------------------------------------------ reactions
    def _on_change(self, *_):
        self.stack.setCurrentIndex(self.method_box.currentIndex())
        s = self.settings
        s.set("review/method", self.method_box.currentText())
        s.set("review/continuum", self.position)
        s.set("review/interpolate", self.interpolate.isChecked())
        s.set("review/time", self.time.value())
        s.set("review/solver", self.solver.currentText())
        s.set("review/iterations", self.iterations.value())
        s.set("review/flow", self.flow.currentText())
        s.set("review/ma_time", self.ma_time.value())
        s.set("review/refine", self.refine.value())
        s.set("review/passes", self.passes.value())
        s.set("review/slow_reach", self.slow_reach.value())
        self._refresh()
        self.changed.emit()

    def _refresh(self) -> None:
        name = self.method_box.currentText()
        slider_used = name in ("rebin", "diffusion")
        self.slider.setEnabled(slider_used)
        if name == "rebin":
            if self._divisions:
                d = continuum_division(self.position, self._divisions)
                self.slider_text.setText(f"division {d.label}: TR ×{d.tr}, SR ×{d.sr} "
                                         f"({len(self._divisions)} supported divisions along the slider)")
            else:
                self.slider_text.setText("open a recording to see its divisions")
        elif name == "diffusion":
            self.slider_text.setText(describe(self.position))
        elif name == "gap-tv":
            self.slider_text.setText("GAP-TV has no space-time knob (the slider applies to rebin and diffusion)")
        else:
            self.slider_text.setText("motion-aware chooses the trade per voxel from the flow: "
                                     "high SR where still, high TR where moving")
