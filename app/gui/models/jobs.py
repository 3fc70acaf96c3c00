"""Reconstruction jobs that can be cancelled between chunks (Qt-free).

A job runs on a worker thread (see :mod:`flexvox_app.gui.widgets.qt_jobs`) and checks a :class:`CancelToken`
after every chunk of camera frames: :func:`run_reconstruction` passes a progress callback to the
one chunked runner, :func:`flexvox_core.methods.run`, that raises :class:`Cancelled` when the
token is set. It asks the runner for the method's extras, so a method that returns the flow and
the per-voxel TR (motion-aware) feeds the Review workspace's overlays.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from flexvox_app.gui.models.device_words import short_where, where_it_ran
from flexvox_core.methods import Method, run

if TYPE_CHECKING:
    from flexvox_core.accuracy import AccuracyEstimate

Progress = Callable[[int, int], None]


class Cancelled(Exception):  # noqa: N818 - a state, not an error
    """The job was cancelled by the user; nothing is wrong."""


class CancelToken:
    """A thread-safe flag the GUI sets and the job polls."""

    def __init__(self):
        self._event = threading.Event()

    def cancel(self) -> None:
        """Ask the job to stop at its next check."""
        self._event.set()

    @property
    def cancelled(self) -> bool:
        """True once :meth:`cancel` was called."""
        return self._event.is_set()

    def check(self) -> None:
        """Raise :class:`Cancelled` when cancelled."""
        if self._event.is_set():
            raise Cancelled("cancelled")


@dataclass
class ReconstructionResult:
    """A finished reconstruction and what the Review workspace shows of it.

    Attributes
    ----------
    video : ndarray (S, H, W) float32 in [0, 1]
    method : Method
    seconds : float
    first_frame : int
        Camera frame the video starts at (0 for a full reconstruction; a preview covers a window).
    flow : ndarray (S, H, W, 2) float32 or None
        Methods that return the flow (motion-aware): the gated flow that drove the tensors.
    tr : ndarray (S, H, W) float32 or None
        Methods that return it (motion-aware): effective temporal resolution per voxel (SR = 1 / TR).
    psnr : float or None
        Mean PSNR against the recording's ground truth, when it has one.
    device : str
        Where it ran: ``cpu`` or ``cuda`` (an NVIDIA GPU: jobs take it when one is usable).
    device_note : str or None
        Why it ran on the CPU although a GPU was there (its method has no GPU path).
    estimate : AccuracyEstimate or None
        Its PSNR estimated from the recording alone (:func:`flexvox_core.accuracy.estimate_recording`), for a
        full reconstruction of a recording without ground truth once the estimate is made.
    no_estimate : str or None
        Why it has no estimate (the method is refused, or the recording cannot be probed), in words.
    """

    video: np.ndarray
    method: Method
    seconds: float
    first_frame: int = 0
    flow: np.ndarray | None = None
    tr: np.ndarray | None = None
    psnr: float | None = None
    extra: dict = field(default_factory=dict)
    device: str = "cpu"
    device_note: str | None = None
    estimate: AccuracyEstimate | None = None
    no_estimate: str | None = None

    @property
    def where(self) -> str:
        """Where it ran, in words: "on the CPU", "on the GPU (its name)", with why not the GPU
        (:func:`~flexvox_app.gui.models.device_words.where_it_ran`)."""
        return where_it_ran(self.device, self.device_note)

    def label(self) -> str:
        """Method, time, where it ran (the CPU or the GPU by name; why not the GPU stays in :attr:`where`) and
        score (the PSNR against the ground truth, else the estimate's short form, :func:`short_estimate`), for
        lists and titles."""
        if self.psnr is not None:
            score = f", {self.psnr:.2f} dB"
        elif self.estimate is not None:
            score = f", {short_estimate(self.estimate)}"
        else:
            score = ""
        return f"{self.method.label()} ({self.seconds:.2f} s {short_where(self.device)}{score})"


def short_estimate(estimate: AccuracyEstimate) -> str:
    """The estimate's line (:meth:`~flexvox_core.accuracy.AccuracyEstimate.line`) up to its half-width:
    ``estimated PSNR NN.NN dB (± W.WW dB)``."""
    line = estimate.line()
    head, sep, _ = line.partition(", ")
    return f"{head})" if sep and "(" in head and ")" not in head else line


def run_reconstruction(frames, code, method: Method, *, cancel: CancelToken | None = None,
                       progress: Progress | None = None, chunk_frames: int = 4, first_frame: int = 0,
                       truth: np.ndarray | None = None, missing=None, device: str = "auto") -> ReconstructionResult:
    """Reconstruct ``frames`` (F, H, W) with ``method``, checking ``cancel`` between chunks.

    Parameters
    ----------
    frames : ndarray (F, H, W), identity-code capture (demultiplexed)
    code : ndarray (m, n, K)
    method : Method
    cancel : CancelToken, optional
    progress : callable(done_frames, total_frames), optional
    chunk_frames : int
        Camera frames per chunk: the cancel granularity (the result does not depend on it).
    first_frame : int
        Where ``frames`` start in the recording (kept in the result).
    truth : ndarray (F·K, H, W), optional
        Ground truth of these frames; the result then carries the mean PSNR.
    missing : ndarray (F,) bool, optional
        Which of these frames the camera dropped: bridged (:mod:`flexvox_core.gaps`); the result's
        ``extra["interpolated"]`` says which sub-frames.
    device : {"auto", "cpu", "cuda"}
        Where it runs (:func:`flexvox_core.methods.runner.device_for`): by default the GPU when one is usable
        and the method has a GPU path; the result says where it ran.

    Raises
    ------
    Cancelled
        When ``cancel`` was set; no partial result is returned.
    """
    cancel = cancel or CancelToken()
    f = np.asarray(frames, dtype=np.float32)
    code = np.asarray(code, dtype=bool)
    if chunk_frames < 1:
        raise ValueError(f"`chunk_frames` must be >= 1; got {chunk_frames}")
    t0 = time.perf_counter()
    cancel.check()

    def checked(done: int, total: int) -> None:
        if progress:
            progress(done, total)
        cancel.check()

    out = run(f, code, method, chunk_frames=chunk_frames, progress=checked, extras=True, missing=missing,
              device=device)
    video, flow, tr = out.video, out.extras.get("flow"), out.extras.get("tr")
    cancel.check()
    seconds = time.perf_counter() - t0
    score = None
    if truth is not None:
        from flexvox_core.metrics import psnr

        score = float(psnr(truth, video))
    result = ReconstructionResult(video, method, seconds, first_frame=first_frame, flow=flow, tr=tr, psnr=score,
                                  device=out.device, device_note=out.device_note)
    if out.interpolated is not None:
        result.extra["interpolated"] = out.interpolated
    return result


def chunk_frames_for(method: Method, n_frames: int, K: int) -> int:
    """Camera frames per chunk for a full reconstruction: small enough to cancel within about a
    tenth of the run, large enough that the overlap each chunk recomputes stays cheap.

    A method without overlap (GAP-TV) runs one frame per chunk; otherwise a chunk is at least
    4 frames and 8/3 of the overlap on each side (motion-aware's 3 frames: chunks of 8), so it
    recomputes at most 75 % more frames than it keeps; a global solve runs in one chunk.

    Parameters
    ----------
    method : Method
    n_frames : int
        Camera frames to reconstruct.
    K : int
        Slots of the code (the overlap depends on it).
    """
    if n_frames < 1:
        raise ValueError(f"`n_frames` must be >= 1; got {n_frames}")
    overlap = method.overlap(K)
    if overlap is None:
        return n_frames
    if overlap == 0:
        return 1
    return max(4, math.ceil(8 * overlap / 3), -(-n_frames // 10))


def preview_window(n_frames: int, centre: int, *, half_width: int = 1, missing=None) -> tuple[int, int]:
    """Camera frames ``[start, stop)`` of a small preview window around frame ``centre``.

    The window holds ``2 * half_width + 1`` frames where the recording has them (fewer at its ends
    is not needed: it slides inwards), so a preview costs the same anywhere in the recording. With
    ``missing`` (the dropped frames), an end that lands in a gap is moved out of it to the captured
    frame beyond, so the preview bridges the gap from both sides as the full reconstruction does.
    """
    if n_frames < 1:
        raise ValueError(f"`n_frames` must be >= 1; got {n_frames}")
    centre = min(max(int(centre), 0), n_frames - 1)
    width = min(n_frames, 2 * half_width + 1)
    start = min(max(0, centre - half_width), n_frames - width)
    stop = start + width
    if missing is not None:
        m = np.asarray(missing, bool)
        while start > 0 and m[start]:
            start -= 1
        while stop < n_frames and m[stop - 1]:
            stop += 1
    return start, stop
