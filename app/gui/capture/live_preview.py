"""A live preview of the motion-aware reconstruction of the newest camera frames, never slowing capture.

Beside the raw live view (and during a recording) the Capture workspace shows a recent camera frame
reconstructed by the streaming motion-aware (:mod:`flexvox_core.motion.streaming`: the frame before
the newest, so that its trajectories reach both ways), its K sub-frames cycling.
How it stays out of capture's way:

* **Its own worker.** Reconstructions run on a private ``QThreadPool`` of one thread (not the
  workspace's job runner, which starts and stops recordings), so at most one preview runs.
* **Newest wins.** Frames are only *offered* (:meth:`LivePreview.feed`, a list append on the
  GUI thread); while a reconstruction runs, newer frames replace older ones in a small buffer
  and the next run takes the newest. Nothing queues up; frames that were never previewed are
  counted (``offered`` against ``runs``), not waited for.
* **Duty cycle.** After a run of ``t`` seconds the next starts no sooner than
  ``rest_fraction · t`` later, so the preview uses at most ``1 / (1 + rest_fraction)`` of one core.
* **Full resolution, a region when it must.** A run takes on the whole frame when the measured
  cost of a pixel says it fits in ``budget_s``; otherwise a region of the frame at full resolution
  (:func:`flexvox_app.capture.live_preview.preview_region`), which the operator drags on the live view
  (:meth:`LivePreview.set_centre`). Never a subsampled, aliased frame. The region follows the
  measured cost, so it grows back as soon as the machine is less busy.

What is on screen says the resolution, rate and latency it achieves ("preview: 640×480 (the whole
frame), 3 frames, 1.4 Hz, 0.35 s per run, 0.5 s behind the camera"). Multiplexed captures are
demultiplexed first (:func:`flexvox_core.reconstruct.as_identity_capture`).
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict, deque

from PySide6.QtCore import QObject, QThreadPool, QTimer, Signal

from flexvox_app.capture.live_preview import (
    PREVIEW_FRAMES,
    PREVIEW_METHODS,
    START_PIXELS,
    FrameBuffer,
    PixelCost,
    PreviewReconstructor,
    PreviewResult,
    Region,
    preview_region,
)
from flexvox_app.gui.models.device_words import where_it_ran
from flexvox_app.gui.widgets.qt_jobs import JobRunner
from flexvox_core.numbers import positive_number

_logger = logging.getLogger(__name__)

BUDGET_S = 0.6
"""A run should last about this long: it sizes the region (the whole frame when it fits)."""
REST_FRACTION = 1.0
"""Idle time after a run, as a fraction of its duration (1: at most half a core)."""
HYSTERESIS = 0.25
"""The region changes size only when the budget asks for 25 % more or fewer pixels (no jitter)."""

__all__ = ["BUDGET_S", "LivePreview", "PreviewResult", "REST_FRACTION"]


class LivePreview(QObject):
    """Runs a :class:`~flexvox_app.capture.live_preview.PreviewReconstructor` on the newest frames, newest-wins, on a
    worker of its own (motion-aware streams: the frame before the newest, state kept between runs).

    Parameters
    ----------
    n_frames : int
        Camera frames per reconstruction (the newest consecutive ones available, at least 1).
    max_pixels : int
        Pixels of the first run's region, before any run has been timed.
    budget_s : float
        How long a run should last; with the measured cost of a pixel it sizes the region.
    rest_fraction : float
        Idle time after each run, relative to its duration.
    device : {"auto", "cpu", "cuda"}
        Where motion-aware runs (:func:`flexvox_core.gpu.resolve_device`; ``auto``: the GPU when one is usable).
        On the GPU every run takes on the whole frame with all of motion-aware's stages and no rest between runs,
        so that every camera frame can be previewed; on the CPU the region and rest above apply. :attr:`device`
        says which, and :meth:`text` says so.
    """

    updated = Signal(object)
    """A new :class:`PreviewResult` (on the GUI thread)."""
    failed = Signal(str)
    """The preview stopped on an error (in words)."""

    def __init__(self, parent: QObject | None = None, *, n_frames: int = PREVIEW_FRAMES, max_pixels: int = START_PIXELS,
                 budget_s: float = BUDGET_S, rest_fraction: float = REST_FRACTION, device: str = "auto"):
        super().__init__(parent)
        from flexvox_core.gpu.device import DeviceUnavailable, resolve_device

        self.device_note: str | None = None
        """Why the preview runs on the CPU although the GPU was asked for (None: it was not, or it runs there)."""
        try:
            self.device = resolve_device(device)
        except DeviceUnavailable as exc:
            _logger.warning("live preview on the CPU: %s", exc)
            self.device, self.device_note = "cpu", str(exc)
        if self.device == "cuda":  # the whole frame from the first run on, no rest
            max_pixels, rest_fraction = 2**31 - 1, 0.0
        if not (isinstance(rest_fraction, int | float) and math.isfinite(rest_fraction) and rest_fraction >= 0):
            raise ValueError(f"`rest_fraction` must be a finite number >= 0; got {rest_fraction!r}")
        budget_s = positive_number("`budget_s`", budget_s, unit="seconds")
        if not positive_number("`max_pixels`", max_pixels) >= 1:
            raise ValueError(f"`max_pixels` must be at least 1; got {max_pixels!r}")
        pool = QThreadPool(self)
        pool.setMaxThreadCount(1)
        self.runner = JobRunner(pool, parent=self)
        self.buffer = FrameBuffer(n_frames)
        self.max_pixels = int(max_pixels)
        self.budget_s = float(budget_s)
        self.rest_fraction = float(rest_fraction)
        self.code = None
        self.tile = (1, 1)
        self.reconstructor = PreviewReconstructor(self.device)
        self.cost = PixelCost()
        self.region: Region | None = None
        """The region of the last run started."""
        self.centre: tuple[float, float] | None = None
        """Where the operator put the region (y, x); None: the frame's centre."""
        self.method = PREVIEW_METHODS[0]
        """What runs reconstruct with (:data:`flexvox_app.capture.live_preview.PREVIEW_METHODS`)."""
        self.latency_s: float | None = None
        """Seconds from the shown frame's arrival to its preview on screen, for the last preview (motion-aware
        shows the frame before the newest, so this includes the wait for the next frame)."""
        self._fed_at: OrderedDict[int, float] = OrderedDict()
        self.enabled = False
        self.result: PreviewResult | None = None
        self.runs = 0
        self.offered = 0
        """Frames fed; only the newest at each free moment is previewed (``runs`` of them)."""
        self.error = ""
        self._job = None
        self._done_version = 0
        self._generation = 0
        """Bumped by every change of code, method or start: a run started before says nothing of now."""
        self._finish_times: deque[float] = deque(maxlen=6)
        self._rest = QTimer(self)
        self._rest.setSingleShot(True)
        self._rest.timeout.connect(self._maybe_start)

    # ------------------------------------------------------------------ control
    def set_code(self, code, tile) -> None:
        """The capture's code (identity array or MultiplexedCode) and tile; resets the buffer and region."""
        self.code = code
        self.tile = tuple(int(v) for v in tile)
        self.reconstructor = PreviewReconstructor(self.device)  # a run still going keeps the old one
        self.region = None
        self.cost.clear()
        self.buffer.clear()
        self._generation += 1

    def set_method(self, method: str) -> None:
        """Reconstruct with ``method`` from the next run on (its own cost per pixel sizes the region)."""
        if method not in PREVIEW_METHODS:
            raise ValueError(f"`method` must be one of {', '.join(PREVIEW_METHODS)}; got {method!r}")
        if method != self.method:
            self.method = method
            self.cost.clear()
            self.region = None
            self._generation += 1

    def set_centre(self, y: float, x: float) -> None:
        """Put the region's centre at (y, x) of the frame (the next run takes it on)."""
        self.centre = (float(y), float(x))
        self.region = None  # placed afresh at the next run

    def start(self) -> None:
        """Accept frames and preview them."""
        self.enabled = True
        self.error = ""
        self.result = None
        self.runs = self.offered = 0
        self.latency_s = None
        self.reconstructor = PreviewReconstructor(self.device)  # a new session starts a new stream
        self._fed_at.clear()
        self._finish_times.clear()
        self.buffer.clear()
        self._done_version = self.buffer.version
        self._generation += 1

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
        self._fed_at[int(frame.frame_id)] = time.monotonic()
        while len(self._fed_at) > 64:
            self._fed_at.popitem(last=False)
        self.buffer.push(frame)
        self._maybe_start()

    def _maybe_start(self) -> None:
        if not self.enabled or self.busy or self._rest.isActive() or not len(self.buffer):
            return
        if self.buffer.version == self._done_version:
            return  # nothing new since the last run
        frames = self.buffer.snapshot()
        self.region = self._next_region(frames[-1].image.shape)
        code, region, version, method = self.code, self.region, self.buffer.version, self.method
        self._done_version = version
        generation, reconstructor = self._generation, self.reconstructor
        self._job = self.runner.submit("live preview", lambda token, progress: reconstructor.run(
            frames, code, region, method), on_finished=lambda r: self._on_result(r, generation),
            on_failed=self._on_failed)

    def _next_region(self, shape) -> Region:
        """The whole frame when the measured cost of a pixel says it fits in the budget, else a region."""
        pixels = self.max_pixels if self.device == "cuda" else self.cost.pixels_for(self.budget_s,
                                                                                     default=self.max_pixels)
        new = preview_region(shape, self.tile, pixels, self.centre)
        old = self.region
        if old is not None and not new.covers(shape) and abs(new.pixels / old.pixels - 1) < HYSTERESIS:
            return old  # a region of about the same size: keep it still (the whole frame is always taken)
        if old is not None:
            _logger.info("live preview: region %dx%d -> %dx%d (%.0f pixels fit in %.2f s)",
                         old.shape[1], old.shape[0], new.shape[1], new.shape[0], pixels, self.budget_s)
        return new

    def _on_result(self, result: PreviewResult, generation: int | None = None) -> None:
        if generation is not None and generation != self._generation:
            return  # started before the code, the method or the session changed: neither its cost nor its picture
        self.runs += 1
        now = time.monotonic()
        self._finish_times.append(now)
        self.cost.add(result.seconds, result.region.pixels)
        if not self.enabled:
            return
        fed = self._fed_at.get(result.frame_id)
        self.latency_s = None if fed is None else now - fed
        self.result = result
        self.updated.emit(result)
        self._rest.start(max(1, int(1000 * self.rest_fraction * result.seconds)))

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
        """What the preview achieves: "preview: 640×480 (the whole frame), 3 frames, 1.4 Hz, …"."""
        if self.error:
            return f"preview stopped: {self.error}"
        r = self.result
        if r is None:
            return "preview: waiting for frames …" if self.enabled else "preview: off"
        w, h = r.size
        H, W = r.frame_shape
        if r.whole_frame:
            where = "the whole frame"
        else:
            whole = self.cost.seconds_for(H * W)
            why = (f"the whole frame would take about {whole:.1f} s a run, over the {self.budget_s:g} s budget"
                   if whole is not None else "the whole frame is not timed yet")
            where = (f"a region of the {W}×{H} frame at full resolution, as {why}; it grows when runs get faster: "
                     "drag it on the live view")
        frames = f"{r.n_frames} frame{'s' if r.n_frames != 1 else ''}"
        rate = f"{self.rate_hz:.1f} Hz" if self.runs > 1 else "rate after the next run"  # one run has no rate
        behind = f", {self.latency_s:.2f} s behind the camera" if self.latency_s is not None else ""
        note = self.device_note
        if r.device == "cpu" and r.method != "motion-aware" and self.device == "cuda":
            note = f"the {r.method} preview runs on the CPU"
        on = " " + where_it_ran(r.device, note)
        return (f"{r.method} preview{on}: {w}×{h} ({where}), {frames}, {rate}, {r.seconds:.2f} s per run{behind} · "
                f"{self.runs} of {self.offered} camera frames previewed (newest wins)")

    def shutdown(self, timeout_ms: int = 5000) -> bool:
        """Stop and wait for a running reconstruction."""
        self.stop()
        return self.runner.shutdown(timeout_ms)
