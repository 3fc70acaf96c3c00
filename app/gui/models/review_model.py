"""The Review workspace's model (Qt-free): the recording open, and the three parts that work on it.

:class:`ReviewModel` is a thin composition: it opens a recording (a
:class:`~flexvox_app.gui.models.review_session.ReviewSession`, read off the GUI thread), hands it to its three
parts, and gives the widget (:class:`flexvox_app.gui.review.workspace.ReviewWorkspace`) one entry:

* :attr:`ReviewModel.playback` (:class:`~flexvox_app.gui.models.review_playback.PlaybackModel`): the current
  sub-frame, playing or not, the speed, and what the panels show (a result or a preview, and the slider's preview
  beside it);
* :attr:`ReviewModel.preview` (:class:`~flexvox_app.gui.models.review_preview.PreviewModel`): when a preview of the
  form's settings around the current frame is wanted, and which one is current;
* :attr:`ReviewModel.jobs` (:class:`~flexvox_app.gui.models.review_jobs.JobsModel`): full reconstructions with
  progress and Cancel, the export of what is shown, and the timing of each method on this machine that the
  expected time comes from.

Each part says what changed through one :class:`~flexvox_app.capture.events.Signal` per thing that changes
(``playback.frame_changed``, ``jobs.result_changed``, …), called on the thread that drives it; a view connects to
those it shows. Long work runs as jobs of a runner (:class:`flexvox_app.gui.widgets.qt_jobs.JobRunner`, see
:mod:`~flexvox_app.gui.models.review_jobs`). The settings kept (playback speed, the preview switch, each method's
speed on this machine, the last folders) go to a settings object with ``get_str``, ``get_int``, ``get_bool``,
``set`` and ``remember_folder`` (:class:`flexvox_app.gui.widgets.settings.AppSettings`).
"""

from __future__ import annotations

import logging
from pathlib import Path

from flexvox_app.capture.events import Signal
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.review_jobs import JobsModel, Line
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_preview import PreviewModel
from flexvox_app.gui.models.review_session import ReviewSession

__all__ = ["Line", "ReviewModel"]

_logger = logging.getLogger(__name__)


class ReviewModel:
    """What the Review workspace holds and decides, without Qt: the recording open and the three parts that own
    the rest (playback, preview scheduling, jobs and export; see the module docstring).

    Parameters
    ----------
    runner
        Runs loading, reconstructions, previews, exports and timings off the GUI thread.
    settings
        Where the playback speed, the preview switch, the speeds on this machine and the last folders are kept.
    quality_table : dict or None
        The shipped bench figures (:func:`flexvox_app.gui.models.expected_quality.load_table`).

    Attributes
    ----------
    playback : PlaybackModel
    preview : PreviewModel
    jobs : JobsModel
    path_changed : Signal
        ``(line)``: :attr:`path_line` changed (opening, or a refusal to open).
    opened : Signal
        ``(session)``: a recording was opened; the parts hold it (nothing shown yet, no results).
    status : Signal
        ``(text)``: one line for the window's status bar (the jobs' too: it is :attr:`JobsModel.status`).
    """

    def __init__(self, runner, settings, quality_table: dict | None):
        self.runner = runner
        self.settings = settings
        self.session: ReviewSession | None = None
        """The recording open (None before one is)."""
        self.playback = PlaybackModel(settings)
        self.jobs = JobsModel(runner, settings, quality_table, self.playback)
        self.preview = PreviewModel(runner, settings, self.playback, self.jobs)
        self.path_line = Line("no recording open")
        self.path_changed = Signal("path changed", contain=False)
        self.opened = Signal("opened", contain=False)
        self.status = self.jobs.status

    def open(self, path):
        """Open ``path`` off the GUI thread; :attr:`opened` fires when it is ready. Returns the job's handle."""
        path = Path(path)
        self._say_path(Line(f"opening {path} …"))
        return self.runner.submit("open", lambda token, progress: ReviewSession.open(path),
                                  on_finished=self._opened, on_failed=lambda message: self.open_refused(path, message))

    def open_refused(self, path, message: str) -> None:
        """Say that ``path`` was not opened, and why; the path line names what is open still (the frames and the
        actions shown are its)."""
        path = Path(path)
        message = in_gui_words(message)
        if self.session is not None:
            self._say_path(Line(f"{self.session.path} (still open) — cannot open {path.name}: {message}", error=True))
        else:
            self._say_path(Line(f"cannot open {path.name}: {message}", error=True))
        self.status.emit(f"cannot open {path.name}: {message}")

    def _opened(self, session: ReviewSession) -> None:
        self.playback.set_playing(False)
        self.cancel()
        self.session = session
        self.playback.set_session(session)
        self.jobs.set_session(session)
        self.settings.remember_folder(session.path, "review/last_dir")
        self.settings.set("review/last_recording", str(session.path))
        self.path_line = Line(str(session.path))  # the view shows it with the session
        self.opened.emit(session)
        self.status.emit(f"opened {session.path.name}")
        self.preview.want_preview()

    def cancel(self) -> None:
        """Cancel a running reconstruction (the preview is cancelled too); it stops after its current chunk."""
        self.jobs.cancel()
        self.preview.cancel()

    def shutdown(self) -> None:
        """The window closes: stop playback and cancel the jobs; after this no preview is wanted and no job is
        submitted."""
        self.preview.shutdown()
        self.jobs.shutdown()
        self.playback.set_playing(False)

    def _say_path(self, line: Line) -> None:
        self.path_line = line
        self.path_changed.emit(line)
