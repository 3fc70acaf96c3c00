"""The Review workspace's model (Qt-free): the recording open, playback, previews, reconstructions and exports.

:class:`ReviewModel` holds what Review knows and decides, and the widget
(:class:`flexvox_app.gui.review.workspace.ReviewWorkspace`) shows it and forwards the operator's actions:

* **opening** a recording (a :class:`~flexvox_app.gui.models.review_session.ReviewSession`, read off the GUI thread);
* **playback**: the current sub-frame, playing or not, the speed (sub-frames per second, or the recording's own
  rate in real time), and how far a tick of the widget's timer advances (:func:`playback_advance`);
* **preview scheduling**: when a preview of the form's settings around the current frame is wanted (a knob
  moved, playback paused, a frame outside the one shown), which preview is current, and whether it shows in
  place of the chosen method's result or beside it;
* **jobs**: full reconstructions with progress and Cancel, and the timing of each method on this machine that
  the expected time comes from;
* **export** of what is shown, over every frame (a preview is reconstructed in full first).

Long work runs as jobs of a runner with ``submit(name, fn, *, on_progress, on_finished, on_failed,
on_cancelled, on_done) -> handle`` (:class:`flexvox_app.gui.widgets.qt_jobs.JobRunner`, whose callbacks run on the GUI
thread); a handle has ``outcome``, ``running``, ``token`` and ``cancel()``. The model says what changed through
:class:`~flexvox_app.capture.events.Signal` s (:attr:`ReviewModel.changed` names the part; see :data:`PARTS`), called
on the thread that drives it. The settings it keeps (playback speed, the preview switch, each method's speed on
this machine, the last folders) go to a settings object with ``get_str``, ``get_int``, ``get_bool``, ``set`` and
``remember_folder`` (:class:`flexvox_app.gui.widgets.settings.AppSettings`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from flexvox_app.capture.events import Signal
from flexvox_app.gui.models.expected_quality import Expectation, expected, format_seconds
from flexvox_app.gui.models.jobs import ReconstructionResult, chunk_frames_for, preview_window, run_reconstruction
from flexvox_app.gui.models.machine_speed import SpeedModel, calibrate, estimate_seconds, is_current, settings_key
from flexvox_app.gui.models.operator_words import in_gui_words
from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.output_files import OutputError, check_output
from flexvox_core.video_io import write_video

_logger = logging.getLogger(__name__)

MAX_DRAWS_HZ = 30
"""Playback draws at most this many pictures a second; faster speeds skip sub-frames between them."""

PARTS = ("path", "session", "frame", "shown", "comparison", "progress", "result", "export", "expected", "jobs",
         "playing", "speed")
"""What :attr:`ReviewModel.changed` names: the path line, a new session, the current sub-frame, the result shown,
the slider's preview beside it, the progress, the result line, the export line, the expected time and quality,
the jobs running (what can be pressed), playing or not, the playback speed."""


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


@dataclass(frozen=True)
class Line:
    """A status line's plain text, and whether it says something failed or was refused."""

    text: str = ""
    error: bool = False


