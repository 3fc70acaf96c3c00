"""A live preview of the motion-aware reconstruction of the newest camera frames, never slowing capture.

Beside the raw live view (and during a recording) the Capture workspace shows the newest
camera frame reconstructed by :func:`flexvox_core.motion.motion_aware`, its K sub-frames cycling.
How it stays out of capture's way:

* **Its own worker.** Reconstructions run on a private ``QThreadPool`` of one thread (not the
  workspace's job runner, which starts and stops recordings), so at most one preview runs.
* **Newest wins.** Frames are only *offered* (:meth:`LivePreview.feed`, a list append on the
  GUI thread); while a reconstruction runs, newer frames replace older ones in a small buffer
  and the next run takes the newest. Nothing queues up; frames that were never previewed are
  counted (``offered`` against ``runs``), not waited for.
* **Duty cycle.** After a run of ``t`` seconds the next starts no sooner than
  ``rest_fraction · t`` later, so the preview uses at most ``1 / (1 + rest_fraction)`` of one core.
* **Resolution.** Frames are subsampled with a stride ``s ≡ 1 (mod lcm(m, n))`` (:func:`preview_stride`),
  which keeps the code's layout: pixel ``(y·s, x·s)`` opens in the slots of ``code[y mod m, x mod n]``,
  so the subsampled frames are a capture of the *same* code, over the whole field of view
  (aliased, for a preview). The stride starts where the frame has at most ``max_pixels``, grows
  when a run takes longer than ``budget_s``, and shrinks again only when the finer run (time ∝
  pixels) is predicted to take under half the budget.

What is on screen says the resolution and rate it achieves ("preview: 160×120 (every pixel),
3 frames, 2.4 Hz"). Multiplexed captures are demultiplexed first (:func:`flexvox_core.reconstruct.prepare`).
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
from PySide6.QtCore import QObject, QThreadPool, QTimer, Signal

from app.gui.widgets.qt_jobs import JobRunner

_logger = logging.getLogger(__name__)

PREVIEW_FRAMES = 3
"""Camera frames reconstructed together (the newest one is shown)."""
MAX_PIXELS = 160 * 120
"""Pixels of a preview frame to start with."""
BUDGET_S = 0.6
"""A run longer than this makes the next one coarser."""
REST_FRACTION = 1.0
"""Idle time after a run, as a fraction of its duration (1: at most half a core)."""


def preview_stride(shape: tuple[int, int], tile: tuple[int, int], max_pixels: int = MAX_PIXELS) -> int:
    """The smallest stride ``s ≡ 1 (mod lcm(m, n))`` with at most ``max_pixels`` subsampled pixels.

    Examples
    --------
    >>> preview_stride((120, 160), (4, 4))
    1
    >>> preview_stride((1200, 1920), (4, 4))
    13
    """
    H, W = (int(v) for v in shape)
    if max_pixels < 1:
        raise ValueError(f"`max_pixels` must be >= 1; got {max_pixels}")
    step = math.lcm(int(tile[0]), int(tile[1]))
    s = 1
    while -(-H // s) * -(-W // s) > max_pixels and s < max(H, W):
        s += step
    return s


def normalise(image: np.ndarray) -> np.ndarray:
    """A camera image in relative units (float32): float frames as they are, counts over the type's range."""
    img = np.asarray(image)
    if np.issubdtype(img.dtype, np.integer):
        return img.astype(np.float32) / float(np.iinfo(img.dtype).max)
    return img.astype(np.float32, copy=False)


class FrameBuffer:
    """The newest run of consecutive camera frames, at most ``size`` of them (a gap starts a new run)."""

    def __init__(self, size: int = PREVIEW_FRAMES):
        if size < 1:
            raise ValueError(f"`size` must be >= 1; got {size}")
        self._frames: deque = deque(maxlen=size)
        self.version = 0
        """Increases with every frame pushed."""

    def push(self, frame) -> None:
        """Add ``frame`` (a :class:`rig_drivers.interfaces.Frame`); older or repeated ids are ignored."""
        last = self._frames[-1].frame_id if self._frames else None
        if last is not None and frame.frame_id <= last:
            return
        if last is not None and frame.frame_id != last + 1:
            self._frames.clear()
        self._frames.append(frame)
        self.version += 1

    def clear(self) -> None:
        """Forget every frame."""
        self._frames.clear()

    def snapshot(self) -> list:
        """The frames, oldest first (a copy of the list; the frames themselves are shared, read-only)."""
        return list(self._frames)

    def __len__(self) -> int:
        return len(self._frames)


