r"""Dropped camera frames: where the gaps are, how far a method may bridge them, and the bridge.

A camera drops a frame now and then. The recording keeps its row, zero and flagged ``dropped``
(:mod:`flexvox_core.recording`), so frame f still holds sub-frames ``f·K .. f·K + K − 1``. Those
sub-frames have no samples. Every reconstruction treats them so:

1. **No sample is invented.** Methods that take a sampling mask (constant-tensor diffusion,
   motion-aware) leave the dropped frames out of it. The others (re-binning, GAP-TV) are given
   each dropped pixel as the straight line between the same pixel in the nearest captured frames
   on each side (:func:`fill_frames`; with an identity code a pixel samples the same slot in
   every frame), so that no zero row leaks into the frames beside the gap.
2. **The gap is filled from both sides** (:func:`bridge`). The gap's sub-frames are blended
   from the reconstructed sub-frames just before and just after it, in proportion to their
   distance in time. With a flow (motion-aware) each side is first moved along the flow,
   itself interpolated linearly across the gap, so a moving edge travels through the gap
   instead of fading out at one place and in at another. A gap at the start or end of a
   recording has one side: that side is held (moved along its flow, if any).
3. **Reach.** A method bridges a gap of at most :func:`max_gap` frames: twice the context it
   reads on each side of a chunk (its overlap), at least 2. A longer gap is refused
   (:class:`GapTooLongError`, naming it) before anything is computed.

Which sub-frames were interpolated travels with the result (:func:`interpolated_subframes`):
``flexvox reconstruct`` prints them and writes them as an array beside the video.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

_logger = logging.getLogger(__name__)


class GapTooLongError(ValueError):
    """A run of dropped frames longer than the method can bridge; the message names it."""


@dataclass(frozen=True)
class Gap:
    """Dropped camera frames ``[start, stop)``."""

    start: int
    stop: int

    @property
    def frames(self) -> int:
        """How many frames are missing."""
        return self.stop - self.start

    def describe(self, K: int | None = None) -> str:
        """E.g. "frames 12-16 (5 frames; sub-frames 192-271)"."""
        n = self.frames
        text = f"frame {self.start}" if n == 1 else f"frames {self.start}-{self.stop - 1}"
        text += f" ({n} frame{'s' if n != 1 else ''}"
        if K:
            text += f"; sub-frames {self.start * K}-{self.stop * K - 1}"
        return text + ")"


def _indices_hint(m: np.ndarray, n_frames: int) -> str:
    """How to give integers that look like dropped frames' indices as flags ("" where they cannot be)."""
    indices = sorted({int(i) for i in m})
    if not (0 <= indices[0] and indices[-1] < n_frames and len(indices) <= 8):
        return ""
    return f": for dropped frames' indices {indices} give np.isin(np.arange({n_frames}), {indices})"


def as_missing(missing, n_frames: int) -> np.ndarray | None:
    """``missing`` as a bool array of ``n_frames``, or None when no frame is missing.

    Raises
    ------
    ValueError
        A shape other than (n_frames,), integers other than 0 and 1 (frame indices are not flags), or every
        frame missing.
    """
    if missing is None:
        return None
    m = np.asarray(missing)
    integers = m.ndim == 1 and m.size and np.issubdtype(m.dtype, np.integer)
    if m.shape != (n_frames,) or not (m.dtype == bool or np.issubdtype(m.dtype, np.integer)):
        raise ValueError(f"`missing` must be {n_frames} booleans, one per camera frame; got {m.dtype} {m.shape}"
                         + (_indices_hint(m, n_frames) if integers else ""))
    if m.dtype != bool and not np.isin(m, (0, 1)).all():
        indices = sorted({int(i) for i in m})
        raise ValueError(f"`missing` must be {n_frames} booleans (or 0/1), one per camera frame; got the values "
                         f"{indices[0]} to {indices[-1]}{_indices_hint(m, n_frames)}")
    m = m.astype(bool)
    if not m.any():
        return None
    if m.all():
        raise ValueError(f"all {n_frames} camera frames are missing (dropped): there is nothing to reconstruct")
    return m


