"""The method picker with its knobs and the SR ↔ TR continuum slider; produces a :class:`Method`.

One page per registered method (:mod:`flexvox_core.methods.registry`), each the shared options form
(:class:`~flexvox_app.gui.widgets.options_form.OptionsForm`, a field per option by its kind; the napari plugin shows
the same). The options the continuum slider sets stay off the pages: a ``triple`` (the diffusion tensor, at
the slider's position) and a ``division`` (re-binning's block: the recording's divisions along the slider).
For a method without one (motion-aware chooses the trade per voxel, GAP-TV has none) the slider stays usable:
moving it previews the fixed diffusion tensor at that position beside the chosen method
(:meth:`MethodForm.preview_method`), for comparison, without switching method; Reconstruct still runs the
chosen method.

Below the slider, "choose … by the estimate" (with ``offer_auto``) offers ``auto`` for a knob with default candidates
(:data:`flexvox_core.choice.AUTO_KNOBS`: diffusion's time, re-binning's division): checked, Reconstruct is to try
each candidate and keep the one with the best PSNR estimated from the recording alone (:meth:`MethodForm.auto_knob`,
:func:`flexvox_app.gui.models.choice_job.run_choice`, off the GUI thread as every job). It is enabled only where
the estimate offers the method (:func:`flexvox_core.accuracy.refusal`); elsewhere its tool tip says why.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QSlider,
    QStackedWidget,
    QVBoxLayout,
    QWidget,
)

from flexvox_app.gui.models.continuum import continuum_division, continuum_tensor, describe
from flexvox_app.gui.widgets.collapsible import Collapsible
from flexvox_app.gui.widgets.options_form import OptionsForm
from flexvox_app.gui.widgets.settings import AppSettings
from flexvox_app.gui.widgets.status_line import StatusLine
from flexvox_core.methods import DEFAULT, Method, get, names, specs
from flexvox_core.methods.option_kinds import DIVISION, TRIPLE

SLIDER_STEPS = 100
DEFAULT_POSITION = 0.18
"""Slider position of the default tensor: at this step the slider gives diffusion's default tensor (0.15, 0.15, 1)
itself, the one the bench measures, not the continuum's (0.147, 0.147, 1) nearby."""
DEFAULT_STEP = round(DEFAULT_POSITION * SLIDER_STEPS)

SLIDER_KINDS = (TRIPLE, DIVISION)
"""Option kinds the continuum slider sets (the diffusion tensor, re-binning's division)."""


