"""A section that folds: a header button (▸ / ▾ and a title) over a body shown only when open.

Workspaces keep their details (tables, long explanations, rarely changed options) in these, below
the primary actions, so the actions stay in view on a small screen. Whether a section is open can
persist in the settings (``key``).
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QSizePolicy, QToolButton, QVBoxLayout, QWidget


class Collapsible(QWidget):
    """A titled section whose ``body`` folds away.

    Parameters
    ----------
    title : str
    body : QWidget
    expanded : bool
        Open at first (the setting, when ``settings`` and ``key`` are given, wins).
    settings : AppSettings, optional
    key : str, optional
        Settings key that remembers whether the section is open.
    """

    toggled = Signal(bool)

    def __init__(self, title: str, body: QWidget, *, expanded: bool = False, settings=None, key: str = "",
                 parent: QWidget | None = None):
        super().__init__(parent)
        self._settings = settings if key else None
        self._key = key
        if self._settings is not None:
            expanded = self._settings.get_bool(key, expanded)
        self.header = QToolButton()
        self.header.setText(title)
        self.header.setCheckable(True)
        self.header.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.header.setAutoRaise(True)
        self.header.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.header.setStyleSheet("QToolButton { font-weight: bold; text-align: left; }")
        self.body = body
        v = QVBoxLayout(self)
        v.setContentsMargins(0, 0, 0, 0)
        v.setSpacing(2)
        v.addWidget(self.header)
        v.addWidget(body)
        self.header.toggled.connect(self.set_expanded)
        self.set_expanded(expanded)

    @property
    def expanded(self) -> bool:
        """True when the body shows."""
        return self.header.isChecked()

    def set_expanded(self, on: bool) -> None:
        """Open or fold the section."""
        on = bool(on)
        if self.header.isChecked() != on:
            self.header.blockSignals(True)
            self.header.setChecked(on)
            self.header.blockSignals(False)
        self.header.setArrowType(Qt.ArrowType.DownArrow if on else Qt.ArrowType.RightArrow)
        self.body.setVisible(on)
        if self._settings is not None:
            self._settings.set(self._key, on)
        self.toggled.emit(on)
