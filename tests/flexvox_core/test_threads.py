import cv2
import pytest

from flexvox_core.threads import for_each, workers


def test_every_item_runs_once_with_opencv_single_threaded_and_restored_after():
    before = cv2.getNumThreads()
    seen, inside = [], []

    def fn(i):
        seen.append(i)
        inside.append(cv2.getNumThreads())

    for_each(fn, 37)
    assert sorted(seen) == list(range(37))
    if workers() > 1:
        assert set(inside) == {1}
    assert cv2.getNumThreads() == before


def test_an_exception_in_one_item_is_raised_and_threads_restored():
    before = cv2.getNumThreads()

    def fn(i):
        if i == 5:
            raise ValueError("item 5 failed")

    with pytest.raises(ValueError, match="item 5 failed"):
        for_each(fn, 9)
    assert cv2.getNumThreads() == before


def test_workers_follow_the_process_affinity_not_the_machine(monkeypatch):
    import os

    from flexvox_core import threads

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert threads.cores() == 3 and workers() == 3
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(40)), raising=False)
    assert workers() == threads.MAX_WORKERS


def test_calls_inside_items_and_from_several_threads_all_finish(monkeypatch):
    import threading

    from flexvox_core import threads

    monkeypatch.setattr(threads, "workers", lambda: 4)
    hits = [0] * (3 * 5 * 7)
    lock = threading.Lock()

    def leaf(i, j, k):
        with lock:
            hits[(i * 5 + j) * 7 + k] += 1

    def outer(i):
        for_each(lambda j: for_each(lambda k: leaf(i, j, k), 7), 5)

    callers = [threading.Thread(target=for_each, args=(outer, 3)) for _ in range(2)]
    for t in callers:
        t.start()
    for t in callers:
        t.join(timeout=60)
    assert not any(t.is_alive() for t in callers)
    assert hits == [2] * len(hits)  # each caller ran every item once


def test_the_pool_is_kept_from_call_to_call(monkeypatch):
    import threading

    from flexvox_core import threads

    monkeypatch.setattr(threads, "workers", lambda: 2)
    names = set()

    def fn(i):
        names.add(threading.current_thread().name)

    for _ in range(20):
        for_each(fn, 8)
    helpers = {n for n in names if n.startswith(threads.POOL_THREAD_PREFIX)}
    assert names <= helpers | {threading.current_thread().name}  # the caller and the kept pool, nothing else
    assert len(helpers) <= threads.MAX_WORKERS  # no new threads per call (a pool per call: up to 20 names)
