"""Two images side by side where there is width, one above the other where there is not.

In a small window the view beside the controls column is taller than wide: side by side, each of two
images would get a third of its width. :class:`AdaptiveSplit` lays its widgets out side by side while
its width is at least :data:`WIDE` times its height, else one above the other.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QSplitter, QWidget

WIDE = 4 / 3
"""Side by side from this width-to-height ratio up: below it, two 4:3 images are larger one above the other."""


class AdaptiveSplit(QSplitter):
    """A splitter of equal parts whose orientation follows its shape (see the module docstring)."""

    def __init__(self, *widgets: QWidget, parent: QWidget | None = None):
        super().__init__(Qt.Orientation.Horizontal, parent)
        for w in widgets:
            self.addWidget(w)
        self.setChildrenCollapsible(False)

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Turn to the orientation that gives each part the most room."""
        super().resizeEvent(event)
        wide = self.width() >= WIDE * self.height()
        orientation = Qt.Orientation.Horizontal if wide else Qt.Orientation.Vertical
        if self.orientation() != orientation:
            self.setOrientation(orientation)
            self.setSizes([1000] * self.count())