class MethodForm(QWidget):
    """Method combo, per-method knobs and the continuum slider.

    Parameters
    ----------
    settings : AppSettings
        Where the choices persist (``review/...`` keys).
    offer_auto : bool
        Show "choose … by the estimate (auto)" (:meth:`auto_knob`): for a workspace whose Reconstruct runs the
        choice (:func:`~flexvox_app.gui.models.choice_job.run_choice`) when it names a knob.
    """

    changed = Signal()
    """Any knob changed (the Review workspace re-plans its preview and expectation)."""

    def __init__(self, settings: AppSettings, parent: QWidget | None = None, *, offer_auto: bool = False):
        super().__init__(parent)
        self.settings = settings
        self.offer_auto = offer_auto
        self._divisions: list = []
        self._comparing = False
        self._beside = False
        self.method_box = QComboBox()
        self.method_box.addItems(names())
        self.stack = QStackedWidget()
        self.pages: dict[str, OptionsForm] = {}
        """Each method's options form (the options the slider sets left out)."""
        for spec in specs():
            page = self.pages[spec.name] = OptionsForm(
                spec, skip=[o.name for o in spec.option_specs if o.kind in SLIDER_KINDS], settings=settings,
                key=f"review/{spec.name}", empty="no knobs besides the slider")
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
        self.auto_box = QCheckBox()
        """Checked: the knob :meth:`auto_knob` names is chosen by the estimate when Reconstruct runs."""
        self.auto_box.setChecked(settings.get_bool("review/auto", False))
        if offer_auto:  # hidden for a method with no knob to choose, it keeps its room: no button below it moves
            policy = self.auto_box.sizePolicy()
            policy.setRetainSizeWhenHidden(True)
            self.auto_box.setSizePolicy(policy)
        layout.addWidget(self.auto_box)
        self.options = Collapsible("method options", self.stack, settings=settings, key="review/show_options")
        """The chosen method's knobs, folded (the workspace places it below its actions)."""

        self.method_box.setCurrentText(settings.get_str("review/method", DEFAULT))
        self.stack.setCurrentIndex(self.method_box.currentIndex())
        self.method_box.currentIndexChanged.connect(self._on_method)
        self.slider.valueChanged.connect(self._on_slider)
        self.auto_box.toggled.connect(self._on_knob)
        for page in self.pages.values():
            page.changed.connect(self._on_knob)
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
        widgets = self.pages[get(name).name].widgets
        if option not in widgets:
            raise ValueError(f"{name} has no widget for {option!r} (its widgets: {', '.join(widgets) or 'none'}; "
                             "the slider sets the tensor or division)")
        return widgets[option]

    def method(self) -> Method:
        """The :class:`Method` the form describes (what Reconstruct runs)."""
        return self._method_for(self.method_box.currentText())

    def auto_knob(self) -> str | None:
        """The knob Reconstruct is to choose by the estimated PSNR (``time``, ``block``), or None: the box is
        unchecked, the method has no knob to choose, or the estimate refuses it (:meth:`auto_refusal`)."""
        knob = self._auto_candidate()
        if knob is None or not self.offer_auto or not self.auto_box.isChecked() or self.auto_refusal() is not None:
            return None
        return knob

    def auto_refusal(self) -> str | None:
        """Why the chosen method's knob cannot be chosen by the estimate now, or None when it can."""
        from flexvox_core.accuracy import refusal

        name = self.method_box.currentText()
        knob = self._auto_candidate()
        if knob is None:
            return f"{name} has no knob to choose by the estimate"
        try:
            why = refusal(self.method())
        except ValueError as exc:  # a value the method refuses: Reconstruct says so
            return str(exc)
        return None if why is None else f"the estimate refuses {name}: {why}"

    def _auto_candidate(self) -> str | None:
        from flexvox_core.choice import AUTO_KNOBS

        knobs = AUTO_KNOBS.get(self.method_box.currentText(), ())
        return knobs[0] if knobs else None

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
        values = self.pages[spec.name].values()
        along = {TRIPLE: lambda o: self.tensor(tuple(o.default)),
                 DIVISION: lambda o: continuum_division(self.position, self._divisions) if self._divisions else None}
        values.update({o.name: along[o.kind](o) for o in spec.option_specs if o.kind in along})
        return Method(spec.name, **values)

    def tensor(self, default=None) -> tuple[float, float, float]:
        """The diffusion tensor at the slider's position: at :data:`DEFAULT_STEP` the benched default (one default
        tensor everywhere), else :func:`continuum_tensor`'s."""
        if self.slider.value() == DEFAULT_STEP:
            if default is None:
                default = tuple(next(o.default for o in get("diffusion").option_specs if o.kind == TRIPLE))
            return tuple(float(c) for c in default)
        return continuum_tensor(self.position)

    # ------------------------------------------------------------------ reactions
    def _has_slider(self) -> bool:
        return any(o.kind in SLIDER_KINDS for o in get(self.method_box.currentText()).option_specs)

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
        self.settings.set("review/auto", self.auto_box.isChecked())
        self.settings.set("review/continuum", self.position)
        for page in self.pages.values():
            page.save()
        self._refresh()
        self.changed.emit()

    def _refresh_auto(self, spec) -> None:
        from flexvox_core.choice import AUTO_KNOBS

        chosen = self.auto_knob()
        for name, page in self.pages.items():  # a knob being chosen is greyed on its page; the others stay usable
            for k in AUTO_KNOBS.get(name, ()):
                if k in page.widgets:
                    page.widgets[k].setEnabled(not (name == spec.name and chosen == k))
        self.slider.setEnabled(not (chosen is not None and spec.option(chosen).kind is DIVISION))
        knob = self._auto_candidate()
        self.auto_box.setVisible(knob is not None and self.offer_auto)
        if knob is None:
            return
        option = spec.option(knob)
        what = "division" if option.kind is DIVISION else option.label or knob
        self.auto_box.setText(f"choose the {what} by the estimate (auto)")
        why = self.auto_refusal()
        self.auto_box.setEnabled(why is None)
        self.auto_box.setToolTip(why or (f"Reconstruct tries each candidate {what}, estimates each result's PSNR "
                                         "from the recording alone and keeps the best (each candidate costs a "
                                         "reconstruction and the estimate's probe run)"))

    def _refresh(self) -> None:
        spec = get(self.method_box.currentText())
        self._refresh_auto(spec)
        kinds = {o.kind for o in spec.option_specs}
        if DIVISION in kinds:
            if self._divisions:
                d = continuum_division(self.position, self._divisions)
                self.slider_text.setText(f"division {d.label}: TR ×{d.tr}, SR ×{d.sr} "
                                         f"({len(self._divisions)} supported divisions along the slider)")
            else:
                self.slider_text.setText("open a recording to see its divisions")
        elif TRIPLE in kinds:
            self.slider_text.setText(describe(self.position, self.tensor()))
        elif self._comparing and self._beside:
            self.slider_text.setText(f"previewing diffusion, {describe(self.position, self.tensor())}, beside the "
                                     f"{spec.name} result for comparison; Reconstruct runs {spec.name}")
        elif self._comparing:
            self.slider_text.setText(f"previewing diffusion, {describe(self.position, self.tensor())}, in place of "
                                     f"{spec.name} (no {spec.name} result to set it beside yet); Reconstruct runs "
                                     f"{spec.name}")
        else:
            self.slider_text.setText(f"{spec.trade}; moving the slider previews diffusion at its tensor beside "
                                     f"{spec.name}, for comparison")
