"""The layout every workspace shares: a column of controls beside a large view.

The column holds the workspace's primary actions at the top, never scrolled away, and its details
below them in a scroll area (collapsible sections, see :mod:`flexvox_app.gui.widgets.collapsible`), so the
actions stay in view on a 1024×700 screen whatever the details hold. The column takes
:data:`COLUMN_SHARE` of the workspace's width, between its minimum and ``max_width``, and the view the
rest, until the operator drags the handle between them (then their choice holds).
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QScrollArea, QSplitter, QVBoxLayout, QWidget

COLUMN_SHARE = 0.4
"""The column's share of the workspace's width (between its minimum and its maximum)."""


class ColumnSplitter(QSplitter):
    """The column beside the view: the column's width follows the window's (see the module docstring)."""

    def __init__(self, column: QWidget, view: QWidget, max_width: int):
        super().__init__()
        self.max_width = int(max_width)
        self.dragged = False
        """True once the operator moved the handle."""
        self.addWidget(column)
        self.addWidget(view)
        self.setStretchFactor(1, 1)
        self.setCollapsible(0, False)
        self.splitterMoved.connect(self._moved)

    def _moved(self, *_) -> None:
        self.dragged = True

    def column_width(self, total: int) -> int:
        """The column's width in a workspace ``total`` pixels wide."""
        lo = self.widget(0).minimumWidth()
        return max(lo, min(self.max_width, round(COLUMN_SHARE * total)))

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Share the width between the column and the view (until the operator moved the handle)."""
        super().resizeEvent(event)
        if not self.dragged:
            total = self.width() - self.handleWidth()
            col = self.column_width(total)
            self.blockSignals(True)
            self.setSizes([col, max(0, total - col)])
            self.blockSignals(False)


def controls_beside_view(workspace: QWidget, controls, view: QWidget, *, actions=(), min_width: int = 340,
                         max_width: int = 420) -> QScrollArea:
    """Lay ``workspace`` out as its ``actions`` (widgets, top to bottom, always in view) over its ``controls``
    (widgets, top to bottom, in a scroll area), beside ``view``.

    Returns the scroll area (so a workspace can scroll a box into sight).
    """
    details = QWidget()
    v = QVBoxLayout(details)
    v.setContentsMargins(0, 0, 0, 0)
    for w in controls:
        v.addWidget(w)
    v.addStretch(1)
    scroll = QScrollArea()
    scroll.setWidget(details)
    scroll.setWidgetResizable(True)
    scroll.setFrameShape(QScrollArea.Shape.NoFrame)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
    column = QWidget()
    column.setMinimumWidth(min_width)
    c = QVBoxLayout(column)
    c.setContentsMargins(0, 0, 0, 0)
    for w in actions:
        c.addWidget(w)
    c.addWidget(scroll, 1)
    QHBoxLayout(workspace).addWidget(ColumnSplitter(column, view, max_width))
    return scroll
