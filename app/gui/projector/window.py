"""The projector output window: the packed shutter patterns, full-screen and pixel-exact, on a chosen screen.

For a projector driven through its video input (the DLPC350 in video pattern mode): every
24-bit input frame is shown as 24 one-bit patterns, so the K masks are packed into the
bit-planes of ``ceil(K / 24)`` RGB frames by :func:`rig_drivers.dlpc350.bitplanes.pack_bitplanes`
(green bits 0-7, red 8-15, blue 16-23). The capture service and this window show the same
masks, :meth:`flexvox_app.capture.plan.CapturePlan.patterns` (the code tiled over the camera, through the
calibration's homography, phase compensated), packed as
:attr:`flexvox_calibration.shutter.ShutterPatterns.packed`.

Pixel-exactness
---------------
A bit-plane is a bit of each pixel's value, so a single resampled or blended pixel changes
the mirror pattern. :class:`ProjectorWindow` therefore never scales:

* the frame becomes a ``QImage`` (``Format_RGB888``, a deep copy of the numpy bytes) whose
  ``devicePixelRatio`` is set, at paint time, to the widget's: one image pixel is one device
  pixel whatever the desktop's scale setting (a 2× screen would otherwise double it);
* a small view widget paints it with ``QPainter.drawImage`` at the origin (0, 0), its native
  size, no smooth-transform hint, so Qt blits it unscaled. (A ``QLabel`` with a ``QPixmap`` was
  tried first: at scale 2 it drew the 91-pixel-wide frame over 92 device pixels, so it is not used.)
* the window is frameless, full-screen on the chosen screen, black around the pattern,
  without margins, and the cursor is hidden over it.

The tests check this offscreen at scale factors 1, 1.25 and 2 (``QT_SCALE_FACTOR``). What the
window cannot guarantee: what a compositor or driver does to the image after Qt (keep the
projector's screen at 100 % and unrotated), a screen mode other than the projector's native
resolution (the window says so: :meth:`ProjectorWindow.size_warning`),
and swapping frames on the video signal's vsync: with K > 24 the frames are cycled on a timer
(one per ``cycle_ms``), which a DLPC350 in video pattern mode does not lock to. Use K ≤ 24 (one
static frame) for video-port capture, or the flash sequence the capture service loads.

The test (``tests/app/gui/test_projector_window.py``) grabs the window and compares every pixel
with the packed frame.
"""

from __future__ import annotations

import logging

import numpy as np
from PySide6.QtCore import QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QGuiApplication, QImage, QPainter
from PySide6.QtWidgets import QComboBox, QVBoxLayout, QWidget

_logger = logging.getLogger(__name__)

CYCLE_MS = 1000 // 60
"""Frame interval when K > 24 (the video input's 60 Hz), best effort."""


class ScreenGone(RuntimeError):
    """The screen a projector window was made for is no longer listed (unplugged, or re-created by the platform)."""


def live_screen(name: str | None):
    """The screen called ``name`` as Qt lists it now (the primary screen for None; None when none has that name).

    A QScreen kept across an event loop can be deleted under its Python wrapper (a screen unplugged, or re-created
    by the platform), so the projector's windows keep the name and look the screen up where they use it."""
    if name is None:
        return QGuiApplication.primaryScreen()
    return next((s for s in QGuiApplication.screens() if s.name() == name), None)


def screen_label(screen) -> str:
    """``name — W×H at (x, y)`` (and the scale when it is not 1) for the screen combo box."""
    g = screen.geometry()
    dpr = screen.devicePixelRatio()
    scale = "" if dpr == 1 else f", scale {dpr:g}"
    primary = " (primary)" if screen is QGuiApplication.primaryScreen() else ""
    return f"{screen.name() or 'screen'}{primary} — {g.width()}×{g.height()} at ({g.x()}, {g.y()}){scale}"


