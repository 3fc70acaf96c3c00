r"""Flow over a whole high-speed video, made robust where flexible-voxel reconstruction needs it.

For sub-frames s = 0..S-1 the result holds the velocity at each pixel, in pixels per
sub-frame, and a confidence in [0, 1]:

* **Forward–backward consistency** (occlusions): with F the flow s→s+1 and B the flow
  s+1→s, a pixel is trusted when ``|F(x) + B(x + F(x))|² ≤ 0.01 (|F|² + |B|²) + 0.5``
  (Sundaram et al. 2010); the confidence falls off smoothly beyond that.
* **Borders**: flow that leaves the image has confidence 0 (no evidence past the border).
* **Temporal consistency**: the velocity at sub-frame s is the confidence-weighted mean of
  the forward flows of s-w..s+w (default w = 1): motion is smooth over a few milliseconds,
  and a single bad pair does not flip a tensor.
* **Large motion**: flow is computed on a copy scaled by ``scale`` (default 0.5) and scaled
  back, which halves displacements for the coarse-to-fine search and quarters the work;
  the paper notes flow needs far less spatial resolution than the scene.
* **Robustness of values**: NaN or infinite flow is replaced by zero with confidence 0,
  and magnitudes are capped at half the image size.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np

from flexvox_core.flow.backends import backend_params, make_backend
from flexvox_core.flow.mean_kernel import pair_mean
from flexvox_core.threads import for_each

_logger = logging.getLogger(__name__)

MIN_FLOW_SIDE = 16
"""Images smaller than this are mirror-padded for the flow backend (DIS needs 12 px)."""


@dataclass
class FlowField:
    """Velocity and confidence of every voxel.

    Attributes
    ----------
    flow : ndarray, shape (S, H, W, 2), float32
        (u, v) in pixels per sub-frame.
    confidence : ndarray, shape (S, H, W), float32 in [0, 1]
    params : dict
        Backend, its parameters and the robustness settings.
    seconds : float
        Time spent computing flow.
    """

    flow: np.ndarray
    confidence: np.ndarray
    params: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def magnitude(self) -> np.ndarray:
        """Speed ``(S, H, W)`` in pixels per sub-frame."""
        return np.hypot(self.flow[..., 0], self.flow[..., 1])

    @property
    def shape(self) -> tuple[int, ...]:
        """``flow``'s shape (S, H, W, 2)."""
        shape: tuple[int, ...] = self.flow.shape
        return shape

    @property
    def held(self) -> np.ndarray:
        """The velocity array held: ``flow`` itself (as :attr:`ScaledFlow.held`)."""
        return self.flow

    def band(self, t0: int, t1: int) -> np.ndarray:
        """``flow[t0:t1]`` (a view): the :class:`~flexvox_core.planes.Bands` protocol."""
        return self.flow[t0:t1]

    def put(self, t: int, plane: np.ndarray) -> None:
        """Set sub-frame ``t``'s velocity (H, W, 2)."""
        self.flow[t] = plane


