"""The projector's display sink in the app: packed pattern frames on a chosen screen, from any thread.

A DLPC350 takes its 1-bit patterns as bit-planes of 24-bit frames on its video input, so
whoever loads a sequence (the calibration session, the capture service) must also get the
frames onto the screen that feeds the projector's HDMI. The driver does that through a
*display sink* (:mod:`rig_drivers.dlpc350.driver`): ``display(frames)`` with the packed
``(N, H, W, 3)`` uint8 frames, called inside ``load_sequence`` on whatever thread loads it.

:class:`ProjectorDisplay` is that sink for the app. It owns a
:class:`~flexvox_app.gui.projector.window.ProjectorWindow` (the pixel-exact drawing: no scaling, one
image pixel per device pixel) on the chosen screen and is called like a function:

* from the GUI thread it shows the frames at once;
* from any other thread it posts them to the GUI thread through a queued signal and **waits**
  until the GUI thread has put them in the window and painted them (a synchronous
  ``repaint``), at most ``timeout_s``; then it returns, so the caller's next step (start the
  sequence, then accept only camera frames taken after the change) sees the new pattern.
  A GUI thread that does not answer in time (a blocked or missing event loop) raises
  ``TimeoutError``; a window the operator closed (Esc) raises ``RuntimeError``. The driver
  turns either into a :class:`~rig_drivers.dlpc350.ProjectorDisplayError`.

"Painted" is what Qt can promise: the frame is in the window's backing store and flushed to the
window system. The compositor's and the video signal's own latency (a frame or two) come after;
the calibration session skips ``settle_frames`` camera frames after every change for that.

:func:`run_with_projector_screen` is what ``flexvox calibrate|capture --projector-screen N`` use:
a QApplication, the window on screen N, the work on a worker thread while the Qt event loop runs.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QCoreApplication, QEventLoop, QObject, Qt, QThread, QTimer, Signal

from flexvox_app.gui.projector.window import (
    CYCLE_MS,
    ProjectorWindow,
    ScreenGone,
    check_frames,
    live_screen,
    screen_label,
)

_logger = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 5.0
"""Longest wait for the GUI thread to show a frame."""


class ScreenError(ValueError):
    """No screen to show the patterns on (no display, no screens, a bad index); the message says which."""


class _Ticket:
    """One request from a worker thread: the frames, and how it ended."""

    def __init__(self, frames: np.ndarray):
        self.frames = frames
        self.done = threading.Event()
        self.error: str | None = None
        self.lock = threading.Lock()
        self.abandoned = False


class ProjectorDisplay(QObject):
    """The DLPC350's display sink: ``display(frames)`` shows them full-screen, pixel-exact, from any thread.

    Create it in the GUI thread (it lives there). The window opens on the first frames.

    Parameters
    ----------
    screen : QScreen, optional
        Where the projector's video input is (default the primary screen).
    timeout_s : float
        Longest wait, from a worker thread, for the frames to be on screen.
    cycle_ms : int
        Frame interval when there are several frames (K > 24; not locked to the video's vsync).
    """

    shown = Signal(int)
    """The number of frames just put on screen (for a status line)."""
    _requested = Signal(object)

    def __init__(self, screen=None, *, timeout_s: float = DEFAULT_TIMEOUT_S, cycle_ms: int = CYCLE_MS,
                 parent: QObject | None = None):
        super().__init__(parent)
        if isinstance(timeout_s, bool) or not isinstance(timeout_s, int | float) or not 0 < timeout_s <= 600:
            raise ValueError(f"`timeout_s` must be between 0 and 600 s; got {timeout_s!r}")
        self.screen_name: str | None = screen.name() if screen is not None else None  # looked up when shown
        self.timeout_s = float(timeout_s)
        self.cycle_ms = int(cycle_ms)
        self.window: ProjectorWindow | None = None
        self.closed_by_user = False
        """True once the operator closed the window (Esc): further frames are refused."""
        self.frames_shown = 0
        """How many times frames were put on screen."""
        self._closing = False
        self._pending: list[_Ticket] = []
        self._frames_n = 0
        self._requested.connect(self._serve, Qt.ConnectionType.QueuedConnection)

    # ------------------------------------------------------------------ the sink
    def __call__(self, frames) -> None:
        """Show ``frames`` ``(N, H, W, 3)`` uint8; return once they are painted.

        Raises
        ------
        ValueError
            Frames of the wrong shape or type.
        TimeoutError
            They were not painted within ``timeout_s`` (from a worker thread: the GUI thread did not
            answer; from the GUI thread: the window never got a paint event).
        RuntimeError
            The window was closed by the operator.
        """
        frames = check_frames(frames)
        if QThread.currentThread() is self.thread():
            self._show_and_wait(frames)
            return
        ticket = _Ticket(frames)
        self._requested.emit(ticket)
        finished = ticket.done.wait(self.timeout_s)
        with ticket.lock:
            if not finished and not ticket.done.is_set():
                ticket.abandoned = True
                raise TimeoutError(f"the projector window did not show the frames within {self.timeout_s:g} s "
                                   "(the GUI thread is busy or its event loop is not running)")
        if ticket.error is not None:
            raise RuntimeError(ticket.error)

    def _show_and_wait(self, frames: np.ndarray) -> None:
        """GUI thread: show, then let Qt deliver the paint event (bounded)."""
        self._show(frames)
        deadline = time.monotonic() + self.timeout_s
        while not self._painted():
            if time.monotonic() > deadline:
                raise TimeoutError(f"the projector window did not paint the frames within {self.timeout_s:g} s "
                                   "(is it visible on its screen?)")
            QCoreApplication.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 20)
        self._finish()

    def _serve(self, ticket: _Ticket) -> None:
        """GUI thread: a worker's request. Done at once when painted, else at the window's next paint."""
        with ticket.lock:
            if ticket.abandoned:
                return  # the caller gave up: do not change the screen behind its back
            try:
                self._show(ticket.frames)
            except (RuntimeError, ValueError) as exc:
                ticket.error = str(exc)
                ticket.done.set()
                return
            self._pending.append(ticket)
        if self._painted():
            self._finish()

    def _show(self, frames: np.ndarray) -> None:
        if self.closed_by_user:
            raise RuntimeError("the projector output window was closed (Esc): the patterns cannot reach the "
                               "projector")
        if self.window is None:
            screen = live_screen(self.screen_name)
            if screen is None:
                raise ScreenGone(f"the screen {self.screen_name!r} is gone (unplugged?): the patterns cannot reach "
                                 "the projector")
            window = ProjectorWindow(frames, screen=screen, cycle_ms=self.cycle_ms)
            window.closed.connect(self._on_closed)
            window.view.painted_now.connect(self._on_painted)
            self.window = window
            window.open()
            warning = window.size_warning()
            if warning:
                _logger.warning("projector output window: %s", warning)
        else:
            self.window.set_frames(frames)
        self._frames_n = int(frames.shape[0])
        self.window.view.repaint()  # synchronous where the window is exposed; else the next paint event

    def _painted(self) -> bool:
        return self.window is not None and self.window.on_screen()

    def _on_painted(self) -> None:
        if self._pending and self._painted():
            self._finish()

    def _finish(self) -> None:
        """The current frames are painted: release whoever waits for them."""
        self.frames_shown += 1
        pending, self._pending = self._pending, []
        for ticket in pending:
            ticket.done.set()
        self.shown.emit(self._frames_n)

    def _on_closed(self) -> None:
        pending, self._pending = self._pending, []
        for ticket in pending:
            ticket.error = "the projector output window was closed before it showed the frames"
            ticket.done.set()
        if not self._closing:
            self.closed_by_user = True
            _logger.warning("the projector output window was closed by the operator")

    def close(self) -> None:
        """Close the window (GUI thread); a later call opens a new one."""
        window, self.window = self.window, None
        if window is not None:
            self._closing = True
            try:
                window.close()
            finally:
                self._closing = False
            window.closed.disconnect(self._on_closed)
            window.deleteLater()
        self.closed_by_user = False


# --------------------------------------------------------------------------- the command line's host


def screens_or_error():
    """The QApplication's screens, creating the application when needed.

    Raises
    ------
    ScreenError
        When Qt cannot open a window here (:func:`flexvox_app.qt_platform.display_problem`: no display, a
        platform plugin that cannot start), or when Qt reports no screen.
    """
    from PySide6.QtGui import QGuiApplication

    from flexvox_app.gui.widgets.qapp import ensure_application

    if QGuiApplication.instance() is None:
        from flexvox_app.qt_platform import display_problem

        problem = display_problem()
        if problem is not None:
            raise ScreenError(f"no display: --projector-screen needs a desktop session with the projector connected "
                              f"as a screen; {problem}")
    ensure_application()
    screens = QGuiApplication.screens()
    if not screens:
        raise ScreenError(f"no screens: Qt's platform {QGuiApplication.platformName()!r} reports none; connect the "
                          "projector's HDMI input as a screen")
    return screens


def screen_lines() -> list[str]:
    """``index: label`` for every screen (what ``--list-screens`` prints)."""
    return [f"{i}: {screen_label(s)}" for i, s in enumerate(screens_or_error())]


def pick_screen(index: int):
    """The screen at ``index`` (``--projector-screen``), or ScreenError listing the valid ones."""
    screens = screens_or_error()
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(screens):
        names = "; ".join(f"{i}: {screen_label(s)}" for i, s in enumerate(screens))
        raise ScreenError(f"--projector-screen must be 0..{len(screens) - 1} on this desktop; got {index!r} "
                          f"(screens: {names})")
    return screens[index]


def run_with_projector_screen(index: int, work: Callable, *, timeout_s: float = DEFAULT_TIMEOUT_S):
    """Run ``work(display, interrupted)`` on a worker thread while Qt shows its patterns on screen ``index``.

    ``display`` is a :class:`ProjectorDisplay` on that screen (pass it to the DLPC350);
    ``interrupted`` is a ``threading.Event`` set on Ctrl-C (SIGINT) or SIGTERM, which the work
    should poll to stop cleanly. Returns what ``work`` returns; re-raises what it raises (in the
    calling thread). The window is closed at the end.

    Raises
    ------
    ScreenError
        No display, no screens, or ``index`` out of range (before any work starts).
    """
    from PySide6.QtWidgets import QApplication

    screen = pick_screen(index)
    app = QApplication.instance()
    display = ProjectorDisplay(screen, timeout_s=timeout_s)
    interrupted = threading.Event()
    outcome: dict = {}

    class _Done(QObject):
        finished = Signal()

    done = _Done()
    done.finished.connect(app.quit, Qt.ConnectionType.QueuedConnection)

    def body() -> None:
        try:
            outcome["value"] = work(display, interrupted)
        except BaseException as exc:  # handed to the calling thread below, never lost  # noqa: BLE001
            outcome["error"] = exc
        finally:
            done.finished.emit()

    # Python runs signal handlers only between bytecodes: a timer lets it look while Qt's loop runs.
    ticker = QTimer()
    ticker.start(200)
    ticker.timeout.connect(lambda: None)
    handlers = {}
    in_main = threading.current_thread() is threading.main_thread()
    if in_main:
        for sig in (signal.SIGINT, signal.SIGTERM):
            handlers[sig] = signal.signal(sig, lambda *_: interrupted.set())
    quit_on_close = app.quitOnLastWindowClosed()
    app.setQuitOnLastWindowClosed(False)  # Esc on the projector window must not end the loop under the work
    worker = threading.Thread(target=body, name="flexvox-rig-work", daemon=True)
    worker.start()
    try:
        app.exec()
    finally:
        app.setQuitOnLastWindowClosed(quit_on_close)
        ticker.stop()
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
        display.close()
    worker.join(timeout_s)
    if worker.is_alive():
        raise RuntimeError(f"the rig work did not end within {timeout_s:g} s after the event loop stopped")
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")
