"""Review's preview scheduling (Qt-free): when a preview of the form's settings is wanted, and which one shows.

A preview reconstructs a small window of camera frames around the current one
(:func:`~flexvox_app.gui.models.jobs.preview_window`) off the GUI thread. :class:`PreviewModel` says when one is
wanted (:attr:`PreviewModel.preview_wanted`: a knob moved, playback paused, a frame outside what is shown; the
view waits a moment for more changes, then calls :meth:`PreviewModel.request_preview`), keeps only the newest
request's result, and puts it in place of the chosen method's result or beside it
(:class:`~flexvox_app.gui.models.review_playback.PlaybackModel`'s ``shown`` and ``comparison``). The chosen
method's full result is shown itself, never a preview of it.
"""

from __future__ import annotations

from flexvox_app.capture.events import Signal
from flexvox_app.gui.models.jobs import ReconstructionResult, preview_window, run_reconstruction
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.review_jobs import JobsModel, Line
from flexvox_app.gui.models.review_playback import PlaybackModel


class PreviewModel:
    """Review's preview scheduling, without Qt.

    Parameters
    ----------
    runner
        Runs the previews off the GUI thread (``submit``, as :class:`~flexvox_app.gui.models.review_jobs.JobsModel`'s).
    settings
        Keeps the live preview switch (``review/preview``): an object with ``get_bool`` and ``set``.
    playback : PlaybackModel
        The current sub-frame, and where a preview shows; its ``preview_due`` asks for one.
    jobs : JobsModel
        The full results (the chosen method's is shown instead of a preview of it); a failed preview is said on
        its result line.

    Attributes
    ----------
    preview_wanted : Signal
        ``()``: a preview of the form's settings around the current frame is due.
    """

    def __init__(self, runner, settings, playback: PlaybackModel, jobs: JobsModel):
        self.runner = runner
        self.settings = settings
        self.playback = playback
        self.jobs = jobs
        self.preview_on = settings.get_bool("review/preview", True)
        """The live preview switch."""
        self.preview_job = None
        """The handle of the preview running or last run."""
        self._generation = 0
        self.closed = False
        """The window closes: no preview is wanted and none is submitted any more."""
        self.preview_wanted = Signal("preview wanted", contain=False)
        playback.preview_due.connect(self.want_preview)

    def set_preview_on(self, on: bool) -> None:
        """The live preview switch."""
        self.preview_on = bool(on)
        self.settings.set("review/preview", self.preview_on)
        if self.preview_on:
            self.want_preview()

    def want_preview(self) -> None:
        """Ask for a preview (:attr:`preview_wanted`) when one can be made now."""
        s = self.playback.session
        if not self.closed and s is not None and s.frames is not None and self.preview_on:
            self.preview_wanted.emit()

    def request_preview(self, method, chosen, comparing: bool):
        """Recompute ``method`` on a small window of frames around the current one; returns the job's handle.

        Parameters
        ----------
        method : Method
            What to preview (the form's preview method).
        chosen : Method
            The form's method: when it has a full result, that result is shown instead of a preview of it, and
            with ``comparing`` the preview shows beside it.
        comparing : bool
            The slider previews another method than the chosen one.
        """
        p = self.playback
        s = p.session
        if s is None or s.frames is None or self.closed:
            return None
        self.cancel()
        gen = self._generation
        full = self.jobs.full_result_of(chosen)
        beside = comparing and full is not None
        if not beside:
            p.set_comparison(None)
        if full is not None and (beside or method == full.method):
            if p.shown is not full:  # the result itself, never a preview of it
                p.set_shown(full)
            if not beside:
                return None
        a, b = preview_window(s.n_frames, p.subframe // s.K, half_width=1, missing=s.missing)
        frames, code = s.input(method)
        frames, truth = frames[a:b], s.truth(a, b)
        missing = None if s.missing is None else s.missing[a:b]

        def work(token, progress):
            r = run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=b - a,
                                   first_frame=a, truth=truth, missing=missing)
            r.extra["preview"] = True
            return r

        self.preview_job = self.runner.submit(
            "preview", work, on_finished=lambda r, g=gen: self._preview_done(r, g, beside),
            on_failed=lambda msg, g=gen: g == self._generation and self.jobs.set_result_line(
                Line(f"preview failed: {in_gui_words(msg)}")))
        return self.preview_job

    def _preview_done(self, result: ReconstructionResult, generation: int, beside: bool) -> None:
        if generation != self._generation:
            return  # a newer request, or cancel (another recording opened), superseded it
        if beside:
            self.playback.set_comparison(result)
        else:
            self.playback.set_shown(result)

    def cancel(self) -> None:
        """Cancel the preview running: its result is not shown, even one that finished and is on its way to the
        GUI thread (another recording may have opened)."""
        self._generation += 1
        if self.preview_job is not None and self.preview_job.running:
            self.preview_job.cancel()

    def shutdown(self) -> None:
        """The window closes: cancel the preview; after this none is wanted or submitted."""
        self.closed = True
        self.cancel()
