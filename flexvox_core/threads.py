"""Independent per-item work (one sub-frame, one frame pair) spread over the cores."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import cv2

MAX_WORKERS = 16
"""The most threads per-item work takes."""


def cores() -> int:
    """The cores this process may run on (its CPU affinity: ``taskset`` or a container's share), not the
    machine's count."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # no affinity on this platform
        return max(1, os.cpu_count() or 1)


def workers() -> int:
    """Threads for per-item work: this process's cores, at most :data:`MAX_WORKERS`."""
    return min(cores(), MAX_WORKERS)


def for_each(fn: Callable[[int], None], count: int) -> None:
    """Call ``fn(i)`` for i in range(count) on :func:`workers` threads (each call writes its own output).

    OpenCV releases the GIL and runs most element-wise operations on one thread, so sub-frames run
    side by side. OpenCV's own thread pool is switched off meanwhile (``cv2.setNumThreads(1)``,
    restored after): its idle workers wait for work by spinning, which beside these threads costs
    time in system calls (the figures: docs/benchmarks.md, "Figures behind the code"). An exception
    in any call is raised here.
    """
    n = workers()
    if n == 1 or count < 2:
        for i in range(count):
            fn(i)
        return
    saved = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with ThreadPoolExecutor(max_workers=n) as pool:
            list(pool.map(fn, range(count)))  # consumes the results, so an exception is raised here
    finally:
        cv2.setNumThreads(saved)
