"""Review's playback (Qt-free): the current sub-frame, playing or not, the speed, and what the panels show.

:class:`PlaybackModel` holds the sub-frame shown, whether playback runs, its speed (sub-frames per second, or the
recording's own rate in real time) and how far a tick of the view's timer advances (:func:`playback_advance`), and
what the reconstruction panel shows (:attr:`PlaybackModel.shown`, a full result or a preview) with the slider's
preview beside it (:attr:`PlaybackModel.comparison`). Each part that changes has its own
:class:`~flexvox_app.capture.events.Signal`, emitted on the thread that drives the model (the GUI thread).
:attr:`PlaybackModel.preview_due` says when what is shown stops covering the frame of a paused playback; Review's
preview scheduling (:class:`~flexvox_app.gui.models.review_preview.PreviewModel`) decides whether a preview is made.
"""

from __future__ import annotations

import time

from flexvox_app.capture.events import Signal
from flexvox_app.gui.models.jobs import ReconstructionResult
from flexvox_app.gui.models.review_session import ReviewSession

MAX_DRAWS_HZ = 30
"""Playback draws at most this many pictures a second; faster speeds skip sub-frames between them."""


def playback_advance(elapsed_s: float, speed: float, step: int, carried: float = 0.0) -> tuple[int, float]:
    """Sub-frames to advance after ``elapsed_s`` at ``speed`` sub-frames/s, in whole ``step`` s, and the part
    carried to the next tick.

    Examples
    --------
    >>> playback_advance(1.0, 240.0, 16)   # real time at 15 Hz × 16: a second is 15 raw frames
    (240, 0.0)
    >>> playback_advance(0.05, 12.0, 1, 0.5)
    (1, 0.10000000000000009)
    """
    total = carried + max(0.0, elapsed_s) * speed
    n = int(total // step) * step
    return n, total - n


class PlaybackModel:
    """Where playback stands in the recording open, and what the panels show, without Qt.

    Parameters
    ----------
    settings
        Keeps the speed box's speed (``review/fps``) and the real-time switch (``review/real_time``): an object
        with ``get_int``, ``get_bool`` and ``set``.

    Attributes
    ----------
    frame_changed : Signal
        ``(s)``: the current sub-frame is now ``s``.
    playing_changed : Signal
        ``(playing)``: playback started or stopped.
    speed_changed : Signal
        ``()``: the speed box's speed or the real-time switch changed (:meth:`interval_ms` may have).
    shown_changed : Signal
        ``(result)``: the reconstruction panel shows ``result`` (None: nothing).
    comparison_changed : Signal
        ``(result)``: the slider's preview beside it is ``result`` (None: hidden).
    preview_due : Signal
        ``()``: playback is paused where nothing shown covers the frame (or was just paused), so a preview
        would be wanted.
    """

    def __init__(self, settings):
        self.settings = settings
        self.session: ReviewSession | None = None
        self.subframe = 0
        """The current sub-frame index s (camera frame s // K)."""
        self.playing = False
        self.fps = settings.get_int("review/fps", 12)
        """The speed box's playback speed, in sub-frames per second."""
        self.real_time = settings.get_bool("review/real_time", False)
        self.last_tick, self.carried = 0.0, 0.0
        self.shown: ReconstructionResult | None = None
        """What the reconstruction panel shows: a full result or a preview."""
        self.comparison: ReconstructionResult | None = None
        """The slider's preview shown beside :attr:`shown` (the chosen method's full result), or None."""
        self.frame_changed = Signal("frame changed", contain=False)
        self.playing_changed = Signal("playing changed", contain=False)
        self.speed_changed = Signal("speed changed", contain=False)
        self.shown_changed = Signal("shown changed", contain=False)
        self.comparison_changed = Signal("comparison changed", contain=False)
        self.preview_due = Signal("preview due", contain=False)

    def set_session(self, session: ReviewSession | None) -> None:
        """A recording was opened: back to its first sub-frame, nothing shown (no signal: the view shows the
        session whole)."""
        self.session = session
        self.subframe = 0
        self.shown = None
        self.comparison = None

    def set_playing(self, playing: bool) -> None:
        """Start or stop playback (stopping makes a preview due where it stopped)."""
        self.playing = bool(playing) and self.session is not None
        if self.playing:
            self.last_tick, self.carried = time.monotonic(), 0.0
        self.playing_changed.emit(self.playing)
        if not self.playing:
            self.preview_due.emit()

    def step(self) -> int:
        """Sub-frames a tick advances by at least: one under a shown reconstruction, else a whole camera frame."""
        return 1 if self.shown is not None or self.session is None else self.session.K

    def subframe_hz(self) -> float | None:
        """The recording's sub-frame rate (its real time), None when it does not say."""
        if self.session is None:
            return None
        rate = self.session.recording.attrs.get("rates", {}).get("subframe_hz")
        return float(rate) if rate else None

    def speed(self) -> float:
        """Playback speed in sub-frames per second: the recording's own rate in real time, else the speed box's."""
        rate = self.subframe_hz()
        return rate if self.real_time and rate else float(self.fps)

    def interval_ms(self) -> int:
        """Time between two pictures: one step at the speed, but never more than :data:`MAX_DRAWS_HZ` a second."""
        return max(round(1000 / MAX_DRAWS_HZ), round(1000 * self.step() / self.speed()))

    def tick(self, now: float | None = None) -> None:
        """Advance playback by the time since the last tick (``now``: ``time.monotonic()``), wrapping at the end."""
        if self.session is None:
            return
        now = time.monotonic() if now is None else now
        n, self.carried = playback_advance(now - self.last_tick, self.speed(), self.step(), self.carried)
        self.last_tick = now
        if n:
            self.set_subframe((self.subframe + n) % self.session.n_subframes)

    def set_fps(self, fps: int) -> None:
        """The speed box's speed (sub-frames per second)."""
        self.fps = int(fps)
        self.settings.set("review/fps", self.fps)
        self.speed_changed.emit()

    def set_real_time(self, on: bool) -> None:
        """Play at the recording's own rate (or at the speed box's)."""
        self.real_time = bool(on)
        self.settings.set("review/real_time", self.real_time)
        self.speed_changed.emit()

    def set_subframe(self, s: int) -> None:
        """Show sub-frame ``s``; once paused, a preview is due when what is shown does not cover it."""
        self.subframe = int(s)
        self.frame_changed.emit(self.subframe)
        if not self.playing and (not self.covers(self.shown, s)
                                 or self.comparison is not None and not self.covers(self.comparison, s)):
            self.preview_due.emit()

    def covers(self, r: ReconstructionResult | None, s: int) -> bool:
        """True when ``r`` holds sub-frame ``s`` of the recording."""
        if r is None or self.session is None:
            return False
        i = s - r.first_frame * self.session.K
        return 0 <= i < r.video.shape[0]

    def set_shown(self, result: ReconstructionResult | None) -> None:
        """Show ``result`` in the reconstruction panel."""
        self.shown = result
        self.shown_changed.emit(result)

    def set_comparison(self, result: ReconstructionResult | None) -> None:
        """Show the slider's preview beside the chosen method's result (None: hide it)."""
        self.comparison = result
        self.comparison_changed.emit(result)
