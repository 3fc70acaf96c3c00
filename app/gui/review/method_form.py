"""The method picker with its knobs and the SR ↔ TR continuum slider; produces a :class:`Method`.

The form is built from the registered method objects (:mod:`flexvox_core.methods.registry`): one
page per method with a widget per option, chosen by the option's kind (check box, combo box, spin
box). Options of kind ``triple`` (the diffusion tensor) and ``division`` (re-binning's block) are
set by the continuum slider instead. For a method without one (motion-aware chooses the trade per
voxel, GAP-TV has none) the slider stays usable: moving it previews the fixed diffusion tensor at that
position beside the chosen method (:meth:`MethodForm.preview_method`), for comparison, without
switching method; Reconstruct still runs the chosen method.
"""

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
from app.gui.widgets.collapsible import Collapsible
from app.gui.widgets.settings import AppSettings
from app.gui.widgets.status_line import StatusLine
from flexvox_core.methods import DEFAULT, Method, Option, get, names, specs

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


SLIDER_KINDS = ("triple", "division")
"""Option kinds the continuum slider sets (the diffusion tensor, re-binning's division)."""


class _Knob:
    """One option's widget on a method's page, and how it reads, shows and persists its value."""

    def __init__(self, option: Option, settings: AppSettings, key: str):
        self.option, self.settings, self.key = option, settings, key
        o = option
        if o.kind == "flag":
            self.widget = QCheckBox(o.label or o.name)
            self.widget.setChecked(settings.get_bool(key, bool(o.default)))
            self.signal = self.widget.toggled
        elif o.kind == "choice":
            self.widget = QComboBox()
            self.widget.addItems([str(c) for c in o.choices])
            self.widget.setCurrentText(settings.get_str(key, str(o.default)))
            self.signal = self.widget.currentIndexChanged
        elif o.kind == "integer":
            lo, hi, _ = o.span or (1, 1000, 1)
            self.widget = QSpinBox()
            self.widget.setRange(int(lo), int(hi))
            self.widget.setValue(settings.get_int(key, int(o.default)))
            self.signal = self.widget.valueChanged
        elif isinstance(o.shown_default, str) and o.default is None:
            # A default that depends on the capture (motion-aware's refinement: (K/16)²) is a choice of
            # its own, one step below the range, shown in words; every number in the range means itself.
            # Its own settings key: a value stored before (where the number shown stood for the default)
            # must not come back as that number.
            lo, hi, step = o.span or (0.0, 100.0, 0.1)
            self.key = key = f"{key}-or-default"
            self.floor = lo
            self.widget = _spin(lo - step, hi, settings.get_float(key, lo - step), step)
            self.widget.setSpecialValueText(f"default ({o.shown_default})")
            self.signal = self.widget.valueChanged
        else:
            lo, hi, step = o.span or (0.0, 100.0, 0.1)
            shown = o.shown_default if o.default is None else o.default
            self.widget = _spin(lo, hi, settings.get_float(key, float(lo if shown is None else shown)), step)
            self.signal = self.widget.valueChanged
        self.widget.setToolTip(o.help)

    def value(self):
        """The option's value (a number equal to ``shown_default``, or the "default (…)" choice below the
        range, or any number typed below the range, stands for a None default)."""
        w, o = self.widget, self.option
        if o.kind == "flag":
            return w.isChecked()
        if o.kind == "choice":
            return w.currentText()
        value = w.value()
        if o.default is None and (value == o.shown_default
                                  or isinstance(o.shown_default, str) and value < self.floor):
            return None  # the default, or a number typed below the range: the default too
        return value

    def save(self) -> None:
        w, o = self.widget, self.option
        if o.kind == "flag":
            self.settings.set(self.key, w.isChecked())
        elif o.kind == "choice":
            self.settings.set(self.key, w.currentText())
        else:
            self.settings.set(self.key, w.value())


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
        self._comparing = False
        self._beside = False
        self.method_box = QComboBox()
        self.method_box.addItems(names())
        self.stack = QStackedWidget()
        self._knobs: dict[str, dict[str, _Knob]] = {}
        for spec in specs():
            page = QWidget()
            f = QFormLayout(page)
            knobs = {}
            for o in spec.options:
                if o.kind in SLIDER_KINDS:
                    continue
                knob = knobs[o.name] = _Knob(o, settings, f"review/{spec.name}/{o.name}")
                if o.kind == "flag":
                    f.addRow(knob.widget)
                else:
                    f.addRow(o.label or o.name, knob.widget)
            if not knobs:
                f.addRow(QLabel("no knobs besides the slider"))
            self._knobs[spec.name] = knobs
            self.stack.addWidget(page)

        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, SLIDER_STEPS)
        self.slider.setValue(round(settings.get_float("review/continuum", DEFAULT_POSITION) * SLIDER_STEPS))
        self.slider.setToolTip("from high spatial resolution (left) to high temporal resolution (right)")
        ends = QHBoxLayout()
        ends.addWidget(QLabel("high SR"))
        ends.addWidget(self.slider, 1)
        ends.addWidget(QLabel("high TR"))
        self.slider_text = StatusLine(lines=2)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        top = QFormLayout()
        top.addRow("method", self.method_box)
        layout.addLayout(top)
        layout.addLayout(ends)
        layout.addWidget(self.slider_text)
        self.options = Collapsible("method options", self.stack, settings=settings, key="review/show_options")
        """The chosen method's knobs, folded (the workspace places it below its actions)."""

        self.method_box.setCurrentText(settings.get_str("review/method", DEFAULT))
        self.stack.setCurrentIndex(self.method_box.currentIndex())
        self.method_box.currentIndexChanged.connect(self._on_method)
        self.slider.valueChanged.connect(self._on_slider)
        for knobs in self._knobs.values():
            for knob in knobs.values():
                knob.signal.connect(self._on_knob)
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
        get(name)  # ValueError naming the registered methods
        self.method_box.setCurrentText(name)

    def set_divisions(self, divisions) -> None:
        """The divisions the current recording's code supports (re-binning's choices)."""
        self._divisions = list(divisions)
        self._refresh()

    def widget(self, option: str, method: str | None = None) -> QWidget:
        """The widget of ``option`` on ``method``'s page (default: the chosen method's)."""
        name = method or self.method_box.currentText()
        knobs = self._knobs[get(name).name]
        if option not in knobs:
            raise ValueError(f"{name} has no widget for {option!r} (its widgets: {', '.join(knobs) or 'none'}; "
                             "the slider sets the tensor or division)")
        return knobs[option].widget

    def method(self) -> Method:
        """The :class:`Method` the form describes (what Reconstruct runs)."""
        return self._method_for(self.method_box.currentText())

    @property
    def comparing(self) -> bool:
        """True when the slider was moved for a method without a tensor or division: the preview then shows
        the fixed diffusion tensor at the slider's position (see :meth:`preview_method`)."""
        return self._comparing

    def preview_method(self) -> Method:
        """What the live preview shows: the chosen method, or the fixed diffusion tensor at the slider's
        position while :attr:`comparing`."""
        return self._method_for("diffusion") if self._comparing else self.method()

    def _method_for(self, name: str) -> Method:
        spec = get(name)
        values = {name: knob.value() for name, knob in self._knobs[spec.name].items()}
        for o in spec.options:
            if o.kind == "triple":
                values[o.name] = continuum_tensor(self.position)
            elif o.kind == "division":
                values[o.name] = continuum_division(self.position, self._divisions) if self._divisions else None
        return Method(spec.name, **values)

    # ------------------------------------------------------------------ reactions
    def _has_slider(self) -> bool:
        return bool({o.kind for o in get(self.method_box.currentText()).options} & set(SLIDER_KINDS))

    def _on_method(self, *_):
        self._comparing = False
        self._on_change()

    def _on_knob(self, *_):
        self._comparing = False
        self._on_change()

    def _on_slider(self, *_):
        self._comparing = not self._has_slider()
        self._on_change()

    def set_beside(self, beside: bool) -> None:
        """Whether the chosen method has a full result for the slider's preview to stand beside (the line under the
        slider says which)."""
        if bool(beside) != self._beside:
            self._beside = bool(beside)
            self._refresh()

    def stop_comparing(self) -> None:
        """Preview the chosen method again (after the slider previewed a fixed tensor)."""
        if self._comparing:
            self._comparing = False
            self._on_change()

    def _on_change(self, *_):
        self.stack.setCurrentIndex(self.method_box.currentIndex())
        self.settings.set("review/method", self.method_box.currentText())
        self.settings.set("review/continuum", self.position)
        for knobs in self._knobs.values():
            for knob in knobs.values():
                knob.save()
        self._refresh()
        self.changed.emit()

    def _refresh(self) -> None:
        spec = get(self.method_box.currentText())
        kinds = {o.kind for o in spec.options}
        if "division" in kinds:
            if self._divisions:
                d = continuum_division(self.position, self._divisions)
                self.slider_text.setText(f"division {d.label}: TR ×{d.tr}, SR ×{d.sr} "
                                         f"({len(self._divisions)} supported divisions along the slider)")
            else:
                self.slider_text.setText("open a recording to see its divisions")
        elif "triple" in kinds:
            self.slider_text.setText(describe(self.position))
        elif self._comparing and self._beside:
            self.slider_text.setText(f"previewing diffusion, {describe(self.position)}, beside the {spec.name} "
                                     f"result for comparison; Reconstruct runs {spec.name}")
        elif self._comparing:
            self.slider_text.setText(f"previewing diffusion, {describe(self.position)}, in place of {spec.name} (no "
                                     f"{spec.name} result to set it beside yet); Reconstruct runs {spec.name}")
        else:
            self.slider_text.setText(f"{spec.trade}; the slider previews a fixed tensor for comparison")