def captured(frames: np.ndarray, missing) -> np.ndarray:
    """The rows of ``frames`` that were captured (all of them when ``missing`` is None): what a sample
    range, a clip or a mean is taken over, never a dropped frame's zero row."""
    return frames if missing is None else frames[~np.asarray(missing, bool)]


def find_gaps(missing) -> list[Gap]:
    """The runs of consecutive missing frames, in order."""
    m = np.asarray(missing, bool)
    if not m.any():
        return []
    edges = np.diff(np.concatenate([[0], m.view(np.int8), [0]]))
    return [Gap(int(a), int(b)) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True)]


def max_gap(overlap: int | None) -> int:
    """The longest gap (frames) a method with this chunk ``overlap`` bridges: 2·overlap, at least 2."""
    return max(2, 2 * (overlap or 0))


def context(overlap: int | None, missing) -> int | None:
    """Frames of context a chunk reads on each side: ``overlap``, plus the longest gap and one
    frame when frames are missing (the gap's far side and that frame's own context lie beyond it)."""
    if overlap is None:
        return None
    gaps = find_gaps(missing) if missing is not None else []
    return overlap + (max(g.frames for g in gaps) + 1 if gaps else 0)


def check_reach(missing, reach: int, what: str, K: int | None = None, advice: str = "") -> None:
    """Refuse the first gap longer than ``reach`` frames (:class:`GapTooLongError` naming it and
    ending with ``advice``)."""
    for g in find_gaps(missing) if missing is not None else []:
        if g.frames > reach:
            raise GapTooLongError(f"{g.describe(K)} were dropped in a row; {what} bridges gaps of at most {reach} "
                                  f"frame(s){'. ' + advice if advice else ''}")


def interpolated_subframes(missing, K: int) -> np.ndarray:
    """Bool ``(F·K,)``: True for the sub-frames of missing frames (filled by :func:`bridge`)."""
    return np.repeat(np.asarray(missing, bool), K)


def fill_frames(frames: np.ndarray, missing) -> np.ndarray:
    """A copy of ``frames`` whose missing frames are, pixel by pixel, the straight line between the
    nearest captured frames on each side (held beyond the first and last captured frame)."""
    f = np.array(frames, dtype=np.float32)
    m = np.asarray(missing, bool)
    present = np.flatnonzero(~m)
    for g in find_gaps(m):
        before = present[present < g.start]
        after = present[present >= g.stop]
        a = int(before[-1]) if len(before) else None
        b = int(after[0]) if len(after) else None
        for i in range(g.start, g.stop):
            if a is None or b is None:
                f[i] = f[a if b is None else b]
            else:
                w = (i - a) / (b - a)
                f[i] = (1 - w) * f[a] + w * f[b]
    return f


def bridge_flow(flow: np.ndarray, missing, K: int, margin: int) -> None:
    """Replace, in place, the flow ``(S, H, W, 2)`` of each gap's sub-frames and of ``margin``
    sub-frames on each side of it (measured on frames that were interpolated, or across them)
    by the straight line between the flows just outside that span (held at the video's ends).

    ``flow`` may be held at its own scale (``(S, h, w, 2)``, :class:`~flexvox_core.flow.estimate.ScaledFlow`'s
    ``small``): the line in time commutes with the resize (both linear), so its full-size planes are those of
    the full-size flow bridged, to float32 rounding."""
    S = flow.shape[0]
    for g in find_gaps(missing):
        a, b = g.start * K - 1 - margin, g.stop * K + margin
        lo, hi = max(a, -1), min(b, S)
        for t in range(lo + 1, hi):
            if a < 0 and b >= S:
                flow[t] = 0
            elif a < 0 or b >= S:
                flow[t] = flow[b if a < 0 else a]
            else:
                w = np.float32((t - a) / (b - a))
                flow[t] = (1 - w) * flow[a] + w * flow[b]


