"""An image view with a title: a pyqtgraph ImageItem (row-major), an optional RGBA overlay and colour bar."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QEvent, Qt
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget


class ImagePanel(QWidget):
    """A titled image: ``set_image(img, levels=...)`` never auto-levels unless asked.

    Parameters
    ----------
    title : str
    colormap : str, optional
        A pyqtgraph colour map name (e.g. "viridis") with a colour bar; default grey.
    """

    def __init__(self, title: str = "", *, colormap: str | None = None, parent: QWidget | None = None):
        super().__init__(parent)
        self.title = QLabel(title)
        self.title.setWordWrap(True)
        self.title.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.graphics = pg.GraphicsLayoutWidget()
        self.graphics.setBackground("#202020")
        self.view = self.graphics.addViewBox(lockAspect=True, invertY=True, enableMenu=False)
        self.image = pg.ImageItem(axisOrder="row-major")
        self.overlay = pg.ImageItem(axisOrder="row-major")
        self.overlay.setZValue(10)
        self.view.addItem(self.image)
        self.view.addItem(self.overlay)
        self.colorbar = None
        if colormap is not None:
            cmap = pg.colormap.get(colormap)
            self.image.setColorMap(cmap)
            self.colorbar = pg.ColorBarItem(colorMap=cmap, interactive=False, width=14)
            self.colorbar.setImageItem(self.image)
            self.graphics.addItem(self.colorbar)
        # The message shown instead of an image: a word-wrapped label over the view (never clipped, unlike
        # a text item in the scene, which keeps its one line whatever the panel's width).
        self.placeholder = QLabel("", self.graphics)
        self.placeholder.setWordWrap(True)
        self.placeholder.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.placeholder.setStyleSheet("color: #bbbbbb; background: transparent; padding: 12px")
        self.placeholder.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        self.graphics.installEventFilter(self)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.title)
        layout.addWidget(self.graphics, 1)
        self._shape: tuple[int, int] | None = None

    def set_title(self, text: str) -> None:
        """Replace the title line."""
        self.title.setText(text)

    def set_image(self, img: np.ndarray, *, levels=None) -> None:
        """Show ``img`` (H, W) or (H, W, 3) RGB uint8. ``levels`` (low, high) for grey images."""
        img = np.asarray(img)
        self.placeholder.setText("")
        self.placeholder.hide()
        if img.ndim == 3:
            self.image.setImage(img, autoLevels=False, levels=(0, 255))
        else:
            if levels is None:
                lo, hi = float(np.nanmin(img)), float(np.nanmax(img))
                levels = (lo, hi if hi > lo else lo + 1)
            self.image.setImage(img, autoLevels=False, levels=levels)
            if self.colorbar is not None:
                self.colorbar.setLevels(levels)
                self.colorbar.show()
        shape = img.shape[:2]
        if shape != self._shape:
            self._shape = shape
            self.view.autoRange(padding=0.01)

    def set_overlay(self, rgba: np.ndarray | None) -> None:
        """An RGBA uint8 (H, W, 4) drawn over the image, or None to remove it."""
        if rgba is None:
            self.overlay.clear()
        else:
            self.overlay.setImage(np.asarray(rgba), autoLevels=False, levels=(0, 255))

    def clear(self, message: str = "") -> None:
        """Remove the image and show ``message`` in its place."""
        self.image.clear()
        self.overlay.clear()
        self._shape = None
        self.placeholder.setText(message)
        self.placeholder.setVisible(bool(message))
        if self.colorbar is not None:  # no image, no scale: an empty colour bar says nothing
            self.colorbar.hide()
        self.placeholder.setGeometry(self.graphics.rect())
        self.view.setRange(xRange=(-1, 1), yRange=(-1, 1), padding=0)

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt's name
        """Keep the placeholder over the whole view when the view is resized."""
        if watched is self.graphics and event.type() == QEvent.Type.Resize:
            self.placeholder.setGeometry(self.graphics.rect())
        return super().eventFilter(watched, event)

    def placeholder_text(self) -> str:
        """The message shown instead of an image ("" when an image is shown)."""
        return self.placeholder.text() if self.placeholder.isVisible() or not self.has_image() else ""

    def has_image(self) -> bool:
        """True when an image is shown."""
        return self.image.image is not None