class ReviewModel:
    """What the Review workspace holds and decides, without Qt.

    Parameters
    ----------
    runner
        Runs loading, reconstructions, previews, exports and timings off the GUI thread (see the module
        docstring).
    settings
        Where the playback speed, the preview switch, the speeds on this machine and the last folders are kept.
    quality_table : dict or None
        The shipped bench figures (:func:`flexvox_app.gui.models.expected_quality.load_table`).
    """

    def __init__(self, runner, settings, quality_table: dict | None):
        self.runner = runner
        self.settings = settings
        self.table = quality_table
        self.session: ReviewSession | None = None
        self.results: list[ReconstructionResult] = []
        """The full reconstructions, oldest first."""
        self.shown: ReconstructionResult | None = None
        """What the reconstruction panel shows: a full result or a preview."""
        self.comparison: ReconstructionResult | None = None
        """The slider's preview shown beside :attr:`shown` (the chosen method's full result), or None."""
        self.exported: tuple[Path, ReconstructionResult] | None = None
        """The last export: its path and the full result written."""
        self._written: list[ReconstructionResult] = []
        """Every full result exported (the others are lost when the window closes)."""
        self.truth = None
        """The ground truth of the recording open, when it has one."""
        self.job = None
        """The handle of the full reconstruction (or the export reconstructing one) running or last run."""
        self.preview_job = None
        self._preview_generation = 0
        self._expected_for_job: float | None = None
        self._speed_jobs: dict[str, object] = {}
        self.closed = False
        """The window closes: no preview is wanted and no job is submitted any more."""
        # playback
        self.subframe = 0
        """The current sub-frame index s (camera frame s // K)."""
        self.playing = False
        self.fps = settings.get_int("review/fps", 12)
        """The speed box's playback speed, in sub-frames per second."""
        self.real_time = settings.get_bool("review/real_time", False)
        self.preview_on = settings.get_bool("review/preview", True)
        self.last_tick, self.carried = 0.0, 0.0
        # what the lines say
        self.path_line = Line("no recording open")
        self.result_line = Line()
        self.export_line = Line()
        self.progress = (0, 1)
        """``(done, total)`` of the job the progress bar follows."""
        self.changed = Signal("review changed", contain=False)
        """``(part)``: one of :data:`PARTS` changed."""
        self.preview_wanted = Signal("preview wanted", contain=False)
        """``()``: a preview of the form's settings around the current frame is due (the view waits a moment for
        more changes, then calls :meth:`request_preview`)."""
        self.opened = Signal("opened", contain=False)
        """``(session)``: a recording was opened."""
        self.result_added = Signal("result added", contain=False)
        """``(result)``: a full reconstruction was added to :attr:`results`."""
        self.status = Signal("status", contain=False)
        """``(text)``: one line for the window's status bar."""

    # ------------------------------------------------------------------ opening
    def open(self, path):
        """Open ``path`` off the GUI thread; :attr:`opened` fires when it is ready. Returns the job's handle."""
        path = Path(path)
        self._say("path", Line(f"opening {path} …"))
        return self.runner.submit("open", lambda token, progress: ReviewSession.open(path),
                                  on_finished=self._opened, on_failed=lambda message: self._open_failed(path, message))

    def _open_failed(self, path: Path, message: str) -> None:
        """The path line names what is open still (the frames and the actions shown are its) after the refusal."""
        message = in_gui_words(message)
        if self.session is not None:
            self._say("path", Line(f"{self.session.path} (still open) — cannot open {path.name}: {message}",
                                   error=True))
        else:
            self._say("path", Line(f"cannot open {path.name}: {message}", error=True))
        self.status.emit(f"cannot open {path.name}: {message}")

    def _opened(self, session: ReviewSession) -> None:
        self.set_playing(False)
        self.cancel()
        self.session = session
        self.results = []
        self.shown = None
        self.comparison = None
        self._written = []
        self.truth = session.truth() if session.has_ground_truth else None
        self.subframe = 0
        self.settings.remember_folder(session.path, "review/last_dir")
        self.settings.set("review/last_recording", str(session.path))
        self.path_line = Line(str(session.path))
        self.result_line, self.export_line = Line(), Line()  # they spoke of the recording before
        self._set_progress(0, 1)
        self.changed.emit("result")
        self.changed.emit("export")
        self.changed.emit("session")
        self.opened.emit(session)
        self.status.emit(f"opened {session.path.name}")
        self.want_preview()

    # ------------------------------------------------------------------ playback
    def set_playing(self, playing: bool) -> None:
        """Start or stop playback (stopping asks for a preview where it stopped)."""
        self.playing = bool(playing) and self.session is not None
        if self.playing:
            self.last_tick, self.carried = time.monotonic(), 0.0
        self.changed.emit("playing")
        if not self.playing:
            self.want_preview()

    def step(self) -> int:
        """Sub-frames a tick advances by at least: one under a shown reconstruction, else a whole camera frame."""
        return 1 if self.shown is not None else self.session.K

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
        self.changed.emit("speed")

    def set_real_time(self, on: bool) -> None:
        """Play at the recording's own rate (or at the speed box's)."""
        self.real_time = bool(on)
        self.settings.set("review/real_time", self.real_time)
        self.changed.emit("speed")

    def set_subframe(self, s: int) -> None:
        """Show sub-frame ``s``; once paused, a preview is wanted when what is shown does not cover it."""
        self.subframe = int(s)
        self.changed.emit("frame")
        if not self.playing and (not self.covers(self.shown, s)
                                 or self.comparison is not None and not self.covers(self.comparison, s)):
            self.want_preview()

    def covers(self, r: ReconstructionResult | None, s: int) -> bool:
        """True when ``r`` holds sub-frame ``s`` of the recording."""
        if r is None or self.session is None:
            return False
        i = s - r.first_frame * self.session.K
        return 0 <= i < r.video.shape[0]

    # ------------------------------------------------------------------ preview
    def set_preview_on(self, on: bool) -> None:
        """The live preview switch."""
        self.preview_on = bool(on)
        self.settings.set("review/preview", self.preview_on)
        if self.preview_on:
            self.want_preview()

    def want_preview(self) -> None:
        """Ask for a preview (:attr:`preview_wanted`) when one can be made now."""
        s = self.session
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
        s = self.session
        if s is None or s.frames is None or self.closed:
            return None
        if self.preview_job is not None and self.preview_job.running:
            self.preview_job.cancel()
        self._preview_generation += 1
        gen = self._preview_generation
        full = self.full_result_of(chosen)
        beside = comparing and full is not None
        if not beside:
            self.set_comparison(None)
        if full is not None and (beside or method == full.method):
            if self.shown is not full:  # the result itself, never a preview of it
                self.set_shown(full)
            if not beside:
                return None
        a, b = preview_window(s.n_frames, self.subframe // s.K, half_width=1, missing=s.missing)
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
            on_failed=lambda msg: self._say("result", Line(f"preview failed: {in_gui_words(msg)}")))
        return self.preview_job

    def _preview_done(self, result: ReconstructionResult, generation: int, beside: bool) -> None:
        if generation != self._preview_generation:
            return  # a newer request superseded it
        if beside:
            self.set_comparison(result)
        else:
            self.set_shown(result)

    def set_comparison(self, result: ReconstructionResult | None) -> None:
        """Show the slider's preview beside the chosen method's result (None: hide it)."""
        self.comparison = result
        self.changed.emit("comparison")

    def set_shown(self, result: ReconstructionResult | None) -> None:
        """Show ``result`` in the reconstruction panel."""
        self.shown = result
        self.changed.emit("shown")

    def flow_result(self) -> ReconstructionResult | None:
        """The result whose flow and TR map the Motion tab shows: the shown one when it has a flow, else the
        newest full result with one (a preview of another method never hides a full motion-aware result)."""
        if self.shown is not None and self.shown.flow is not None:
            return self.shown
        return next((r for r in reversed(self.results) if r.flow is not None), None)

    # ------------------------------------------------------------------ full reconstruction
    def reconstruct(self, method):
        """Reconstruct every frame with ``method`` (off-thread, cancellable); the job's handle, or None when it
        cannot start now."""
        s = self.session
        if s is None or s.frames is None or self.busy:
            return None
        chunk = chunk_frames_for(method, s.n_frames, s.K)
        (frames, code), truth, missing = s.input(method), self.truth, s.missing

        def work(token, progress):
            return run_reconstruction(frames, code, method, cancel=token, progress=progress, chunk_frames=chunk,
                                      truth=truth, missing=missing)

        self._set_progress(0, s.n_frames)
        self._expected_for_job = self.expected_seconds(method)
        self._say("result", Line(f"reconstructing with {method.label()} …"))
        self.job = self.runner.submit(
            "reconstruct", work, on_progress=self._progressed,
            on_finished=lambda result: s is self.session and self._reconstructed(result),
            on_cancelled=lambda: self._reconstruction_cancelled(s),
            on_failed=lambda msg: s is self.session and self._say(
                "result", Line(f"reconstruction failed: {in_gui_words(msg)}", error=True)),
            on_done=lambda: self.changed.emit("jobs"))
        self.changed.emit("jobs")
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
        """Cancel a running reconstruction (the preview is cancelled too); it stops after its current chunk."""
        if self.cancellable:
            self.job.token.cancel()
            self._say("result", Line("cancelling … (the current chunk of frames finishes first)"))
            self.changed.emit("jobs")
        for h in (self.job, self.preview_job):
            if h is not None and h.running:
                h.cancel()

    def _reconstruction_cancelled(self, session) -> None:
        if session is not self.session:  # cancelled because another recording opened: nothing to say of it
            return
        self._set_progress(0, self.progress[1])
        self._say("result", Line("cancelled; nothing was kept"))
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
        self._say("result", Line(text))
        self.set_shown(result)
        self.result_added.emit(result)
        self.status.emit(text)

    # ------------------------------------------------------------------ export
    def export_candidate(self) -> ReconstructionResult | None:
        """What the reconstruction panel shows (a full result or a preview), else the newest full result."""
        if self.shown is not None:
            return self.shown
        return self.results[-1] if self.results else None

    def full_result_of(self, method) -> ReconstructionResult | None:
        """The newest full reconstruction made with exactly ``method`` (None: none yet)."""
        return next((r for r in reversed(self.results) if r.method == method), None)

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
            self._say("export", Line("nothing to export: reconstruct, or preview, first"))
            return None
        if r.extra.get("preview") and (s.frames is None or self.busy):
            self._say("export", Line("not exported: wait for the running reconstruction to end", error=True)
                      if s.frames is not None else Line("not exported: this recording cannot be reconstructed"))
            return None
        path = Path(path)
        self.settings.remember_folder(path, "review/export_dir")
        if overwrite is None and path.exists() and path.resolve() != s.path.resolve():  # the recording: refused
            if not ask(path):
                self._say("export", Line(f"not exported: {path} is kept (choose another path)"))
                return None
            overwrite = True
        overwrite = bool(overwrite)
        try:  # never onto the recording under review; the folder must take the file
            check_output(path, overwrite=overwrite, inputs=[s.path])
        except OutputError as exc:
            self._say("export", Line(f"not exported: {in_gui_words(str(exc))}", error=True))
            return None
        method = r.method
        full = r if not r.extra.get("preview") else self.full_result_of(method)
        fps = float(self.fps)
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
            self._say("export", Line(f"reconstructing all frames with {what} to export what is shown …"))
            self._set_progress(0, s.n_frames)
        else:
            self._say("export", Line(f"writing {path.name}: {what} …"))
        handle = self.runner.submit(
            "export", work, on_progress=self._progressed,
            on_finished=lambda out: self._exported(out, full is None, what),
            on_cancelled=lambda: self._say("export", Line("export cancelled; nothing was written")),
            on_failed=lambda msg: self._say("export", Line(f"export failed: {in_gui_words(msg)}", error=True)),
            on_done=lambda: self.changed.emit("jobs"))
        if full is None:
            self.job = handle  # Cancel stops it; Reconstruct waits for it
            self.changed.emit("jobs")
        return handle

    def _exported(self, out, reconstructed: bool, what: str) -> None:
        result, path = out
        if reconstructed:
            self._reconstructed(result)
        self.exported = (path, result)
        self._written.append(result)
        self._say("export", Line(f"wrote {path}: {what}"))
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
        method was not timed on this machine yet, a timing starts (:attr:`changed` says ``expected`` when done)."""
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
            self.changed.emit("expected")

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
        """The window closes: stop playback and cancel the jobs; after this no preview is wanted and no job is
        submitted."""
        self.closed = True
        self.set_playing(False)
        self.cancel()

    # ------------------------------------------------------------------ helpers
    def _say(self, part: str, line: Line) -> None:
        """Put ``line`` in :attr:`path_line`, :attr:`result_line` or :attr:`export_line` (``part``) and say so."""
        setattr(self, f"{part}_line", line)
        self.changed.emit(part)

    def _progressed(self, done: int, total: int) -> None:
        """A job's progress: the bar keeps the total it was given when the job started."""
        self._set_progress(done, self.progress[1])

    def _set_progress(self, done: int, total: int) -> None:
        self.progress = (int(done), int(total))
        self.changed.emit("progress")
