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
