"""The layout every workspace shares: a scrolling column of controls beside a large view."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHBoxLayout, QScrollArea, QSplitter, QVBoxLayout, QWidget


def controls_beside_view(workspace: QWidget, controls, view: QWidget, *, min_width: int = 380,
                         sizes=(400, 900)) -> QScrollArea:
    """Lay ``workspace`` out as its ``controls`` (widgets, top to bottom) in a scroll area beside ``view``.

    Returns the scroll area (so a workspace can scroll a box into sight).
    """
    column = QWidget()
    v = QVBoxLayout(column)
    for w in controls:
        v.addWidget(w)
    v.addStretch(1)
    scroll = QScrollArea()
    scroll.setWidget(column)
    scroll.setWidgetResizable(True)
    scroll.setMinimumWidth(min_width)
    scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
    split = QSplitter()
    split.addWidget(scroll)
    split.addWidget(view)
    split.setStretchFactor(1, 1)
    split.setSizes(list(sizes))
    QHBoxLayout(workspace).addWidget(split)
    return scroll
