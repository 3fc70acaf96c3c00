"""Review's jobs (Qt-free): full reconstructions with progress and Cancel, the export, the expected time.

:class:`JobsModel` runs the full reconstructions of the recording open (off the GUI thread, cancellable between
chunks), keeps them (:attr:`JobsModel.results`, oldest first), writes what the reconstruction panel shows over
every frame (:meth:`JobsModel.export`: a preview is reconstructed in full first), and times each method on this
machine once, where the expected time of a reconstruction comes from. A full reconstruction of a recording without
ground truth is scored from the recording alone (:func:`flexvox_core.accuracy.estimate_recording`, one more job off
the GUI thread; about one more reconstruction's time): the result line and the result's label then say
``estimated PSNR NN.NN dB (± …)``; a method the estimate refuses (:func:`flexvox_core.accuracy.refusal`) keeps why
in the result's ``no_estimate``, and the lines say nothing of it. Where the recording has a ground truth, the line
says the true PSNR and nothing is estimated. It says what it did on its two lines
(:attr:`JobsModel.result_line`, :attr:`JobsModel.export_line`) and the progress bar's ``(done, total)``; each
has its own :class:`~flexvox_app.capture.events.Signal`, emitted on the thread that drives the model.

Jobs go to a runner with ``submit(name, fn, *, on_progress, on_finished, on_failed, on_cancelled, on_done) ->
handle`` (:class:`flexvox_app.gui.widgets.qt_jobs.JobRunner`, whose callbacks run on the GUI thread); a handle has
``outcome``, ``running``, ``token`` and ``cancel()``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from flexvox_app.capture.events import Signal
from flexvox_app.gui.models.choice_job import choice_lines, run_choice
from flexvox_app.gui.models.expected_quality import Expectation, expected, format_seconds
from flexvox_app.gui.models.jobs import ReconstructionResult, chunk_frames_for, run_reconstruction
from flexvox_app.gui.models.machine_speed import SpeedModel, calibrate, estimate_seconds, is_current, settings_key
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.accuracy import REFUSED_MULTIPLEXED, estimate_recording, noise_of, refusal
from flexvox_core.choice import candidates_for
from flexvox_core.output_files import OutputError, check_output
from flexvox_core.video_io import check_mp4_size, write_video

_logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Line:
    """A status line's plain text, and whether it says something failed or was refused."""

    text: str = ""
    error: bool = False


