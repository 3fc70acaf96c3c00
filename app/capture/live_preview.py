"""What the live preview reconstructs, and how big a region it takes on (Qt-free).

The Capture workspace previews the newest camera frames reconstructed by motion-aware
(:mod:`flexvox_app.gui.capture.live_preview` runs it beside capture). This module holds the parts that
need no Qt, so that a benchmark and the tests can run them alone:

* :class:`FrameBuffer` — the newest run of consecutive frames (a gap starts a new run).
* :func:`preview_region` — the part of the frame a run takes on. **Always at full resolution**:
  when the whole frame would take longer than the budget, a region of it (whole tiles, placed on
  the tile grid, so the crop is a capture of the same code), centred where the operator put it.
  Never a subsampled frame: subsampling aliases fine motion and focus away.
* :class:`PixelCost` — seconds per pixel of the last runs, which sizes the next region. A slow run
  (a busy machine) shrinks the region; the next quick one grows it back, because the prediction
  is the measured cost of a pixel, not an extrapolation from a smaller run.
* :class:`PreviewReconstructor` — motion-aware by the streaming reconstructor
  (:mod:`flexvox_core.motion.streaming`: the frame before the newest, its flow pairs and frames kept
  between runs), or the fast constant-tensor ``nc`` (the preview's fallback: the whole VGA frame in
  about a tenth of a second, the newest frame), of a region of the newest frames: K sub-frames.
* :func:`preview_options` — motion-aware's options for it: the flow at the whole frame's scale, whatever the
  region, so that a region shows what the recording's reconstruction will show there.

When the machine cannot keep up the preview gives way in this order: first frames are skipped (the newest
wins, always), then the region shrinks; it never shows a subsampled frame.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

_logger = logging.getLogger(__name__)

PREVIEW_FRAMES = 3
"""Camera frames reconstructed together: motion-aware shows the middle one (one frame of latency), nc the newest."""
START_PIXELS = 160 * 120
"""Pixels of the first run's region (before any run has been timed)."""
PREVIEW_METHODS = ("motion-aware", "nc")
"""What the preview reconstructs with: motion-aware (a region when the whole frame does not fit), or
constant-tensor diffusion's normalized convolution (diffusion's default tensor), fast enough for the
whole frame at a few hertz."""
MIN_SIDE = 32
"""The region is never smaller than this many pixels a side (nor than one tile), nor than the frame."""


@dataclass(frozen=True)
class Region:
    """Rows ``[y0, y1)`` and columns ``[x0, x1)`` of the frame."""

    y0: int
    y1: int
    x0: int
    x1: int

    @property
    def shape(self) -> tuple[int, int]:
        """(h, w)."""
        return self.y1 - self.y0, self.x1 - self.x0

    @property
    def pixels(self) -> int:
        h, w = self.shape
        return h * w

    @property
    def centre(self) -> tuple[float, float]:
        """(y, x) of its centre."""
        return (self.y0 + self.y1) / 2, (self.x0 + self.x1) / 2

    def covers(self, shape: tuple[int, int]) -> bool:
        """True when it is the whole frame of ``shape``."""
        return (self.y0, self.x0) == (0, 0) and (self.y1, self.x1) == tuple(shape)

    def crop(self, images: np.ndarray) -> np.ndarray:
        """``images[..., y0:y1, x0:x1]``."""
        return images[..., self.y0:self.y1, self.x0:self.x1]


