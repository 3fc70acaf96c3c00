"""The mouse wheel changes a spin box, combo box or slider only when that widget has the focus.

Without it, scrolling a column of controls with the wheel changes whatever value passes under the
pointer (a camera rate of 15 Hz became 13 Hz while the operator scrolled). :class:`WheelGuard` is an
event filter on the application: a wheel event over a value widget that does not have the focus
(the operator clicked into it, or reached it with Tab) scrolls the scroll area around it instead,
and the widget keeps its value. :func:`guard_value_widgets` also sets the widgets' focus policy to
``StrongFocus``, so the wheel itself never gives them the focus.
"""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtWidgets import (
    QAbstractScrollArea,
    QAbstractSlider,
    QAbstractSpinBox,
    QApplication,
    QComboBox,
    QScrollBar,
    QWidget,
)

VALUE_WIDGETS = (QAbstractSpinBox, QComboBox, QAbstractSlider)
"""The widgets whose value the wheel changes."""


def _value_widget(obj) -> QWidget | None:
    """The value widget ``obj`` is (or is inside: a spin box's line edit), or None. Scroll bars are not guarded."""
    w = obj if isinstance(obj, QWidget) else None
    while w is not None and not w.isWindow():
        if isinstance(w, QScrollBar):
            return None
        if isinstance(w, VALUE_WIDGETS):
            return w
        if isinstance(w, QAbstractScrollArea):
            return None
        w = w.parentWidget()
    return None


def scroll_area_of(widget: QWidget) -> QAbstractScrollArea | None:
    """The nearest scroll area that holds ``widget`` (None: none)."""
    w = widget.parentWidget()
    while w is not None:
        if isinstance(w, QAbstractScrollArea):
            return w
        w = w.parentWidget()
    return None


class WheelGuard(QObject):
    """Application event filter: the wheel over an unfocused value widget scrolls its column instead."""

    def eventFilter(self, obj, event) -> bool:  # noqa: N802 - Qt's name
        """Redirect a wheel event meant for an unfocused value widget."""
        if event.type() != QEvent.Type.Wheel:
            return False
        widget = _value_widget(obj)
        if widget is None or widget.hasFocus():
            return False
        # Handed to the column's scroll bar here (and taken, so Qt does not pass it on to the parents as well):
        # one path for the operator's wheel and for a synthesised event, which Qt would not pass on.
        area = scroll_area_of(widget)
        if area is not None:
            bar = area.verticalScrollBar()
            if bar is not None and bar.maximum() > bar.minimum():
                QApplication.sendEvent(bar, event.clone())
        event.accept()
        return True


_GUARD: WheelGuard | None = None


def install_wheel_guard() -> WheelGuard:
    """Install the guard on the running application (once); returns it."""
    global _GUARD
    if _GUARD is None:
        _GUARD = WheelGuard()
        QApplication.instance().installEventFilter(_GUARD)
    return _GUARD


def guard_value_widgets(root: QWidget) -> int:
    """Give every value widget under ``root`` the ``StrongFocus`` policy (click or Tab, never the wheel).

    Returns how many widgets it set.
    """
    n = 0
    for kind in VALUE_WIDGETS:
        for w in root.findChildren(kind):
            if not isinstance(w, QScrollBar):
                w.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
                n += 1
    return n