@dataclass(frozen=True)
class PreviewResult:
    """One preview: the newest frame's sub-frames.

    Attributes
    ----------
    video : ndarray (K, h, w) float32
    frame_id : int
        Camera frame shown.
    n_frames : int
        Camera frames reconstructed together.
    stride : int
    seconds : float
        Time of the reconstruction.
    levels : (low, high)
    """

    video: np.ndarray
    frame_id: int
    n_frames: int
    stride: int
    seconds: float
    levels: tuple[float, float]

    @property
    def size(self) -> tuple[int, int]:
        """(w, h) of the preview."""
        return int(self.video.shape[2]), int(self.video.shape[1])


def reconstruct_preview(frames: list, code, *, stride: int = 1) -> PreviewResult:
    """Motion-aware reconstruction of ``frames`` (consecutive Frames), the newest frame's K sub-frames.

    ``code`` is the capture's identity code (m, n, K) or its :class:`~flexvox_core.multiplex.MultiplexedCode`.
    """
    from flexvox_core.motion import motion_aware
    from flexvox_core.reconstruct import prepare

    if not frames:
        raise ValueError("`frames` must hold at least one frame")
    t0 = time.perf_counter()
    stack = np.stack([normalise(f.image) for f in frames])
    if not isinstance(code, np.ndarray) and stride > 1:
        stack, identity = prepare(stack, code)  # demultiplex at full resolution, then subsample
        stack = stack[:, ::stride, ::stride]
    else:
        stack, identity = prepare(stack[:, ::stride, ::stride] if stride > 1 else stack, code)
    K = identity.shape[2]
    result = motion_aware(np.ascontiguousarray(stack, np.float32), identity)
    video = np.clip(result.video[-K:], 0.0, 1.0).astype(np.float32, copy=False)
    hi = float(np.percentile(video, 99.5)) if video.size else 1.0
    return PreviewResult(video, int(frames[-1].frame_id), len(frames), int(stride), time.perf_counter() - t0,
                         (0.0, hi if hi > 0 else 1.0))