class ScaledFlow:
    """Velocity and confidence of every voxel, held at the flow's own (smaller) scale; full-size planes are made
    when read (:meth:`band`), each exactly as :func:`upsample_flow` makes it: ``cv2.resize(small[t] * ratio)``,
    bilinear.

    A :class:`FlowField` in what it offers (``flow``, ``confidence``, ``params``, ``seconds``, ``magnitude``;
    the full-size arrays made when first read, and kept), and a :class:`~flexvox_core.planes.Bands`
    (``shape``, ``band``): a reader of a few sub-frames at a time never makes the whole volume (at 640×480 ×
    240 sub-frames it is 590 MB; at a third of the size, 66 MB).

    Parameters
    ----------
    small : ndarray (S, h, w, 2) float32
        The velocity at its own scale, in its own pixels per sub-frame (sanitised: :func:`sanitize_flow`).
    small_confidence : ndarray (S, h, w) float32
        Held as a read-only view of 1 where it is 1 everywhere (the flow without a round-trip check).
    size : (H, W)
        The full size.
    params : dict
    seconds : float
    """

    def __init__(self, small: np.ndarray, small_confidence: np.ndarray, size: tuple[int, int],
                 params: dict | None = None, seconds: float = 0.0) -> None:
        S, h, w = small.shape[:3]
        if small.shape != (S, h, w, 2) or small.dtype != np.float32 or small_confidence.shape != (S, h, w):
            raise ValueError(f"`small` must be float32 (S, h, w, 2) and `small_confidence` (S, h, w); got "
                             f"{small.dtype} {small.shape} and {small_confidence.shape}")
        H, W = (int(v) for v in size)
        if small_confidence.size and small_confidence.min() == 1:  # the usual case: a read-only view of 1, no memory
            small_confidence = np.broadcast_to(np.float32(1), small_confidence.shape)
        self.small = small
        self.small_confidence = small_confidence
        self.size = (H, W)
        self.params = dict(params or {})
        self.seconds = seconds
        self.ratio = np.array([W / w, H / h], np.float32)
        self._put: dict[int, np.ndarray] = {}  # full-size planes set by put()

    @property
    def shape(self) -> tuple[int, ...]:
        """The full-size flow's shape (S, H, W, 2)."""
        return (len(self.small), *self.size, 2)

    @property
    def held(self) -> np.ndarray:
        """The velocity array held: ``small``."""
        return self.small

    def plane(self, t: int, out: np.ndarray | None = None) -> np.ndarray:
        """Sub-frame ``t``'s full-size velocity (H, W, 2), into ``out`` when given."""
        if out is None:
            out = np.empty((*self.size, 2), np.float32)
        put = self._put.get(t)
        if put is not None:
            out[...] = put
        else:
            cv2.resize(scaled_vectors(self.small[t], self.ratio), self.size[::-1], dst=out,
                       interpolation=cv2.INTER_LINEAR)
        return out

    def scaled(self, t: int) -> tuple[np.ndarray, ...] | None:
        """Sub-frame ``t``'s velocity for a reader of a few voxels: ``(plane, *tables)``, the small plane scaled
        (h, w, 2) and :func:`resize_tables`, from which :func:`resize_at` gives any voxel of :meth:`plane` (t),
        the same bits, without the full-size plane. None where :meth:`plane` is not that resize: a plane
        :meth:`put`, the full-size volume made (read it), or an OpenCV whose resize the tables do not reproduce
        (checked once on a plane)."""
        if t in self._put or "flow" in self.__dict__ or self._tables is None:
            return None
        return (scaled_vectors(self.small[t], self.ratio), *self._tables)

    @cached_property
    def _tables(self) -> tuple[np.ndarray, ...] | None:
        """:func:`resize_tables` of the sizes where they reproduce ``cv2.resize`` on the middle plane, else None."""
        tables = resize_tables(self.small.shape[1:3], self.size)
        t = len(self.small) // 2
        small = scaled_vectors(self.small[t], self.ratio)
        full = cv2.resize(small, self.size[::-1], interpolation=cv2.INTER_LINEAR)
        return tables if np.array_equal(resize_at(small, *tables), full, equal_nan=True) else None

    def band(self, t0: int, t1: int) -> np.ndarray:
        """Full-size sub-frames ``t0`` to ``t1`` (exclusive; clipped to the sub-frames, as a slice is)."""
        if "flow" in self.__dict__:
            return self.flow[t0:t1]
        t0, t1, _ = slice(t0, t1).indices(len(self.small))
        out = np.empty((max(0, t1 - t0), *self.size, 2), np.float32)
        self.band_into(t0, t1, out)
        return out

    def band_into(self, t0: int, t1: int, out: np.ndarray) -> np.ndarray:
        """Full-size sub-frames ``t0`` to ``t1`` (exclusive, within the sub-frames) into ``out``
        (``t1 − t0``, H, W, 2) float32, whose planes are C-contiguous; returns ``out``."""
        S = len(self.small)
        if not 0 <= t0 <= t1 <= S or out.shape != (t1 - t0, *self.size, 2) or out.dtype != np.float32:
            raise ValueError(f"sub-frames {t0} to {t1} of {S} into `out` {out.dtype} {out.shape}: they must be "
                             f"within the sub-frames, and `out` float32 of shape {(t1 - t0, *self.size, 2)}")
        if "flow" in self.__dict__:
            out[...] = self.flow[t0:t1]
            return out

        def one(i: int) -> None:
            self.plane(t0 + i, out[i])

        if len(out) > 1:
            for_each(one, len(out))  # OpenCV releases the GIL: planes side by side
        elif len(out):
            one(0)
        return out

    def put(self, t: int, plane: np.ndarray) -> None:
        """Set sub-frame ``t``'s full-size velocity (H, W, 2): read from here on instead of the resized one."""
        plane = np.array(plane, np.float32)
        if plane.shape != (*self.size, 2):
            raise ValueError(f"`plane` must have shape {(*self.size, 2)}; got {plane.shape}")
        self._put[t] = plane
        if "flow" in self.__dict__:
            self.flow[t] = plane

    @cached_property
    def flow(self) -> np.ndarray:
        """The full-size velocity (S, H, W, 2) float32, made when first read."""
        out = np.empty(self.shape, np.float32)

        def one(t: int) -> None:
            self.plane(t, out[t])

        for_each(one, len(self.small))
        return out

    @cached_property
    def confidence(self) -> np.ndarray:
        """The full-size confidence (S, H, W), resized as :func:`to_full_size` does (a read-only view of 1 where
        it is 1 everywhere)."""
        conf = self.small_confidence
        S, h, w = conf.shape
        H, W = self.size
        if (h, w) == (H, W):
            return conf
        if conf.min() == 1:
            return np.broadcast_to(np.float32(1), (S, H, W))
        full = np.empty((S, H, W), np.float32)
        for i, c in enumerate(conf):
            cv2.resize(c, (W, H), dst=full[i], interpolation=cv2.INTER_LINEAR)
        return full

    @property
    def magnitude(self) -> np.ndarray:
        """Speed ``(S, H, W)`` in pixels per sub-frame."""
        return np.hypot(self.flow[..., 0], self.flow[..., 1])


