"""Flow of image pairs already computed, found again by the images' content.

A streaming reconstruction (:mod:`flexvox_core.motion.streaming`) runs the motion-aware pipeline
over a sliding window of camera frames, so it meets most pairs of sub-frames in several windows.
Flow is the costliest step per pair, and the backends are deterministic: the same two 8-bit
images give the same flow. :class:`FlowMemo` keeps the flow of the newest pairs keyed by a digest
of both images, the backend and its parameters, so a pair is computed once however many windows
hold it. The key is the content, not a position: a sub-frame near a window's edge, whose value
depends on the frames the window holds, simply misses and is computed afresh, so a memo never
changes a result.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict

import numpy as np


class FlowMemo:
    """The flow of up to ``max_pairs`` pairs, the least recently used forgotten first (thread-safe).

    Attributes
    ----------
    hits, misses : int
        Lookups that found a pair, and that did not.
    """

    def __init__(self, max_pairs: int = 512):
        if isinstance(max_pairs, bool) or not isinstance(max_pairs, int) or max_pairs < 1:
            raise ValueError(f"`max_pairs` must be a whole number >= 1; got {max_pairs!r}")
        self.max_pairs = max_pairs
        self._pairs: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    @staticmethod
    def key(backend: str, a: np.ndarray, b: np.ndarray, consistency: bool) -> bytes:
        """The key of the flow ``a → b`` by ``backend`` (its name and parameters, as text)."""
        h = hashlib.blake2b(digest_size=20)
        h.update(f"{backend}|{bool(consistency)}|{a.shape}|{a.dtype}|".encode())
        h.update(np.ascontiguousarray(a).data)
        h.update(b"|")
        h.update(np.ascontiguousarray(b).data)
        return h.digest()

    def get(self, key: bytes) -> tuple[np.ndarray, np.ndarray] | None:
        """The (flow, confidence) stored under ``key`` (read-only arrays), or None."""
        with self._lock:
            found = self._pairs.get(key)
            if found is None:
                self.misses += 1
                return None
            self._pairs.move_to_end(key)
            self.hits += 1
            return found

    def put(self, key: bytes, flow: np.ndarray, confidence: np.ndarray) -> None:
        """Store copies of ``flow`` and ``confidence`` under ``key``."""
        flow, confidence = np.array(flow, np.float32), np.array(confidence, np.float32)
        flow.flags.writeable = confidence.flags.writeable = False
        with self._lock:
            self._pairs[key] = (flow, confidence)
            self._pairs.move_to_end(key)
            while len(self._pairs) > self.max_pairs:
                self._pairs.popitem(last=False)

    def __len__(self) -> int:
        return len(self._pairs)

    def clear(self) -> None:
        """Forget every pair (the counters too)."""
        with self._lock:
            self._pairs.clear()
            self.hits = self.misses = 0