def preview_region(shape: tuple[int, int], tile: tuple[int, int], max_pixels: float,
                   centre: tuple[float, float] | None = None) -> Region:
    """The region of a ``shape`` frame a preview run takes on: the whole frame when it has at most
    ``max_pixels``, else a region of about that many pixels with the frame's aspect ratio, whole
    tiles on the tile grid, around ``centre`` (y, x; default the frame's centre) and inside the frame.

    Examples
    --------
    >>> preview_region((120, 160), (4, 4), 160 * 120)
    Region(y0=0, y1=120, x0=0, x1=160)
    >>> preview_region((480, 640), (4, 4), 160 * 120)
    Region(y0=180, y1=300, x0=240, x1=400)
    """
    H, W = (int(v) for v in shape)
    m, n = (int(v) for v in tile)
    if not max_pixels > 0:
        raise ValueError(f"`max_pixels` must be > 0; got {max_pixels}")
    if H * W <= max_pixels:
        return Region(0, H, 0, W)
    scale = math.sqrt(max_pixels / (H * W))
    floor_h, floor_w = min(H, max(m, MIN_SIDE)), min(W, max(n, MIN_SIDE))
    h = min(H, max(floor_h, int(H * scale) // m * m))
    w = min(W, max(floor_w, int(W * scale) // n * n))
    cy, cx = (H / 2, W / 2) if centre is None else (float(centre[0]), float(centre[1]))
    # Corners on the tile grid (multiples of m and n): the crop opens its pixels as the code says.
    y0 = int(min(max(0, cy - h / 2), H - h)) // m * m
    x0 = int(min(max(0, cx - w / 2), W - w)) // n * n
    return Region(y0, min(H, y0 + h), x0, min(W, x0 + w))


PROBE = 1.5
"""After a run that took under :data:`PROBE_BELOW` of the budget, the next may take on this many times its pixels
whatever the measured cost says (at worst, all cost per pixel, it lasts 1.2 budgets): the region grows back when
runs get faster, also where a run's fixed part makes a small region's cost per pixel look dear."""
PROBE_BELOW = 0.8


class PixelCost:
    """What a run costs: ``a + b·pixels`` fitted over the last ``runs`` runs when they covered different sizes (a
    run's fixed part — the flow's set-up, the compiled kernels' calls — then does not count as cost per pixel), else
    their median cost per pixel."""

    def __init__(self, runs: int = 3):
        self._runs: deque[tuple[float, int]] = deque(maxlen=runs)

    def add(self, seconds: float, pixels: int) -> None:
        """Record a run of ``seconds`` over ``pixels``."""
        if pixels > 0 and seconds > 0:
            self._runs.append((float(seconds), int(pixels)))

    def _model(self) -> tuple[float, float]:
        """(fixed seconds a, seconds per pixel b) of the runs recorded."""
        t = np.array([r[0] for r in self._runs])
        p = np.array([r[1] for r in self._runs], float)
        if p.max() > 1.1 * p.min():
            b, a = np.polyfit(p, t, 1)
            if b > 0 and a >= 0:
                return float(a), float(b)
        return 0.0, float(np.median(t / p))

    def pixels_for(self, budget_s: float, default: float) -> float:
        """Pixels a run may take on to last about ``budget_s``; ``default`` before any run; after a quick run at
        least :data:`PROBE` times its pixels."""
        if not self._runs:
            return default
        a, b = self._model()
        pixels = (budget_s - a) / b if budget_s > a else budget_s / float(np.median([t / p for t, p in self._runs]))
        seconds, last = self._runs[-1]
        if seconds < PROBE_BELOW * budget_s:
            pixels = max(pixels, PROBE * last)
        return pixels

    def seconds_for(self, pixels: int) -> float | None:
        """About how long a run over ``pixels`` takes at the measured cost (None before any run)."""
        if not self._runs:
            return None
        a, b = self._model()
        return a + b * pixels

    def clear(self) -> None:
        self._runs.clear()


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
    """One preview: the newest frame's sub-frames over a region of the frame, at full resolution.

    Attributes
    ----------
    video : ndarray (K, h, w) float32
    frame_id : int
        Camera frame shown.
    n_frames : int
        Camera frames reconstructed together.
    region : Region
        Where ``video`` lies in the frame.
    frame_shape : (H, W)
        The camera frame's size.
    seconds : float
        Time of the reconstruction.
    levels : (low, high)
    method : str
        One of :data:`PREVIEW_METHODS`.
    device : str
        Where it ran: ``cpu`` or ``cuda``.
    """

    video: np.ndarray
    frame_id: int
    n_frames: int
    region: Region
    frame_shape: tuple[int, int]
    seconds: float
    levels: tuple[float, float]
    method: str = "motion-aware"
    device: str = "cpu"

    @property
    def size(self) -> tuple[int, int]:
        """(w, h) of the preview."""
        return int(self.video.shape[2]), int(self.video.shape[1])

    @property
    def whole_frame(self) -> bool:
        """True when the preview covers the whole camera frame."""
        return self.region.covers(self.frame_shape)


class PreviewReconstructor:
    """Reconstructs preview runs, keeping motion-aware's stream between them.

    Motion-aware runs through :class:`~flexvox_core.motion.streaming.StreamingMotionAware`: a run shows
    the frame *before* the newest (one frame of latency, so its trajectories reach both ways, where a
    run that showed the newest frame would see only its past), over the window of the newest
    consecutive frames. Between runs the stream keeps the frames and the flow of every pair of
    sub-frames it measured: when the preview keeps up with the camera, each run pushes one new frame
    and reuses the rest. A change of code or region, a gap in the frames, a run that fell behind by
    more than the window, or frames brighter than the stream's scale (:func:`_full_scale`) starts a new
    stream. ``nc`` keeps no state and shows the newest frame. The runs of one reconstructor must not
    overlap (the live preview runs one at a time).

    ``device``: ``cpu`` (the default) or ``cuda``. On the GPU motion-aware runs with all its stages (the
    refinement, the local choice and the noise-aware smoothing, which the CPU preview leaves out to cover a
    larger region), the stream's device buffers kept between runs.
    """

    def __init__(self, device: str = "cpu"):
        if device not in ("cpu", "cuda"):
            raise ValueError(f"`device` must be cpu or cuda; got {device!r}")
        self.device = device
        self._stream = None
        self._key = None
        self._first_id = 0
        """Camera frame id of the stream's frame 0."""
        self._scale = 1.0
        """What the stream's frames are divided by (:func:`_full_scale`)."""

    def run(self, frames: list, code, region: Region | None = None, method: str = "motion-aware") -> PreviewResult:
        """The reconstruction (``method``: one of :data:`PREVIEW_METHODS`) of ``region`` (default: all) of
        ``frames`` (consecutive Frames, oldest first) at full resolution.

        ``code`` is the capture's identity code (m, n, K) or its :class:`~flexvox_core.multiplex.MultiplexedCode`
        (demultiplexed over the whole frame first, then cropped). A region must be a non-empty part of the
        frame and its corner must lie on the tile grid (:func:`preview_region` places it so): the crop is then
        a capture of the same code. Frames are taken to [0, 1] (:func:`normalise`; float frames above 1, a
        camera's counts, by :func:`_full_scale`) and clipped there (a noisy demultiplex leaves it a little): a
        preview never stops on its input's range.
        """
        from flexvox_core.reconstruct import as_identity_capture, diffuse

        if method not in PREVIEW_METHODS:
            raise ValueError(f"`method` must be one of {', '.join(PREVIEW_METHODS)}; got {method!r}")
        if not frames:
            raise ValueError("`frames` must hold at least one frame")
        t0 = time.perf_counter()
        stack = np.stack([normalise(f.image) for f in frames])
        H, W = stack.shape[1:]
        region = Region(0, H, 0, W) if region is None else region
        if not (0 <= region.y0 < region.y1 <= H and 0 <= region.x0 < region.x1 <= W):
            raise ValueError(f"a preview region must be a non-empty part of the {H}x{W} frame "
                             f"(0 <= y0 < y1 <= {H}, 0 <= x0 < x1 <= {W}); got {region}")
        if isinstance(code, np.ndarray):
            m, n = code.shape[:2]
            if region.y0 % m or region.x0 % n:
                raise ValueError(f"a preview region must start on the tile grid ({m}x{n}); got {region}")
            stack, identity = as_identity_capture(region.crop(stack), code)
        else:
            stack, identity = as_identity_capture(stack, code)  # demultiplex whole tiles, then crop
            stack = region.crop(stack)
        K = identity.shape[2]
        ids = [int(f.frame_id) for f in frames]
        key = (identity.tobytes(), identity.shape, region, (H, W))
        if method == "nc":
            stack = np.ascontiguousarray(stack / _full_scale(stack), np.float32)
            video, shown, n_frames = diffuse(stack, identity)[-K:], ids[-1], len(frames)
        else:
            scale = _full_scale(stack)
            if self._stream is None or key != self._key or scale > self._scale:
                # One scale for the stream's life (its samples' range is fixed): brighter frames than the stream
                # began with (a float camera's counts rising past its first power of two) start a new one.
                self._scale, self._stream = scale, None
            stack = np.ascontiguousarray(np.clip(stack / self._scale, 0.0, 1.0), np.float32)
            video, shown, n_frames = self._motion_aware(stack, identity, ids, key)
        video = np.clip(video, 0.0, 1.0).astype(np.float32, copy=False)
        hi = float(np.percentile(video, 99.5)) if video.size else 1.0
        return PreviewResult(video, shown, n_frames, region, (int(H), int(W)), time.perf_counter() - t0,
                             (0.0, hi if hi > 0 else 1.0), method, self.device if method == "motion-aware" else "cpu")

    def _motion_aware(self, stack: np.ndarray, identity: np.ndarray, ids: list[int], key):
        """(K sub-frames, the frame id shown, frames in its window) by the stream."""
        from flexvox_core.motion.streaming import StreamingMotionAware

        options = preview_options(key[3], self.device)  # key[3]: the camera frame's (H, W)
        stream = self._stream
        pushed_to = None if stream is None else self._first_id + stream.pushed - 1  # newest id in the stream
        if (stream is None or key != self._key or ids != list(range(ids[0], ids[0] + len(ids)))
                or ids[0] > pushed_to + 1 or ids[-1] <= pushed_to):
            stream = self._stream = StreamingMotionAware(identity, device=self.device, **options)
            self._key, self._first_id, pushed_to = key, ids[0], ids[0] - 1
        if len(ids) == 1:  # the first frame of a run: nothing after it yet, shown alone
            self._stream = None
            from flexvox_core.motion import motion_aware

            return motion_aware(stack, identity, sample_range=(0.0, 1.0), device=self.device,
                                **options).video, ids[0], 1
        target = ids[-1] - 1 - self._first_id  # the frame before the newest, as the stream counts
        out = []
        for fid, image in zip(ids, stack, strict=True):
            if fid > pushed_to:
                stream.skip_to(min(stream.pushed, target))  # the newest wins: older frames are not reconstructed
                out += stream.push(image)
        shown = out[-1]
        a, b = shown.window
        return shown.video, self._first_id + shown.index, b - a


def preview_options(frame_shape: tuple[int, int], device: str = "cpu") -> dict:
    """Motion-aware's options for a preview of a camera frame of ``frame_shape`` (H, W), whatever region of it runs.

    * The flow at the scale the whole frame's reconstruction uses (:func:`~flexvox_core.motion.options.auto_flow_scale`
      of the frame, not of the region): a region then shows what the recording's reconstruction will show there,
      where a region's own scale (finer: 0.56-0.83 for 288-192 px regions of a 640×480 frame, against 1/3) made it
      0.2-1.5 dB better or worse than that, at 1.2-2× the time (docs/benchmarks.md, "Live preview").
    * On the CPU without the refinement (a sixth less time per run, so a larger region; it adds ~0.4 dB offline),
      the local choice (about 8 % of a VGA run for a few hundredths of a dB there) and the noise-aware smoothing
      (a wider blur, more voxels gathered); on the GPU all of them.
    """
    from flexvox_core.motion.options import auto_flow_scale

    scale = {"flow_scale": auto_flow_scale(*frame_shape)}
    if device == "cuda":
        return scale
    return {**scale, "refine_time": 0.0, "local_choice": False, "noise_aware": False}


def _full_scale(stack: np.ndarray) -> float:
    """1 for frames in [0, 1]; else the smallest power of two above their largest value (a float camera's
    counts: 255 -> 256, 4095 -> 4096, 128 -> 256), so that they fall in [0, 1]."""
    top = float(np.max(stack)) if stack.size else 0.0
    return 1.0 if not top > 1.0 else float(2.0 ** (math.floor(math.log2(top)) + 1))


def reconstruct_preview(frames: list, code, region: Region | None = None, method: str = "motion-aware",
                        device: str = "cpu") -> PreviewResult:
    """One preview run without state (:meth:`PreviewReconstructor.run` of a new reconstructor)."""
    return PreviewReconstructor(device).run(frames, code, region, method)