def to_uint8(video: np.ndarray) -> np.ndarray:
    """Map a video in [0, 1] to uint8 (a fixed scale: the same pixels give the same flow in
    any chunk of a long recording; values outside [0, 1] are clipped)."""
    return np.clip(video * np.float32(255) + np.float32(0.5), 0, 255).astype(np.uint8)


def to_uint8_planes(video: np.ndarray) -> np.ndarray:
    """:func:`to_uint8` of a video (S, H, W), a sub-frame at a time on every core: its values, without its three
    whole-volume float32 temporaries (fresh memory is dear: at the flow's size of a 1-s 640×480 clip they cost
    0.15-0.4 s of one core)."""
    out = np.empty(video.shape, np.uint8)

    def one(s: int) -> None:
        out[s] = to_uint8(video[s])

    for_each(one, len(video))
    return out


def _warp(field_: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """Sample ``field_`` at x + flow(x) (bilinear, replicate borders)."""
    H, W = flow.shape[:2]
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    return cv2.remap(field_, gx + flow[..., 0], gy + flow[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def consistency_confidence(fwd: np.ndarray, bwd: np.ndarray) -> np.ndarray:
    """Confidence of ``fwd`` from the round trip with ``bwd``, and 0 where it leaves the image."""
    H, W = fwd.shape[:2]
    back = _warp(bwd, fwd)
    err2 = np.sum((fwd + back) ** 2, axis=-1)
    tol = 0.01 * (np.sum(fwd**2, axis=-1) + np.sum(back**2, axis=-1)) + 0.5
    conf = np.exp(-np.maximum(err2 - tol, 0) / tol)
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32))
    tx, ty = gx + fwd[..., 0], gy + fwd[..., 1]
    conf[(tx < 0) | (tx > W - 1) | (ty < 0) | (ty > H - 1)] = 0
    return conf.astype(np.float32)


def sanitize_flow(flow: np.ndarray, confidence: np.ndarray | None = None, *, max_magnitude: float | None = None):
    """Replace NaN/inf by 0 (confidence 0) and cap the magnitude; returns (flow, confidence)."""
    flow = np.asarray(flow, dtype=np.float32)
    if flow.ndim < 3 or flow.shape[-1] != 2:
        raise ValueError(f"`flow` must have shape (..., H, W, 2); got {flow.shape}")
    conf = np.ones(flow.shape[:-1], np.float32) if confidence is None else np.array(confidence, np.float32)
    # Both checks first from the largest and smallest values, two passes that usually settle them (no
    # temporaries): every value finite (NaN makes both NaN), no component beyond max_magnitude / √2.
    top, bottom = (flow.max(), flow.min()) if flow.size else (np.float32(0), np.float32(0))
    if not (np.isfinite(top) and np.isfinite(bottom)):
        bad = ~np.isfinite(flow).all(axis=-1)
        flow = flow.copy()
        flow[bad] = 0
        conf[bad] = 0
        top, bottom = flow.max(), flow.min()
    if max_magnitude is not None and max(top, -bottom) * np.sqrt(2) > max_magnitude:
        mag = np.hypot(flow[..., 0], flow[..., 1])
        over = mag > max_magnitude
        if over.any():
            flow = flow * np.where(over, max_magnitude / np.maximum(mag, 1e-12), 1)[..., None]
    # A confidence made here is 1 or 0; one given is clipped to [0, 1] (NaN fails both checks: it stays NaN).
    if confidence is not None and conf.size and not (np.min(conf) >= 0 and np.max(conf) <= 1):
        conf = np.clip(conf, 0, 1)
    return flow.astype(np.float32, copy=False), conf


def flow_size(H: int, W: int, scale: float) -> tuple[int, int]:
    """The size (h, w) :func:`downscale` gives an H×W picture at ``scale``: never below :data:`MIN_FLOW_SIDE` px,
    never above the picture."""
    return min(H, max(MIN_FLOW_SIDE, round(H * scale))), min(W, max(MIN_FLOW_SIDE, round(W * scale)))


def downscale(v: np.ndarray, scale: float) -> np.ndarray:
    """The video resized by ``scale`` (area average, never below :data:`MIN_FLOW_SIDE` px), float32.
    Flow runs at this size, and so does everything computed from the video before it."""
    S, H, W = v.shape
    h, w = flow_size(H, W, scale)
    if (h, w) == (H, W):
        return v.astype(np.float32, copy=False)
    out = np.empty((S, h, w), np.float32)

    def one(s):
        cv2.resize(v[s].astype(np.float32, copy=False), (w, h), dst=out[s], interpolation=cv2.INTER_AREA)

    for_each(one, S)  # OpenCV releases the GIL: two sub-frames at a time on two cores
    return out


def run_pairs(flow_fn, u8: np.ndarray, pairs, out: np.ndarray, conf: np.ndarray, *, consistency: bool,
              memo=None) -> None:
    """Flow ``u8[a] → u8[b]`` for each (a, b) in ``pairs`` into ``out[i]`` (confidence into ``conf[i]``),
    the pairs spread over the cores (OpenCV releases the GIL; each pair writes its own slice).
    ``memo`` (a :class:`~flexvox_core.flow.memo.FlowMemo`): pairs found there are not computed again,
    and the new ones are stored."""
    _, h, w = u8.shape
    tag = repr(sorted(backend_params(flow_fn).items())) if memo is not None else ""
    pad_y, pad_x = max(0, MIN_FLOW_SIDE - h), max(0, MIN_FLOW_SIDE - w)

    def pair(a, b):  # backends need a minimum size (DIS: 12 px): mirror-pad small images
        if pad_y or pad_x:
            a = cv2.copyMakeBorder(a, 0, pad_y, 0, pad_x, cv2.BORDER_REFLECT)
            b = cv2.copyMakeBorder(b, 0, pad_y, 0, pad_x, cv2.BORDER_REFLECT)
        return sanitize_flow(flow_fn(a, b)[:h, :w])

    def one(i):
        a, b = pairs[i]
        key = memo.key(tag, u8[a], u8[b], consistency) if memo is not None else None
        found = memo.get(key) if key is not None else None
        if found is not None:
            out[i], conf[i] = found
            return
        f_ab, c = pair(u8[a], u8[b])
        if consistency:
            bwd, cb = pair(u8[b], u8[a])
            c = c * consistency_confidence(f_ab, bwd) * np.minimum(cb, 1)
        out[i], conf[i] = f_ab, c
        if key is not None:
            memo.put(key, out[i], conf[i])

    for_each(one, len(pairs))


def resize_tables(small: tuple[int, int], size: tuple[int, int]) -> tuple[np.ndarray, ...]:
    """``cv2.resize``'s bilinear (``INTER_LINEAR``, float32) from ``small`` (h, w) to ``size`` (H, W) as tables:
    ``(rows0, rows1, wy0, wy1, cols0, cols1, wx0, wx1)``, the two source rows (int64, (H,)) and their float32
    weights of each output row, the same of each column (W,). Output pixel (y, x) is
    ``(p[r0, c0]·a0 + p[r0, c1]·a1)·b0 + (p[r1, c0]·a0 + p[r1, c1]·a1)·b1`` in float32 (:func:`resize_at`), OpenCV's
    coefficients and order of operations: its position (d + ½)·(source / output) − ½ rounded to float32, its
    fraction f and weights (1 − f, f); a column outside the source takes the edge pixel with weight 1, a row
    outside takes the edge row as both rows, with the fraction's weights (as OpenCV's generic resize does)."""

    def axis(n_out: int, n_in: int, rows: bool) -> tuple[np.ndarray, ...]:
        pos = ((np.arange(n_out) + 0.5) * (1.0 / (n_out / n_in)) - 0.5).astype(np.float32)
        start = np.floor(pos).astype(np.int64)
        frac = (pos - start.astype(np.float32)).astype(np.float32)
        if not rows:
            low, high = start < 0, start >= n_in - 1
            frac[low | high] = 0
            start = np.clip(start, 0, n_in - 1)
        return (np.clip(start, 0, n_in - 1), np.clip(start + 1, 0, n_in - 1), (np.float32(1) - frac).astype(np.float32),
                frac)

    (h, w), (H, W) = small, size
    return (*axis(H, h, True), *axis(W, w, False))


def resize_at(plane: np.ndarray, rows0, rows1, wy0, wy1, cols0, cols1, wx0, wx1) -> np.ndarray:
    """The full-size plane of :func:`resize_tables` in numpy (the compiled readers take single voxels)."""
    a0, a1 = wx0[:, None], wx1[:, None]
    top = plane[rows0][:, cols0] * a0 + plane[rows0][:, cols1] * a1
    bottom = plane[rows1][:, cols0] * a0 + plane[rows1][:, cols1] * a1
    return top * wy0[:, None, None] + bottom * wy1[:, None, None]


def scaled_vectors(plane: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """``plane * ratio``, a new array: a velocity plane (h, w, 2) float32 with its x and y components scaled by
    ``ratio`` (2,) float32, the same bits as numpy's product (each component one float32 multiplication) in a
    thirtieth of its time (numpy's broadcast over a last axis of 2 runs 2 values per inner loop)."""
    return cv2.multiply(plane, (float(ratio[0]), float(ratio[1]), 0.0, 0.0))


def upsample_flow(flow: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Flow ``(N, h, w, 2)`` resized to ``size`` = (H, W), its vectors scaled with it (bilinear)."""
    H, W = size
    N, h, w = flow.shape[:3]
    out = np.empty((N, H, W, 2), np.float32)
    # Vectors scaled before the resize (a linear map): the small flow is cheap to touch, the
    # full-size one is not (two strided passes over it cost ~0.3 s at 640×480 × 240 sub-frames).
    ratio = np.array([W / w, H / h], np.float32)

    def one(i):
        cv2.resize(scaled_vectors(flow[i], ratio), (W, H), dst=out[i], interpolation=cv2.INTER_LINEAR)

    for_each(one, N)  # OpenCV releases the GIL: two sub-frames at a time on two cores
    return out


def check_video(video) -> np.ndarray:
    """``video`` as an array ``(S, H, W)`` with S >= 2 and finite values, or a ValueError saying why."""
    v = np.asarray(video)
    if v.ndim != 3:
        raise ValueError(f"`video` must have shape (S, H, W); got {v.ndim} dimensions {v.shape}")
    if v.shape[0] < 2:
        raise ValueError(f"`video` needs at least 2 sub-frames for flow; got {v.shape[0]}")
    # One pass without a boolean volume first (a float64 sum of float32 values cannot overflow; NaN
    # and inf carry through): at 640x480 x 240 sub-frames the volume cost 0.2 s, mostly fresh memory.
    if not subframe_sums_finite(v) and not np.isfinite(v).all():
        bad = int(np.flatnonzero(~np.isfinite(v).all(axis=(1, 2)))[0])
        raise ValueError(f"`video` sub-frame {bad} holds NaN or infinite values")
    return v


def subframe_sums_finite(v: np.ndarray) -> bool:
    """Whether each sub-frame's float64 sum of ``v`` (S, H, W) is finite, the sub-frames summed on every core: True
    when every value is finite and a float32 video's (its sum cannot overflow); False for any NaN or infinity (a
    float64 video's huge values may overflow a sum too: the caller checks the values then)."""
    sums = np.empty(len(v), np.float64)

    def one(s: int) -> None:
        with np.errstate(over="ignore"):
            sums[s] = v[s].sum(dtype=np.float64)

    for_each(one, len(v))
    return bool(np.isfinite(sums).all())


def successive_flow(small: np.ndarray, flow_fn, *, consistency: bool, temporal_window: int, memo=None):
    """Velocity ``(S, h, w, 2)`` and confidence ``(S, h, w)`` of the :func:`downscale` d video
    ``small``, in its pixels: flow between successive sub-frames, averaged over
    ``temporal_window`` by confidence. ``memo``: as :func:`run_pairs`."""
    S, h, w = small.shape
    u8 = to_uint8_planes(small)
    fwd = np.empty((S - 1, h, w, 2), np.float32)
    vconf = np.empty((S, h, w), np.float32)  # each pair writes its plane; the last sub-frame takes the last pair's
    conf = vconf[:-1]
    run_pairs(flow_fn, u8, list(zip(range(S - 1), range(1, S), strict=True)), fwd, conf, consistency=consistency,
              memo=memo)
    vconf[-1] = conf[-1]
    # Velocity at sub-frame s: confidence-weighted mean of forward flows s-w .. s+w (clamped to
    # the pairs; the last sub-frame takes the last pair's), a sub-frame at a time in one compiled
    # pass that weighs the flows as it reads them (fresh memory is dear: at 640x480 x 240 sub-frames
    # the whole-volume sums' temporaries cost 0.15-0.6 s). Each sum is made in the same order as over
    # whole volumes: from 0, offsets in increasing order (mean_kernel.pair_mean).
    P = S - 1
    vel = np.empty((S, h, w, 2), np.float32)
    reach = max(0, min(temporal_window, P - 1))

    def one(c: int) -> None:  # centres c read the pairs c + o that exist (compiled: one pass a sub-frame)
        pair_mean(fwd, conf, c, reach, vel[c])

    for_each(one, P)
    vel[P] = vel[P - 1]
    return vel, vconf


def to_full_size(vel: np.ndarray, conf: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Sanitise flow at its own (small) resolution — NaN/inf to 0 with confidence 0, magnitudes
    capped at half the image — then resize it to ``size``: the full-size arrays are large, so
    every step that can runs before the resize."""
    h, w = vel.shape[1:3]
    vel, conf = sanitize_flow(vel, conf, max_magnitude=0.5 * max(h, w))
    H, W = size
    if (h, w) != (H, W):
        vel = upsample_flow(vel, (H, W))
        if conf.min() == 1:  # the usual case without a round-trip check: a read-only view of 1
            return vel, np.broadcast_to(np.float32(1), (len(conf), H, W))
        small, conf = conf, np.empty((len(conf), H, W), np.float32)
        for i, c in enumerate(small):
            cv2.resize(c, (W, H), dst=conf[i], interpolation=cv2.INTER_LINEAR)
    return vel, conf


def estimate_flow(
    video,
    *,
    backend: str = "dis",
    scale: float = 0.5,
    consistency: bool = True,
    temporal_window: int = 1,
    **backend_params_,
) -> FlowField:
    """Optical flow between successive sub-frames of a (high-TR) video.

    Parameters
    ----------
    video : ndarray, shape (S, H, W)
        S ≥ 2 sub-frames (float, finite).
    backend : {"dis", "deepflow", "farneback", "tvl1"}
    scale : float
        Resolution at which flow is computed, in (0, 1].
    consistency : bool
        Compute backward flow for the forward–backward confidence (doubles the flow work).
    temporal_window : int
        Half-width w of the confidence-weighted temporal average (0: none).
    **backend_params_
        Named parameters of the backend (see :mod:`flexvox_core.flow.backends`).

    Returns
    -------
    FlowField
    """
    v = check_video(video)
    if not 0 < scale <= 1:
        raise ValueError(f"`scale` must be in (0, 1]; got {scale}")
    if isinstance(temporal_window, bool) or not isinstance(temporal_window, int) or temporal_window < 0:
        raise ValueError(f"`temporal_window` must be a whole number >= 0; got {temporal_window!r}")
    flow_fn = make_backend(backend, **backend_params_)
    t0 = time.perf_counter()
    vel, vconf = successive_flow(downscale(v, scale), flow_fn, consistency=consistency,
                                 temporal_window=temporal_window)
    vel, vconf = to_full_size(vel, vconf, v.shape[1:])
    S, H, W = v.shape
    seconds = time.perf_counter() - t0
    params = {**backend_params(flow_fn), "scale": scale, "consistency": consistency,
              "temporal_window": temporal_window}
    _logger.info("flow %s on %d sub-frames of %dx%d: %.2f s", backend, S, H, W, seconds)
    return FlowField(vel, vconf, params, seconds)
