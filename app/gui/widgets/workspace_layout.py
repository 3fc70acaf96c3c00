"""The layout every workspace shares: a column of controls beside a large view.

The column holds the workspace's primary actions at the top, never scrolled away, and its details
below them in a scroll area (collapsible sections, see :mod:`app.gui.widgets.collapsible`), so the
actions stay in view on a 1280×800 screen whatever the details hold.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QScrollArea, QSplitter, QVBoxLayout, QWidget


def controls_beside_view(workspace: QWidget, controls, view: QWidget, *, actions=(), min_width: int = 380,
                         sizes=(400, 900)) -> QScrollArea:
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
    split = QSplitter()
    split.addWidget(column)
    split.addWidget(view)
    split.setStretchFactor(1, 1)
    split.setCollapsible(0, False)
    split.setSizes(list(sizes))
    QHBoxLayout(workspace).addWidget(split)
    return scroll
