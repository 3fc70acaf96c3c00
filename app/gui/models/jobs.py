"""Reconstruction jobs that can be cancelled between chunks (Qt-free).

A job runs on a worker thread (see :mod:`app.gui.widgets.qt_jobs`) and checks a :class:`CancelToken`
after every chunk of camera frames: :func:`run_reconstruction` passes a progress callback to
:func:`flexvox_core.reconstruct.run.reconstruct` that raises :class:`Cancelled` when the token
is set. Motion-aware runs its own chunk loop (same overlap as ``reconstruct``) so that it also
returns the flow and the per-voxel [TR, SR] map for the Review workspace's overlays.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from flexvox_core.reconstruct.run import Method, overlap_frames, reconstruct

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
        Motion-aware only: the gated flow that drove the tensors.
    tr : ndarray (S, H, W) float32 or None
        Motion-aware only: effective temporal resolution per voxel (SR = 1 / TR).
    psnr : float or None
        Mean PSNR against the recording's ground truth, when it has one.
    """

    video: np.ndarray
    method: Method
    seconds: float
    first_frame: int = 0
    flow: np.ndarray | None = None
    tr: np.ndarray | None = None
    psnr: float | None = None
    extra: dict = field(default_factory=dict)

    def label(self) -> str:
        """Method and score, for lists and titles."""
        score = f", {self.psnr:.2f} dB" if self.psnr is not None else ""
        return f"{self.method.label()} ({self.seconds:.2f} s{score})"


def _chunks(F: int, chunk: int, overlap: int):
    for start in range(0, F, chunk):
        stop = min(F, start + chunk)
        yield start, stop, max(0, start - overlap), min(F, stop + overlap)


def _motion_aware(frames: np.ndarray, code: np.ndarray, method: Method, *, chunk_frames: int,
                  cancel: CancelToken, progress: Progress | None):
    from flexvox_core.motion import motion_aware

    F, H, W = frames.shape
    K = code.shape[2]
    video = np.empty((F * K, H, W), np.float32)
    flow = np.empty((F * K, H, W, 2), np.float32)
    tr = np.empty((F * K, H, W), np.float32)
    value_range = (float(np.min(frames)), float(np.max(frames)))  # the same in every chunk
    for start, stop, lo, hi in _chunks(F, chunk_frames, overlap_frames(method, K)):
        cancel.check()
        r = motion_aware(frames[lo:hi], code, **method.motion_kwargs(), value_range=value_range)
        a, b = (start - lo) * K, (stop - lo) * K
        video[start * K: stop * K] = r.video[a:b]
        flow[start * K: stop * K] = r.flow.flow[a:b]
        tr[start * K: stop * K] = r.tr[a:b]
        if progress:
            progress(stop, F)
    return np.clip(video, 0, 1), flow, tr


def run_reconstruction(frames, code, method: Method, *, cancel: CancelToken | None = None,
                       progress: Progress | None = None, chunk_frames: int = 4, first_frame: int = 0,
                       truth: np.ndarray | None = None) -> ReconstructionResult:
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
    flow = tr = None
    cancel.check()
    if method.name == "motion-aware":
        video, flow, tr = _motion_aware(f, code, method, chunk_frames=chunk_frames, cancel=cancel,
                                        progress=progress)
    else:
        def checked(done: int, total: int) -> None:
            if progress:
                progress(done, total)
            cancel.check()

        video = reconstruct(f, code, method, chunk_frames=chunk_frames, progress=checked)
    cancel.check()
    seconds = time.perf_counter() - t0
    score = None
    if truth is not None:
        from flexvox_core.metrics import psnr

        score = float(psnr(truth, video).mean)
    return ReconstructionResult(video, method, seconds, first_frame=first_frame, flow=flow, tr=tr, psnr=score)


def chunk_frames_for(method: Method, n_frames: int) -> int:
    """Camera frames per chunk for a full reconstruction: small enough to cancel within about a
    tenth of the run, large enough that the overlap each chunk recomputes stays cheap.

    GAP-TV needs no overlap (one chunk per frame); motion-aware recomputes 3 frames on each side,
    so its chunks are at least 8 frames.
    """
    if n_frames < 1:
        raise ValueError(f"`n_frames` must be >= 1; got {n_frames}")
    if method.name == "gap-tv":
        return 1
    if method.name == "motion-aware":
        return max(8, -(-n_frames // 8))
    return max(4, -(-n_frames // 10))


def preview_window(n_frames: int, centre: int, *, half_width: int = 1) -> tuple[int, int]:
    """Camera frames ``[start, stop)`` of a small preview window around frame ``centre``.

    The window holds ``2 * half_width + 1`` frames where the recording has them (fewer at its ends
    is not needed: it slides inwards), so a preview costs the same anywhere in the recording.
    """
    if n_frames < 1:
        raise ValueError(f"`n_frames` must be >= 1; got {n_frames}")
    centre = min(max(int(centre), 0), n_frames - 1)
    width = min(n_frames, 2 * half_width + 1)
    start = min(max(0, centre - half_width), n_frames - width)
    return start, start + width
