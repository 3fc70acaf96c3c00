"""A method's options as a form: one field per option, the field its kind names; the Review workspace and the
napari plugin show the same form.

The field is the option's kind's (:attr:`Kind.field <flexvox_core.methods.option_kinds.Kind.field>`):

- ``check``: a check box named by the option's label;
- ``list``: a combo box of the option's choices;
- ``whole``, ``real``: a spin box over the option's ``span``. An option whose default is None offers the default
  as a value of its own: where ``shown_default`` is a number (the value the method then uses), that number stands
  for the default; otherwise (words such as "(K/16)²": a default that depends on the capture) a choice one step
  below the range, shown as "default (…)", and every number in the range means itself (a number typed below the
  range is the default too);
- ``text``: a line read by the kind (:meth:`Kind.parse <flexvox_core.methods.option_kinds.Kind.parse>`; empty: the
  default), which names the option and what it must be when it cannot.

Given settings and a key, each field starts from the value kept there and :meth:`OptionsForm.save` keeps it.
Values are checked where every front end checks them: by :class:`~flexvox_core.methods.Method`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QLabel, QLineEdit, QSpinBox, QWidget

from flexvox_app.gui.widgets.settings import AppSettings

_BIG = 1_000_000
"""The top of a whole- or real-number box whose option gives no span."""


class _Field(ABC):
    """One option's widget: how it reads, shows and keeps its value (``changed``: the widget's signal)."""

    keeps = ""
    """What the settings key holds beyond the option's name ("": the value itself)."""

    def __init__(self, option):
        self.option = option
        self.widget, self.changed = self._make()
        self.widget.setToolTip(option.help or option.rule)
        self.widget.setObjectName(option.name)
        self.show(None)

    @abstractmethod
    def _make(self) -> tuple:
        """The widget and its change signal."""

    @abstractmethod
    def value(self, tile=None):
        """The option's value (None: its default)."""

    @abstractmethod
    def show(self, value) -> None:
        """Show ``value`` (None: the default)."""

    @abstractmethod
    def stored(self):
        """What the settings keep of the field."""

    def kept(self, settings: AppSettings, key: str):
        """The value ``settings`` keep at ``key`` for this field (the default when none)."""
        return settings.get_str(key, self.option.kind.default_text(self.option))


class _Check(_Field):
    """A check box named by the option's label."""

    def _make(self):
        w = QCheckBox(self.option.label or self.option.name)
        return w, w.toggled

    def value(self, tile=None):
        return self.widget.isChecked()

    def show(self, value):
        self.widget.setChecked(bool(self.option.default if value is None else value))

    def stored(self):
        return self.widget.isChecked()

    def kept(self, settings, key):
        return settings.get_bool(key, bool(self.option.default))


class _List(_Field):
    """A combo box of the option's choices."""

    def _make(self):
        w = QComboBox()
        w.addItems([str(c) for c in self.option.choices])
        return w, w.currentIndexChanged

    def value(self, tile=None):
        return self.option.choices[self.widget.currentIndex()]

    def show(self, value):
        self.widget.setCurrentText(str(self.option.default if value is None else value))

    def stored(self):
        return self.widget.currentText()


class _Real(_Field):
    """A real-number box (see the module docstring for a default of None)."""

    number, step = float, 0.1

    def _box(self) -> QSpinBox | QDoubleSpinBox:
        w = QDoubleSpinBox()
        w.setDecimals(2)
        return w

    def _make(self):
        o = self.option
        lo, hi, step = (self.number(v) for v in o.span or (0, _BIG, self.step))
        self.floor = lo
        self.in_words = o.default is None and not isinstance(o.shown_default, int | float)
        if self.in_words:
            # Its own settings key: a value kept where the number shown stood for the default must not come back
            # as that number.
            self.keeps = "-or-default"
            lo -= step
        w = self._box()
        w.setRange(lo, hi)
        w.setSingleStep(step)
        if self.in_words:
            w.setSpecialValueText(f"default ({o.shown_default})" if o.shown_default is not None else "default")
        return w, w.valueChanged

    def _default(self):
        o = self.option
        if o.default is not None:
            return o.default
        return self.widget.minimum() if self.in_words else o.shown_default

    def value(self, tile=None):
        value = self.widget.value()
        o = self.option
        if o.default is None and (value == o.shown_default or self.in_words and value < self.floor):
            return None  # the default, or a number typed below the range: the default too
        return value

    def show(self, value):
        self.widget.setValue(self._default() if value is None else value)

    def stored(self):
        return self.widget.value()

    def kept(self, settings, key):
        return settings.get_float(key, self._default())


