"""Independent per-item work (one sub-frame, one frame pair) spread over the cores."""

from __future__ import annotations

import itertools
import os
import threading
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


POOL_THREAD_PREFIX = "flexvox-for-each"
"""The names of :func:`for_each`'s kept threads begin so."""

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def _shared_pool() -> ThreadPoolExecutor:
    """The process's helper threads for :func:`for_each`, made on first use and kept (a pool made per call costs
    two thread starts and a future per item)."""
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=MAX_WORKERS, thread_name_prefix=POOL_THREAD_PREFIX)
        return _pool


def _forget_pool_in_child() -> None:
    """A forked child has none of its parent's threads: it makes its own pool when it needs one."""
    global _pool
    _pool = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_in_child)


def for_each(fn: Callable[[int], None], count: int) -> None:
    """Call ``fn(i)`` for i in range(count) on :func:`workers` threads (each call writes its own output).

    OpenCV releases the GIL and runs most element-wise operations on one thread, so sub-frames run
    side by side. OpenCV's own thread pool is switched off meanwhile (``cv2.setNumThreads(1)``,
    restored after): its idle workers wait for work by spinning, which beside these threads costs
    time in system calls (the figures: docs/benchmarks.md, "Figures behind the code").

    The calling thread and ``workers() - 1`` threads of a pool kept for the process each take the next item
    not yet taken until none is left, in increasing order (a future per item, as ``Executor.map`` makes them,
    cost 20-30 µs of the GIL each: docs/benchmarks.md). Once an item raises, no further item is started; the
    exception of the lowest item that raised is raised here, after every item started has ended. The caller
    never waits on a pool thread that has not started (its task is cancelled: every item was taken), so calls
    from several threads, or from inside ``fn``, cannot deadlock.
    """
    n = min(workers(), count)
    if n <= 1:
        for i in range(count):
            fn(i)
        return
    take = itertools.count().__next__  # atomic under the GIL: each item is taken once
    failed: list[tuple[int, BaseException]] = []

    def work() -> None:
        while not failed:
            i = take()
            if i >= count:
                return
            try:
                fn(i)
            except BaseException as exc:  # noqa: BLE001 - raised by the caller, below
                failed.append((i, exc))
                return

    saved = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        pool = _shared_pool()
        helpers = [pool.submit(work) for _ in range(n - 1)]
        work()
        for helper in helpers:
            if not helper.cancel():  # started: it ends once its item is done
                helper.result()
    finally:
        cv2.setNumThreads(saved)
    if failed:
        raise min(failed, key=lambda f: f[0])[1]
