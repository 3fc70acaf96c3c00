"""Motion-aware reconstruction of camera frames as they arrive, one frame behind.

:class:`StreamingMotionAware` takes camera frames one at a time and gives back each frame's K
sub-frames as soon as the frame after it has arrived (one frame of latency: a trajectory reaches
about one sampling period, K sub-frames, each way). Each frame is reconstructed by the offline
pipeline (:func:`~flexvox_core.motion.pipeline.run_window`) over a short window of frames around
it — ``back`` frames before it, ``ahead`` after — with two things kept between frames:

* the **flow of every pair of sub-frames already measured** (:class:`~flexvox_core.flow.memo.FlowMemo`):
  the successive-sub-frame flow, the K-average's long-baseline flow and the motion detector's,
  found again by the images' content. Sub-frames near a window's ends differ from the next window's
  (the K-average and the high-TR blur see the window's end), so their pairs are computed again:
  about 1.5× the pairs of the offline run in all;
* the **frames the next windows need** (``back + ahead + 1`` of them, more across dropped ones).

Only the frame's own sub-frames (and the refinement's reach around them: 2 sub-frames at K = 16) are gathered along the
trajectories, the costly step; the high-TR and fixed-tensor guides are recomputed over the window.

How close it comes to the offline run over the whole clip: the window holds ``back + ahead + 1``
frames where the offline run sees every frame. ``bench/bench_streaming.py`` measures the PSNR of
both on every built-in moving scene, and the time per frame.

A frame the camera dropped is pushed as None: it is bridged from both sides as offline
(:mod:`flexvox_core.gaps`), the window growing until it holds a captured frame on each side (at the
stream's end, from the side there is); a run of dropped frames longer than the method bridges is
refused when it grows past that, and the stream stops (its frames would no longer be the camera's).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from flexvox_core.deprecations import renamed_keyword, warn_renamed
from flexvox_core.flow.memo import FlowMemo
from flexvox_core.gaps import GapTooLongError, max_gap
from flexvox_core.motion.pipeline import MotionOptions, engine_for, run_window
from flexvox_core.numbers import number_pair
from flexvox_core.reconstruct._common import check_identity_code

_logger = logging.getLogger(__name__)

NOISE_MARGIN = 0.25
"""How far outside [0, 1] a normalised frame's values may lie and be taken as sensor noise (clipped into it);
further out a frame is refused (it is not normalised)."""

BACK = 1
"""Frames of context before the reconstructed one by default (they cost time, not latency)."""
AHEAD = 1
"""Frames of context after it: the latency, in frames."""


@dataclass(frozen=True)
class StreamFrame:
    """One reconstructed camera frame.

    Attributes
    ----------
    index : int
        The frame's place in the stream (0 for the first frame pushed).
    video : ndarray (K, H, W) float32
        Its sub-frames.
    interpolated : bool
        True for a dropped frame, filled from both sides.
    window : (start, stop)
        The frames its window held.
    seconds : float
        Time of its reconstruction.
    """

    index: int
    video: np.ndarray
    interpolated: bool
    window: tuple[int, int]
    seconds: float


class StreamingMotionAware:
    """Motion-aware reconstruction of a stream of camera frames of an identity ``code`` (m, n, K).

    Parameters
    ----------
    code : ndarray (m, n, K)
    back, ahead : int
        Frames of context before and after each reconstructed frame (``ahead`` >= 1: the latency).
    sample_range : (lo, hi) or None
        Range every sample lies in: it scales the slow voxels' range weight and bounds the result, as the whole
        recording's range does offline; a frame outside it is refused. None (default): normalised frames, [0, 1],
        and a frame that sensor noise takes out of it by at most :data:`NOISE_MARGIN` is clipped into it (logged
        once per stream, counted in :attr:`clipped`).
    device : {"cpu", "cuda", "auto"}
        Where each window runs (:func:`flexvox_core.gpu.resolve_device`). On the GPU one set of device buffers
        serves every window, and every flow pair of a window is measured again (the card does it faster than the
        memo finds it); :attr:`device` says which ran, and ``device_note`` why the CPU when the GPU was asked for
        (options the GPU's stages do not run as the CPU's).
    **options
        The options of :func:`~flexvox_core.motion.pipeline.motion_aware` (flow, time, refine_time, …).

    Examples
    --------
    >>> stream = StreamingMotionAware(code)                      # doctest: +SKIP
    >>> for frame in camera:                                      # doctest: +SKIP
    ...     for out in stream.push(frame):
    ...         show(out.video)
    >>> for out in stream.finish():                               # doctest: +SKIP
    ...     show(out.video)
    """

    def __init__(self, code, *, back: int = BACK, ahead: int = AHEAD, sample_range=None, device: str = "cpu",
                 **options):
        self.code = check_identity_code(code)
        self.K = int(self.code.shape[2])
        for name, value, least in (("back", back, 0), ("ahead", ahead, 1)):
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"`{name}` must be a whole number >= {least} (frames); got {value!r}")
        self.back, self.ahead = back, ahead
        sample_range = renamed_keyword(options, "value_range", "sample_range", sample_range, "StreamingMotionAware")
        self.options = MotionOptions(**options)
        self._noise_margin = NOISE_MARGIN if sample_range is None else 0.0
        lo, hi = number_pair("sample_range", (0.0, 1.0) if sample_range is None else sample_range)
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"`sample_range` must be two finite numbers lo < hi; got {sample_range!r}")
        self.sample_range = (lo, hi)
        """The range every sample lies in (``sample_range``, or [0, 1])."""
        self.clipped = 0
        """Frames clipped into [0, 1] (``sample_range`` None: values sensor noise took out of it)."""
        # The longest run of dropped frames bridged: as the offline method with its chunk overlap.
        self.max_gap = max_gap(self.options.overlap(self.K))
        self.memo = FlowMemo(max_pairs=max(64, 8 * self.K))
        # Options the GPU's stages do not run as the CPU's run on the CPU (``device_note`` says why).
        self.device, self.device_note = engine_for(self.options, device)
        device = self.device
        self._workspace = None
        if device == "cuda":
            from flexvox_core.gpu.volumes import Workspace

            self._workspace = Workspace()
        self._frames: dict[int, np.ndarray | None] = {}
        self._shape: tuple[int, int] | None = None
        self._pushed = 0
        self._next = 0
        self._finished = False
        self._failed = ""  # why the stream stopped (a gap too long), or empty
        self._run = 0  # dropped frames in a row at the end of the stream
        self._captured = 0  # frames pushed that the camera did not drop

    @property
    def value_range(self) -> tuple[float, float]:
        """Deprecated name of :attr:`sample_range` (removed in the next release)."""
        warn_renamed("StreamingMotionAware.value_range", "StreamingMotionAware.sample_range")
        return self.sample_range

    @property
    def pushed(self) -> int:
        """Frames pushed so far."""
        return self._pushed

    @property
    def emitted(self) -> int:
        """Frames given back so far (the next one to give back)."""
        return self._next

    def push(self, frame) -> list[StreamFrame]:
        """Add the next camera frame (H, W), or None for a frame the camera dropped; returns the
        frames now reconstructed (usually one, none at the start, more after dropped frames)."""
        if self._failed:
            raise RuntimeError(f"the stream stopped ({self._failed}); start a new StreamingMotionAware")
        if self._finished:
            raise RuntimeError("the stream is finished; start a new StreamingMotionAware")
        if frame is None:
            self._run += 1
            if self._run > self.max_gap:
                # The stream cannot go on: its frames would no longer be counted as the camera's.
                self._failed = (f"frames {self._pushed - self._run + 1}-{self._pushed} were dropped in a row; "
                                f"the streaming motion-aware bridges gaps of at most {self.max_gap} frame(s)")
                raise GapTooLongError(self._failed)
            self._frames[self._pushed] = None
        else:
            self._frames[self._pushed] = self._check(frame)
            self._captured += 1
            self._run = 0
        self._pushed += 1
        return self._drain()

    def finish(self) -> list[StreamFrame]:
        """The frames still held back (the last ``ahead``), reconstructed with the context there is."""
        self._finished = True
        if self._pushed and not self._captured:
            raise GapTooLongError("every frame of the stream was dropped: there is nothing to reconstruct")
        return self._drain()

    def ready(self) -> int:
        """How many frames could be reconstructed now (without waiting for more)."""
        n = 0
        while self._window(self._next + n) is not None:
            n += 1
        return n

    def skip_to(self, index: int) -> None:
        """Give up the frames before ``index`` (a preview that cannot keep up: the newest wins);
        they are never reconstructed."""
        index = min(int(index), self._pushed)
        if index > self._next:
            self._next = index
            self._forget()

    # -- internals -------------------------------------------------------------------------------

    def _check(self, frame) -> np.ndarray:
        img = np.asarray(frame)
        if img.ndim != 2:
            raise ValueError(f"a frame must be an image (H, W); got shape {img.shape}")
        if self._shape is None:
            self._shape = img.shape
        elif img.shape != self._shape:
            raise ValueError(f"frame {self._pushed} is {img.shape[0]}x{img.shape[1]}; the stream's frames are "
                             f"{self._shape[0]}x{self._shape[1]}")
        img = img.astype(np.float32)
        lo, hi = self.sample_range
        if not np.isfinite(img).all():
            raise ValueError(f"frame {self._pushed} holds NaN or infinite values")
        f_lo, f_hi = float(img.min()), float(img.max())
        if f_lo < lo or f_hi > hi:
            margin = self._noise_margin
            if not (lo - margin <= f_lo and f_hi <= hi + margin):
                raise ValueError(f"frame {self._pushed} has values in [{f_lo:g}, {f_hi:g}], outside the stream's "
                                 f"sample_range [{lo:g}, {hi:g}]")
            if not self.clipped:
                _logger.info("stream: frame %d has values in [%g, %g] (sensor noise): clipped into [%g, %g], as are "
                             "the later frames outside it", self._pushed, f_lo, f_hi, lo, hi)
            self.clipped += 1
            np.clip(img, lo, hi, out=img)
        return img

    def _left(self, f: int) -> int:
        """The first frame of frame ``f``'s window: ``back`` frames before it, and further back past
        dropped frames (past ``f`` itself when it was dropped) to a captured one. A frame not pushed
        yet counts as captured (it is coming)."""
        a = max(0, f - self.back)
        while a > 0 and all(self._frames.get(i, 0) is None for i in range(a, max(f, a + 1))):
            a -= 1
        return a

    def _window(self, f: int) -> tuple[int, int] | None:
        """Frames [a, b) of frame ``f``'s window, or None while it waits for more frames."""
        if f >= self._pushed:
            return None
        a = self._left(f)
        b = f + self.ahead + 1
        while b <= self._pushed and all(self._frames[i] is None for i in range(f + 1, b)):
            b += 1  # dropped frames after: wait for a captured one
        if b > self._pushed:
            if not self._finished:
                return None
            b = self._pushed
        return a, b

    def _drain(self) -> list[StreamFrame]:
        out = []
        while (window := self._window(self._next)) is not None:
            out.append(self._reconstruct(self._next, window))
            self._next += 1
            self._forget()
        return out

    def _forget(self) -> None:
        # Keep what the next window can reach back to (across dropped frames too).
        keep_from = self._left(self._next)
        if self._next >= self._pushed:
            # The next frame is still coming (`skip_to` the newest): if the camera drops it, its window reaches
            # back past it to the newest captured frame, which `_left` (counting it as captured) would not keep.
            captured = [i for i, r in self._frames.items() if i < self._next and r is not None]
            if captured:
                keep_from = min(keep_from, max(captured))
        for i in [i for i in self._frames if i < keep_from]:
            del self._frames[i]

    def _reconstruct(self, f: int, window: tuple[int, int]) -> StreamFrame:
        t0 = time.perf_counter()
        a, b = window
        rows = [self._frames[i] for i in range(a, b)]
        if all(r is None for r in rows):
            raise GapTooLongError(f"frame {f}'s window (frames {a}-{b - 1}) was all dropped: nothing to bridge from")
        shape = self._shape
        missing = np.array([r is None for r in rows])
        frames = np.stack([np.zeros(shape, np.float32) if r is None else r for r in rows])
        K = self.K
        keep = ((f - a) * K, (f - a + 1) * K)
        result = run_window(frames, self.code, self.options, self.sample_range,
                            missing=missing if missing.any() else None, keep=keep, memo=self.memo, device=self.device,
                            workspace=self._workspace)
        seconds = time.perf_counter() - t0
        _logger.debug("stream frame %d over frames [%d, %d): %.2f s (flow memo %d hits, %d misses)",
                      f, a, b, seconds, self.memo.hits, self.memo.misses)
        return StreamFrame(f, result.video, bool(missing[f - a]), (a, b), seconds)

