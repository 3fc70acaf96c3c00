"""Methods run once on a small capture before they are timed: the one-time costs (numba's compile or the load of
its cache, lazy imports, the GPU's module load) are then charged to no row of a benchmark."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

_logger = logging.getLogger(__name__)

WARM_UP_SIZE = (32, 48)
"""The small capture's frame size (H, W), rounded down to whole tiles (at least one)."""

WARM_UP_FRAMES = 3
"""Its camera frames: enough for every method's windows (motion-aware's flow takes two frames or more)."""


def warm_up(code: npt.ArrayLike, methods: Iterable[Any], *, device: str = "cpu", dtype: npt.DTypeLike = np.float32,
            estimates: bool = False) -> float:
    """Run each of ``methods`` (:class:`~flexvox_core.methods.Method`) once on a small random capture through the
    identity ``code`` (m, n, K), :data:`WARM_UP_FRAMES` frames of :data:`WARM_UP_SIZE` in ``dtype``, on
    ``device``, and with ``estimates`` the accuracy estimate of each that it does not refuse by name
    (:func:`~flexvox_core.accuracy.refusal`); returns the seconds spent. A method that refuses the small capture
    (a ``ValueError``, :class:`~flexvox_core.accuracy.NotEstimable` among them) is passed over: its timed run says
    why in its own words.

    A benchmark calls it before its timed runs: without it, the first run of a method family pays numba's compile
    or cache load (the first ``nc`` row took 0.27 s against 0.002 s for the next scene's, docs/benchmarks.md).
    """
    from flexvox_core.forward import capture
    from flexvox_core.methods.runner import run

    code = np.asarray(code, bool)
    m, n, K = code.shape
    H, W = (max(t, s // t * t) for s, t in zip(WARM_UP_SIZE, (m, n), strict=True))
    video = np.random.default_rng(0).random((WARM_UP_FRAMES * K, H, W)).astype(np.float32)
    frames = capture(video, code).astype(dtype)
    t0 = time.perf_counter()
    from flexvox_core.accuracy import estimate_accuracy, refusal

    for method in methods:
        try:
            run(frames, code, method, chunk_frames=None, device=device)
            if estimates and refusal(method) is None:
                estimate_accuracy(frames, code, method, device=device)
        except ValueError as exc:
            _logger.debug("warm-up: %s refused the small capture (%s)", method, exc)
    seconds = time.perf_counter() - t0
    _logger.info("warm-up: %.2f s", seconds)
    return seconds