class _Whole(_Real):
    """A whole-number box."""

    number, step = int, 1

    def _box(self):
        return QSpinBox()

    def kept(self, settings, key):
        return settings.get_int(key, self._default())


class _Text(_Field):
    """A line of text the option's kind reads (empty: the default)."""

    def _make(self):
        w = QLineEdit()
        w.setPlaceholderText(f"{self.option.kind.metavar or 'a value'} (empty: default)")
        return w, w.textChanged

    def value(self, tile=None):
        text = self.widget.text().strip()
        return None if not text else self.option.kind.parse(self.option, text, tile=tile)

    def show(self, value):
        self.widget.setText(value if isinstance(value, str) else self.option.kind.format(
            self.option.default if value is None else value))

    def stored(self):
        return self.widget.text()


FIELDS = {"check": _Check, "list": _List, "whole": _Whole, "real": _Real, "text": _Text}
"""The widget of each field a kind names (:data:`flexvox_core.methods.option_kinds.FIELDS`)."""


class OptionsForm(QWidget):
    """One method's options, a field per option (see the module docstring).

    Parameters
    ----------
    spec : MethodSpec
        The method (:mod:`flexvox_core.methods.registry`).
    skip : iterable of str
        Options the form leaves out (set elsewhere, e.g. by the Review workspace's continuum slider).
    settings, key : AppSettings, str
        Where the fields' values are kept (``key/option``); None: not kept.
    empty : str
        What the form says when it has no field.
    """

    changed = Signal()
    """Any field changed."""

    def __init__(self, spec, *, skip=(), settings: AppSettings | None = None, key: str = "", empty: str = "",
                 parent: QWidget | None = None):
        super().__init__(parent)
        self.spec, self.settings = spec, settings
        self._fields: dict[str, _Field] = {}
        self._keys: dict[str, str] = {}
        form = QFormLayout(self)
        for o in spec.option_specs:
            if o.name in skip:
                continue
            field = self._fields[o.name] = FIELDS[o.kind.field](o)
            self._keys[o.name] = f"{key}/{o.name}{field.keeps}"
            if settings is not None:
                field.show(field.kept(settings, self._keys[o.name]))
            if isinstance(field, _Check):
                form.addRow(field.widget)  # the check box says its label
            else:
                form.addRow(o.label or o.name, field.widget)
            field.changed.connect(self.changed)
        if not self._fields and empty:
            form.addRow(QLabel(empty))

    @property
    def widgets(self) -> dict[str, QWidget]:
        """Each shown option's widget, in the method's order."""
        return {name: f.widget for name, f in self._fields.items()}

    def values(self, tile=None) -> dict:
        """The shown options' values as :class:`~flexvox_core.methods.Method` takes them (None: the default);
        ``tile``: the capture's, for a field whose kind reads text against it (a division).

        Raises
        ------
        ValueError
            A text field that is not what its kind reads, naming the option and what it must be.
        """
        return {name: f.value(tile) for name, f in self._fields.items()}

    def set_value(self, name: str, value) -> None:
        """Show ``value`` in option ``name``'s field (text for a text field, or the value; None: the default)."""
        self._fields[name].show(value)

    def save(self) -> None:
        """Keep every field's value in the settings (nothing without settings)."""
        if self.settings is not None:
            for name, f in self._fields.items():
                self.settings.set(self._keys[name], f.stored())