def _plane(flow: Any, t: int) -> np.ndarray:
    """Sub-frame ``t`` of ``flow``: an array's plane, or a band's (``motion`` is not imported here: it imports this)."""
    plane: np.ndarray = flow[t] if isinstance(flow, np.ndarray) else flow.band(t, t + 1)[0]
    return plane


def bridge(video: np.ndarray, missing, K: int, flow: Any = None) -> np.ndarray:
    """Fill the sub-frames of the missing frames of ``video`` (S, H, W) from both sides, in place.

    Sub-frame t of a gap between the reconstructed sub-frames a (just before it) and b (just
    after) becomes ``(1 − w)·A + w·B`` with ``w = (t − a) / (b − a)``. Without ``flow``, A and B
    are sub-frames a and b. With ``flow`` (S, H, W, 2) in pixels per sub-frame, the velocity at t
    is the same blend of the flows at a and b, A is sub-frame a read at x − (t − a)·velocity and
    B sub-frame b at x + (b − t)·velocity; the gap's flow is set to that velocity. At the start
    or end of the video the one side is held. Returns :func:`interpolated_subframes`.

    ``flow`` may also be a volume read a band at a time (``band(t0, t1)``, as
    :func:`flexvox_core.planes.band` reads it) with a ``put(t, plane)`` that sets a sub-frame's velocity
    (:class:`~flexvox_core.flow.estimate.FlowField`, :class:`~flexvox_core.flow.estimate.ScaledFlow`).
    """
    m = np.asarray(missing)
    if m.ndim != 1 or not (m.dtype == bool or np.issubdtype(m.dtype, np.integer)):
        raise ValueError(f"`missing` must be booleans, one per camera frame; got {m.dtype} {m.shape}")
    m = m.astype(bool)
    S = video.shape[0]
    if S != len(m) * K:
        raise ValueError(f"`video` has {S} sub-frames; {len(m)} frames at K = {K} make {len(m) * K}")
    if flow is not None and tuple(flow.shape[:1]) != (S,):
        raise ValueError(f"`flow` must have the video's {S} sub-frames; got shape {tuple(flow.shape)}")
    H, W = video.shape[1:]
    gx, gy = (np.meshgrid(np.arange(W, dtype=np.float32), np.arange(H, dtype=np.float32)) if flow is not None
              else (None, None))
    for g in find_gaps(m):
        a, b = g.start * K - 1, g.stop * K
        a = a if a >= 0 else None
        b = b if b < S else None
        if a is None and b is None:
            raise ValueError("every frame is missing: there is no side to bridge from")
        for t in range(g.start * K, g.stop * K):
            w = 0.0 if b is None else 1.0 if a is None else (t - a) / (b - a)
            if flow is None:
                video[t] = (1 - w) * (video[a] if a is not None else 0) + w * (video[b] if b is not None else 0)
                continue
            vel = (1 - w) * (_plane(flow, a) if a is not None else 0) + w * (_plane(flow, b) if b is not None else 0)
            vel = np.asarray(vel, np.float32)
            out = np.zeros((H, W), np.float32)
            for side, weight, steps in ((a, 1 - w, None if a is None else t - a),
                                        (b, w, None if b is None else t - b)):
                if side is None or weight == 0:
                    continue
                # Sub-frame `side` read where the voxel was (steps < 0: will be) at that time.
                moved = cv2.remap(video[side], gx - steps * vel[..., 0], gy - steps * vel[..., 1],
                                  cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
                out += np.float32(weight) * moved
            video[t] = out
            if isinstance(flow, np.ndarray):
                flow[t] = vel
            else:
                flow.put(t, vel)
    gaps = find_gaps(m)
    if gaps:
        _logger.info("bridged %s", ", ".join(g.describe(K) for g in gaps))
    return interpolated_subframes(m, K)