class JobsModel:
    """Review's full reconstructions, export and expected times, without Qt.

    Parameters
    ----------
    runner
        Runs the reconstructions, exports and timings off the GUI thread (see the module docstring).
    settings
        Keeps each method's speed on this machine and the last export folder: an object with ``get_str``,
        ``set`` and ``remember_folder`` (:class:`flexvox_app.gui.widgets.settings.AppSettings`).
    quality_table : dict or None
        The shipped bench figures (:func:`flexvox_app.gui.models.expected_quality.load_table`).
    playback : PlaybackModel
        What the reconstruction panel shows (an export writes it; a new result is shown there) and the speed an
        export's video plays at.

    Attributes
    ----------
    result_changed : Signal
        ``(line)``: :attr:`result_line` changed.
    export_changed : Signal
        ``(line)``: :attr:`export_line` changed.
    progress_changed : Signal
        ``(done, total)``: the progress bar's job moved.
    jobs_changed : Signal
        ``()``: a reconstruction or export started or ended, or was asked to stop (what can be pressed changed).
    expected_changed : Signal
        ``()``: a method was timed on this machine (the expected time can be said now).
    result_added : Signal
        ``(result)``: a full reconstruction was added to :attr:`results`.
    estimate_changed : Signal
        ``(result)``: a result of :attr:`results` got its estimate, or why it has none.
    status : Signal
        ``(text)``: one line for the window's status bar.
    """

    def __init__(self, runner, settings, quality_table: dict | None, playback: PlaybackModel):
        self.runner = runner
        self.settings = settings
        self.table = quality_table
        self.playback = playback
        self.session: ReviewSession | None = None
        self.results: list[ReconstructionResult] = []
        """The full reconstructions, oldest first."""
        self.truth = None
        """The ground truth of the recording open, when it has one: an array-like read where it is used (a job reads
        it whole off the GUI thread; the Compare view a sub-frame at a time), never at open."""
        self.exported: tuple[Path, ReconstructionResult] | None = None
        """The last export: its path and the full result written."""
        self._written: list[ReconstructionResult] = []
        """Every full result exported (the others are lost when the window closes)."""
        self.job = None
        """The handle of the full reconstruction (or the export reconstructing one) running or last run."""
        self._expected_for_job: float | None = None
        self._said: tuple[ReconstructionResult, str] | None = None
        """The result the result line speaks of and its text without the estimate."""
        self._estimates: list = []
        """The handles of the estimates running or run for the recording open."""
        self._speed_jobs: dict[str, object] = {}
        self.closed = False
        """The window closes: no job is submitted any more."""
        self.result_line = Line()
        self.export_line = Line()
        self.progress = (0, 1)
        """``(done, total)`` of the job the progress bar follows."""
        self.result_changed = Signal("result changed", contain=False)
        self.export_changed = Signal("export changed", contain=False)
        self.progress_changed = Signal("progress changed", contain=False)
        self.jobs_changed = Signal("jobs changed", contain=False)
        self.expected_changed = Signal("expected changed", contain=False)
        self.result_added = Signal("result added", contain=False)
        self.estimate_changed = Signal("estimate changed", contain=False)
        self.status = Signal("status", contain=False)

    def set_session(self, session: ReviewSession) -> None:
        """A recording was opened: no results, empty lines (they spoke of the recording before), no progress."""
        self.cancel_estimates()
        self.session = session
        self.results = []
        self._written = []
        self.truth = session.recording.ground_truth if session.has_ground_truth else None  # read where used
        self._set_progress(0, 1)
        self.set_result_line(Line())
        self.set_export_line(Line())

    # ------------------------------------------------------------------ full reconstruction
    def reconstruct(self, method, *, auto_knob: str | None = None):
        """Reconstruct every frame with ``method`` (off-thread, cancellable); the job's handle, or None when it
        cannot start now.

        ``auto_knob`` (``time``, ``block``): choose that knob by the estimated PSNR first
        (:func:`~flexvox_app.gui.models.choice_job.run_choice`: each candidate reconstructed and estimated, the
        progress counting candidates); the result keeps the chosen method, the choice in ``extra["choice"]`` and
        the chosen candidate's estimate, and the result line says what was chosen and what choosing cost."""
        s = self.session
        if s is None or s.frames is None or self.busy or self.closed:
            return None
        chunk = chunk_frames_for(method, s.n_frames, s.K)
        (frames, code), truth, missing = s.input(method), self.truth, s.missing

        if auto_knob is None:
            def work(token, progress):
                return run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=chunk,
                                          truth=truth, missing=missing)

            self._set_progress(0, s.n_frames)
            self._expected_for_job = self.expected_seconds(method)
            self.set_result_line(Line(f"reconstructing with {method.label()} …"))
        else:
            if s.reader is not None and s.reader.multiplexed is not None:  # the estimate refuses such captures
                self.set_result_line(Line(in_gui_words(
                    f"cannot choose {method.name}'s {auto_knob} by the estimate on a multiplexed recording: "
                    f"{REFUSED_MULTIPLEXED}"), error=True))
                return None
            noise = noise_of(s.recording)
            frames, code = s.frames, s.code  # the estimate reads the identity-code capture

            def work(token, progress):
                return run_choice(frames, code, method, auto_knob, cancel=token, progress=progress,
                                  chunk_frames=chunk, truth=truth, missing=missing, noise=noise)

            self._set_progress(0, len(candidates_for(method, auto_knob, code)))
            self._expected_for_job = None
            self.set_result_line(Line(f"choosing {method.name}'s {auto_knob} by the estimated PSNR …"))
        self.job = self.runner.submit(
            "reconstruct", work, on_progress=self._progressed,
            on_finished=lambda result: s is self.session and self._reconstructed(result),
            on_cancelled=lambda: self._reconstruction_cancelled(s),
            on_failed=lambda msg: s is self.session and self.set_result_line(
                Line(f"reconstruction failed: {in_gui_words(msg)}", error=True)),
            on_done=self.jobs_changed.emit)
        self.jobs_changed.emit()
        return self.job

    @property
    def busy(self) -> bool:
        """True while a full reconstruction runs (its outcome is set the moment it ends)."""
        return self.job is not None and self.job.outcome is None

    @property
    def cancellable(self) -> bool:
        """A full reconstruction runs and was not asked to stop yet."""
        return self.busy and not self.job.token.cancelled

    def cancel(self) -> None:
        """Cancel a running reconstruction (or the export reconstructing one); it stops after its current chunk."""
        if self.cancellable:
            self.job.token.cancel()
            self.set_result_line(Line("cancelling … (the current chunk of frames finishes first)"))
            self.jobs_changed.emit()
        if self.job is not None and self.job.running:
            self.job.cancel()

    def _reconstruction_cancelled(self, session) -> None:
        if session is not self.session:  # cancelled because another recording opened: nothing to say of it
            return
        self._set_progress(0, self.progress[1])
        self.set_result_line(Line("cancelled; nothing was kept"))
        self.status.emit("reconstruction cancelled")

    def _reconstructed(self, result: ReconstructionResult) -> None:
        self.results.append(result)
        self._set_progress(self.progress[1], self.progress[1])
        vox = result.video.size / max(result.seconds, 1e-9) / 1e6
        text = f"{result.method.label()}: {result.video.shape[0]} sub-frames in {result.seconds:.2f} s " \
               f"{result.where} ({vox:.2g} M voxels/s)"
        if result.psnr is not None:
            text += f"; PSNR vs ground truth {result.psnr:.2f} dB"
        expected_s, self._expected_for_job = self._expected_for_job, None
        if expected_s is not None:
            text += f" (expected ≈ {format_seconds(expected_s)})"
        H, W = result.video.shape[1:]
        _logger.info("reconstruction %s of %d sub-frames of %dx%d: measured %.3f s, expected %s", result.method.label(),
                     result.video.shape[0], W, H, result.seconds,
                     "unknown (not timed yet)" if expected_s is None else f"{expected_s:.3f} s")
        choice = result.extra.get("choice")
        if choice is not None:  # chosen by the estimate: it has one already
            result.estimate = choice.estimate
            head, *_ = choice_lines(result)
            text += f"; {head}; {choice.cost()}"
            estimating = False
            if self.truth is None:
                text += f"; {choice.estimate.line()}"
            for line in choice_lines(result)[1:-1]:
                _logger.info("%s", line)
        else:
            estimating = self._estimate(result)
        self.set_result_line(Line(text + ("; estimating its PSNR from the recording …" if estimating else "")))
        self._said = (result, text)
        self.playback.set_shown(result)
        self.result_added.emit(result)
        self.status.emit(text)

    # ------------------------------------------------------------------ accuracy without ground truth
    def _estimate(self, result: ReconstructionResult) -> bool:
        """Start estimating ``result``'s PSNR when the recording has no ground truth and the method is offered;
        True when an estimate job started (a refused method's reason goes to ``result.no_estimate``)."""
        s = self.session
        if s is None or self.truth is not None or self.closed:
            return False
        why = refusal(result.method)
        if why is not None:
            result.no_estimate = in_gui_words(why)
            return False
        chunk = chunk_frames_for(result.method, s.n_frames, s.K)

        def work(token, progress):
            token.check()  # and after each chunk of its runs: Cancel stops the estimate there
            return estimate_recording(s.path, result.method, reconstruction=result.video, chunk_frames=chunk,
                                      device=result.device, progress=lambda done, total: token.check())

        self._estimates.append(self.runner.submit(
            "estimate", work, on_finished=lambda est: s is self.session and self._estimated(result, est),
            on_failed=lambda msg: s is self.session and self._not_estimated(result, msg)))
        return True

    def _estimated(self, result: ReconstructionResult, estimate) -> None:
        result.estimate = estimate
        _logger.info("%s: %s", result.method.label(), estimate.line())
        if self._said is not None and self._said[0] is result:
            self.set_result_line(Line(f"{self._said[1]}; {estimate.line()}"))
        self.estimate_changed.emit(result)

    def _not_estimated(self, result: ReconstructionResult, message: str) -> None:
        result.no_estimate = in_gui_words(message)
        if self._said is not None and self._said[0] is result:
            self.set_result_line(Line(self._said[1]))
        self.estimate_changed.emit(result)

    def cancel_estimates(self) -> None:
        """Drop the estimates running (another recording opens, or the window closes); each stops after its current
        chunk."""
        for h in self._estimates:
            if h.running:
                h.cancel()
        self._estimates = []

    def full_result_of(self, method) -> ReconstructionResult | None:
        """The newest full reconstruction made with exactly ``method`` (None: none yet)."""
        return next((r for r in reversed(self.results) if r.method == method), None)

    def flow_result(self) -> ReconstructionResult | None:
        """The result whose flow and TR map the Motion tab shows: the shown one when it has a flow, else the
        newest full result with one (a preview of another method never hides a full motion-aware result)."""
        shown = self.playback.shown
        if shown is not None and shown.flow is not None:
            return shown
        return next((r for r in reversed(self.results) if r.flow is not None), None)

    # ------------------------------------------------------------------ export
    def export_candidate(self) -> ReconstructionResult | None:
        """What the reconstruction panel shows (a full result or a preview), else the newest full result."""
        if self.playback.shown is not None:
            return self.playback.shown
        return self.results[-1] if self.results else None

    def export(self, path, *, overwrite: bool | None = None, ask: Callable[[Path], bool] = lambda path: False):
        """Write what the panel shows, over every frame, to ``path`` (.tif, .mp4, .npy, .zarr) off the GUI thread;
        the job's handle, or None when nothing is written (:attr:`export_line` says why).

        A full reconstruction is written as it is. A preview is written as the full reconstruction with the same
        method and options: an existing one, or one made now (with progress and Cancel) and then kept in the
        results. A .zarr export carries the method, its options and the source in its ``flexvox`` attributes;
        the line names the method and its options whatever the format. An existing ``path`` is replaced when
        ``overwrite`` is True, kept when it is False, and otherwise when ``ask(path)`` says so.
        """
        r = self.export_candidate()
        s = self.session
        if r is None or s is None:
            self.set_export_line(Line("nothing to export: reconstruct, or preview, first"))
            return None
        if r.extra.get("preview") and (s.frames is None or self.busy):
            self.set_export_line(Line("not exported: wait for the running reconstruction to end", error=True)
                                 if s.frames is not None else Line("not exported: this recording cannot be "
                                                                   "reconstructed"))
            return None
        path = Path(path)
        self.settings.remember_folder(path, "review/export_dir")
        if overwrite is None and path.exists() and path.resolve() != s.path.resolve():  # the recording: refused
            if not ask(path):
                self.set_export_line(Line(f"not exported: {path} is kept (choose another path)"))
                return None
            overwrite = True
        overwrite = bool(overwrite)
        try:  # never onto the recording under review; the folder must take the file
            check_output(path, overwrite=overwrite, inputs=[s.path])
        except OutputError as exc:
            self.set_export_line(Line(f"not exported: {in_gui_words(str(exc))}", error=True))
            return None
        method = r.method
        full = r if not r.extra.get("preview") else self.full_result_of(method)
        if path.suffix.lower() == ".mp4":  # said now, not after a reconstruction made for it
            try:
                check_mp4_size((full.video if full is not None else s.frames).shape[1:], path)
            except ValueError as exc:
                self.set_export_line(Line(f"not exported: {exc}", error=True))
                return None
        fps = float(self.playback.fps)
        (frames, code), truth, missing = s.input(method), self.truth, s.missing
        chunk = chunk_frames_for(method, s.n_frames, s.K)
        source = str(s.path)
        rate = s.recording.attrs.get("rates", {}).get("subframe_hz")
        time_step = 1.0 / float(rate) if rate else None  # Fiji and OME-Zarr readers then show seconds

        def work(token, progress):
            result = full
            if result is None:
                result = run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=chunk,
                                            truth=truth, missing=missing)
                token.check()
            attrs = {"source": source, "method": method.as_dict(), "method_label": method.label(),
                     "seconds": result.seconds, "subframes": int(result.video.shape[0])}
            write_video(path, result.video, fps=fps, attrs=attrs, overwrite=overwrite, time_step=time_step,
                        interpolated=result.extra.get("interpolated"))
            return result, path

        what = f"{method.label()} ({s.n_frames} frames, {s.n_subframes} sub-frames)"
        if full is None:
            self.set_export_line(Line(f"reconstructing all frames with {what} to export what is shown …"))
            self._set_progress(0, s.n_frames)
        else:
            self.set_export_line(Line(f"writing {path.name}: {what} …"))
        handle = self.runner.submit(
            "export", work, on_progress=self._progressed,
            on_finished=lambda out: self._exported(out, full is None, what, s),
            on_cancelled=lambda: s is self.session and self.set_export_line(
                Line("export cancelled; nothing was written")),
            on_failed=lambda msg: self.status.emit(f"export of {s.path.name} failed: {in_gui_words(msg)}")
            if s is not self.session else self.set_export_line(
                Line(f"export failed: {in_gui_words(msg)}", error=True)),
            on_done=self.jobs_changed.emit)
        if full is None:
            self.job = handle  # Cancel stops it; Reconstruct waits for it
            self.jobs_changed.emit()
        return handle

    def _exported(self, out, reconstructed: bool, what: str, session: ReviewSession) -> None:
        result, path = out
        if session is not self.session:  # another recording opened meanwhile: the file is written, say so only
            self.status.emit(f"exported {path.name}: {what} of {session.path.name}")
            return
        if reconstructed:
            self._reconstructed(result)
        self.exported = (path, result)
        self._written.append(result)
        self.set_export_line(Line(f"wrote {path}: {what}"))
        self.status.emit(f"exported {path.name}: {what}")

    # ------------------------------------------------------------------ expected time and quality
    def speed_model(self, name: str, K: int) -> SpeedModel | None:
        """This machine's calibrated speed of method ``name`` at K slots (None: not measured by this version)."""
        model = SpeedModel.from_json(self.settings.get_str(settings_key(name, K), ""))
        return model if is_current(model) else None

    def expected_seconds(self, method) -> float | None:
        """Expected seconds of a full reconstruction with ``method`` on this machine (None: not known yet)."""
        s = self.session
        if s is None:
            return None
        model = self.speed_model(method.name, s.K)
        if model is None:
            return None
        H, W = s.shape
        return estimate_seconds(model, self.table, method, s.code, n_frames=s.n_frames, H=H, W=W)

    def expected(self, method) -> tuple[Expectation | None, float | None]:
        """The bench's expectation for ``method`` on the recording open and the seconds expected here; when the
        method was not timed on this machine yet, a timing starts (:attr:`expected_changed` fires when done)."""
        s = self.session
        e = expected(self.table, method, s.code, voxels=s.n_subframes * s.shape[0] * s.shape[1])
        seconds = self.expected_seconds(method)
        if seconds is None:
            self._calibrate_speed(method.name, s.code)
        return e, seconds

    def _calibrate_speed(self, name: str, code) -> None:
        """Time method ``name`` on this machine (off the GUI thread, once per method and K; kept in the settings)."""
        K = int(code.shape[2])
        key = settings_key(name, K)
        job = self._speed_jobs.get(key)
        if self.closed or (job is not None and job.outcome in (None, "finished")):
            return

        def done(model: SpeedModel) -> None:
            self.settings.set(key, model.to_json())
            self.expected_changed.emit()

        self._speed_jobs[key] = self.runner.submit(
            "machine speed", lambda token, progress: calibrate(name, code, cancel=token), on_finished=done,
            on_failed=lambda msg: _logger.warning("timing %s on this machine failed: %s", name, msg))

    # ------------------------------------------------------------------ the end
    def unexported(self) -> list[ReconstructionResult]:
        """The full reconstructions never exported (closing the window loses them)."""
        return [r for r in self.results if not any(r is w for w in self._written)]

    def closing_losses(self) -> list[str]:
        """What closing the window would stop or lose now: a reconstruction or export running, results not
        exported."""
        out = []
        if self.busy:
            out.append("the reconstruction running stops; what it computed is lost")
        lost = self.unexported()
        if lost:
            names = "; ".join(r.method.label() for r in lost)
            out.append(f"{len(lost)} reconstruction{'s' if len(lost) > 1 else ''} not exported "
                       f"{'are' if len(lost) > 1 else 'is'} lost: {names}")
        return out

    def shutdown(self) -> None:
        """The window closes: cancel the jobs; after this no job is submitted."""
        self.closed = True
        self.cancel()
        self.cancel_estimates()

    # ------------------------------------------------------------------ the lines
    def set_result_line(self, line: Line) -> None:
        """Say ``line`` on the result line."""
        self._said = None
        self.result_line = line
        self.result_changed.emit(line)

    def set_export_line(self, line: Line) -> None:
        """Say ``line`` on the export line."""
        self.export_line = line
        self.export_changed.emit(line)

    def _progressed(self, done: int, total: int) -> None:
        """A job's progress: the bar keeps the total it was given when the job started."""
        self._set_progress(done, self.progress[1])

    def _set_progress(self, done: int, total: int) -> None:
        self.progress = (int(done), int(total))
        self.progress_changed.emit(*self.progress)