class LivePreview(QObject):
    """Runs :func:`reconstruct_preview` on the newest frames, newest-wins, on a worker of its own.

    Parameters
    ----------
    n_frames : int
        Camera frames per reconstruction (the newest consecutive ones available, at least 1).
    max_pixels : int
        Starting resolution (see :func:`preview_stride`).
    budget_s : float
        Runs longer than this make the next coarser; much shorter ones make it finer.
    rest_fraction : float
        Idle time after each run, relative to its duration.
    """

    updated = Signal(object)
    """A new :class:`PreviewResult` (on the GUI thread)."""
    failed = Signal(str)
    """The preview stopped on an error (in words)."""

    def __init__(self, parent: QObject | None = None, *, n_frames: int = PREVIEW_FRAMES, max_pixels: int = MAX_PIXELS,
                 budget_s: float = BUDGET_S, rest_fraction: float = REST_FRACTION):
        super().__init__(parent)
        if rest_fraction < 0:
            raise ValueError(f"`rest_fraction` must be >= 0; got {rest_fraction}")
        pool = QThreadPool(self)
        pool.setMaxThreadCount(1)
        self.runner = JobRunner(pool, parent=self)
        self.buffer = FrameBuffer(n_frames)
        self.max_pixels = int(max_pixels)
        self.budget_s = float(budget_s)
        self.rest_fraction = float(rest_fraction)
        self.code = None
        self.tile = (1, 1)
        self.stride: int | None = None
        self.enabled = False
        self.result: PreviewResult | None = None
        self.runs = 0
        self.offered = 0
        """Frames fed; only the newest at each free moment is previewed (``runs`` of them)."""
        self.error = ""
        self._job = None
        self._done_version = 0
        self._finish_times: deque[float] = deque(maxlen=6)
        self._rest = QTimer(self)
        self._rest.setSingleShot(True)
        self._rest.timeout.connect(self._maybe_start)

    # ------------------------------------------------------------------ control
    def set_code(self, code, tile) -> None:
        """The capture's code (identity array or MultiplexedCode) and tile; resets the buffer and stride."""
        self.code = code
        self.tile = tuple(int(v) for v in tile)
        self.stride = None
        self.buffer.clear()

    def start(self) -> None:
        """Accept frames and preview them."""
        self.enabled = True
        self.error = ""
        self.result = None
        self.runs = self.offered = 0
        self._finish_times.clear()
        self.buffer.clear()
        self._done_version = self.buffer.version

    def stop(self) -> None:
        """Stop previewing (a run in progress finishes and is ignored)."""
        self.enabled = False
        self._rest.stop()
        self.buffer.clear()

    @property
    def busy(self) -> bool:
        """True while a reconstruction runs."""
        return self._job is not None and self._job.running

    def feed(self, frame) -> None:
        """Offer a camera frame (GUI thread, cheap): it replaces older ones waiting; a run starts when free."""
        if not self.enabled or self.code is None:
            return
        self.offered += 1
        self.buffer.push(frame)
        self._maybe_start()

    def _maybe_start(self) -> None:
        if not self.enabled or self.busy or self._rest.isActive() or not len(self.buffer):
            return
        if self.buffer.version == self._done_version:
            return  # nothing new since the last run
        frames = self.buffer.snapshot()
        if self.stride is None:  # first run: from the frame size
            self.stride = preview_stride(frames[-1].image.shape, self.tile, self.max_pixels)
        code, stride, version = self.code, self.stride, self.buffer.version
        self._done_version = version
        self._job = self.runner.submit("live preview", lambda token, progress: reconstruct_preview(
            frames, code, stride=stride), on_finished=self._on_result, on_failed=self._on_failed)

    def _on_result(self, result: PreviewResult) -> None:
        self.runs += 1
        self._finish_times.append(time.monotonic())
        self._adapt(result)
        if not self.enabled:
            return
        self.result = result
        self.updated.emit(result)
        self._rest.start(max(1, int(1000 * self.rest_fraction * result.seconds)))

    def _adapt(self, result: PreviewResult) -> None:
        step = math.lcm(*self.tile)
        if result.seconds > self.budget_s:
            self.stride = result.stride + step
        elif result.stride > 1:  # finer only when the finer run is predicted to stay well inside the budget
            finer = max(1, result.stride - step)
            if result.seconds * (result.stride / finer) ** 2 < self.budget_s / 2:
                self.stride = finer

    def _on_failed(self, message: str) -> None:
        _logger.warning("live preview stopped: %s", message)
        self.error = message
        self.enabled = False
        self.failed.emit(message)

    # ------------------------------------------------------------------ words
    @property
    def rate_hz(self) -> float:
        """Previews per second over the last few runs (0 until two)."""
        t = self._finish_times
        if len(t) < 2 or t[-1] <= t[0]:
            return 0.0
        return (len(t) - 1) / (t[-1] - t[0])

    def text(self) -> str:
        """What the preview achieves: "preview: 160×120 (every pixel), 3 frames, 2.4 Hz, …"."""
        if self.error:
            return f"preview stopped: {self.error}"
        r = self.result
        if r is None:
            return "preview: waiting for frames …" if self.enabled else "preview: off"
        w, h = r.size
        every = "every pixel" if r.stride == 1 else f"every {r.stride}th pixel"
        frames = f"{r.n_frames} frame{'s' if r.n_frames != 1 else ''}"
        rate = f"{self.rate_hz:.1f} Hz" if self.runs > 1 else "rate after the next run"  # one run has no rate
        return (f"preview: {w}×{h} ({every}), {frames}, {rate}, {r.seconds:.2f} s per run · "
                f"{self.runs} of {self.offered} camera frames previewed (newest wins)")

    def shutdown(self, timeout_ms: int = 5000) -> bool:
        """Stop and wait for a running reconstruction."""
        self.stop()
        return self.runner.shutdown(timeout_ms)