class ScreenPicker(QComboBox):
    """The screens, labelled by :func:`screen_label`, kept current as screens come and go.

    The choice stays on the screen picked before (by name), else ``preferred``, else the second
    screen when there is one (likely the projector's video input).
    """

    def __init__(self, preferred: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        self._preferred = preferred
        self.refresh()
        app = QGuiApplication.instance()
        app.screenAdded.connect(self.refresh)
        app.screenRemoved.connect(self.refresh)

    def refresh(self, *_) -> None:
        """Re-list the screens, keeping the current choice where it still exists."""
        current = self.currentData() or self._preferred
        self.blockSignals(True)
        self.clear()
        for i, screen in enumerate(QGuiApplication.screens()):
            self.addItem(screen_label(screen), screen.name() or str(i))
        idx = self.findData(current) if current else -1
        if idx < 0 and self.count() > 1:
            idx = 1  # a second screen is likely the projector
        self.setCurrentIndex(max(idx, 0))
        self.blockSignals(False)

    def chosen(self):
        """The QScreen picked (None: no screens)."""
        screens = QGuiApplication.screens()
        idx = self.currentIndex()
        return screens[idx] if 0 <= idx < len(screens) else None


def check_frames(frames) -> np.ndarray:
    """``frames`` as an ``(F, H, W, 3)`` uint8 array, or ValueError naming the rule."""
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[3] != 3 or frames.dtype != np.uint8 or frames.shape[0] < 1:
        raise ValueError(f"`frames` must have shape (F, H, W, 3) uint8 with F >= 1; got {frames.shape} "
                         f"{frames.dtype}")
    return frames


def _image(frame: np.ndarray) -> QImage:
    frame = np.ascontiguousarray(frame, dtype=np.uint8)
    h, w, _ = frame.shape
    return QImage(frame.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()  # owns its bytes


class _PatternView(QWidget):
    """Paints one image at the origin, one image pixel per device pixel, on black."""

    painted_now = Signal()
    """A paint event has just drawn :attr:`image`."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.image: QImage | None = None
        self.painted: QImage | None = None
        """The image the last paint event drew (``painted is image``: the current one is on screen)."""
        self.setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent)

    def set_image(self, image: QImage) -> None:
        self.image = image
        self.update()

    def paintEvent(self, event) -> None:  # noqa: N802 - Qt's name
        painter = QPainter(self)
        painter.fillRect(self.rect(), Qt.GlobalColor.black)
        if self.image is not None:
            painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, False)
            self.image.setDevicePixelRatio(self.devicePixelRatioF())  # device pixels, not logical ones
            painter.drawImage(QPointF(0, 0), self.image)
        painter.end()
        self.painted = self.image
        self.painted_now.emit()


class ProjectorWindow(QWidget):
    """A frameless full-screen window showing packed pattern frames pixel for pixel (Esc closes it).

    Parameters
    ----------
    frames : ndarray (F, H, W, 3) uint8
        :attr:`flexvox_calibration.shutter.ShutterPatterns.packed`; with F > 1 they are cycled every ``cycle_ms``.
    screen : QScreen, optional
        Where to show it (default the primary screen).
    cycle_ms : int
    """

    closed = Signal()
    """The window was closed (Esc, or :meth:`close`)."""

    def __init__(self, frames: np.ndarray, *, screen=None, cycle_ms: int = CYCLE_MS, parent: QWidget | None = None):
        super().__init__(parent, Qt.WindowType.Window | Qt.WindowType.FramelessWindowHint)
        frames = check_frames(frames)
        self.setWindowTitle("flexvox — projector output")
        self.setCursor(Qt.CursorShape.BlankCursor)
        self.frames = frames
        chosen = screen or QGuiApplication.primaryScreen()
        self.screen_name: str | None = chosen.name() if chosen is not None else None
        self.view = _PatternView()
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addWidget(self.view)
        self._images = [_image(f) for f in frames]
        self.index = 0
        self.view.set_image(self._images[0])
        self.timer = QTimer(self)
        self.timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.timer.setInterval(int(cycle_ms))
        self.timer.timeout.connect(self.next_frame)

    @property
    def frame_size(self) -> tuple[int, int]:
        """(H, W) of the pattern frames."""
        return int(self.frames.shape[1]), int(self.frames.shape[2])

    @property
    def target_screen(self):
        """The screen it shows on, looked up by name now (:func:`live_screen`); :class:`ScreenGone` when it is gone."""
        screen = live_screen(self.screen_name)
        if screen is None:
            raise ScreenGone(f"the screen {self.screen_name!r} is gone (unplugged?)")
        return screen

    def size_warning(self) -> str:
        """Why the pattern will not cover the screen one-to-one ("" when it does)."""
        g = self.target_screen.geometry()
        dpr = self.target_screen.devicePixelRatio()
        sw, sh = round(g.width() * dpr), round(g.height() * dpr)
        H, W = self.frame_size
        notes = []
        if (sh, sw) != (H, W):
            notes.append(f"the screen is {sw}×{sh} pixels, the patterns {W}×{H}: set the projector's video "
                         "input to its native resolution")
        if dpr != 1:
            notes.append(f"the screen's scale is {dpr:g}: the pattern is drawn in device pixels, but set the "
                         "projector's screen to 100 % so the desktop does not rescale it")
        return "; ".join(notes)

    def set_frames(self, frames: np.ndarray) -> None:
        """Replace the frames (shown from frame 0; cycling when there are several)."""
        frames = check_frames(frames)
        self.frames = frames
        self._images = [_image(f) for f in frames]
        self.index = 0
        self.view.set_image(self._images[0])
        if len(self._images) > 1 and self.isVisible():
            self.timer.start()
        else:
            self.timer.stop()

    def on_screen(self) -> bool:
        """True when the current frame has been painted."""
        return self.view.image is not None and self.view.painted is self.view.image

    def show_frame(self, index: int) -> None:
        """Show frame ``index`` (mod F)."""
        self.index = int(index) % len(self._images)
        self.view.set_image(self._images[self.index])

    def next_frame(self) -> None:
        """Show the next packed frame (K > 24 cycles them)."""
        self.show_frame(self.index + 1)

    def open(self) -> None:
        """Show it frameless and full-screen on its screen; start cycling when there are several frames."""
        screen = self.target_screen
        self.setGeometry(screen.geometry())
        self.create()
        handle = self.windowHandle()
        if handle is not None:
            handle.setScreen(screen)
        self.showFullScreen()
        if len(self._images) > 1:
            self.timer.start()
        _logger.info("projector window on %s: %d frame(s) of %dx%d", screen.name(), len(self._images),
                     *self.frame_size[::-1])

    def keyPressEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Esc closes the window."""
        if event.key() == Qt.Key.Key_Escape:
            self.close()
            return
        super().keyPressEvent(event)

    def closeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Stop cycling and tell the owner."""
        self.timer.stop()
        super().closeEvent(event)
        self.closed.emit()
