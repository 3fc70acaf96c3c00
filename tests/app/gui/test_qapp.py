"""The application's QApplication: Python's garbage collected on the GUI thread only."""

import gc
import threading
import weakref

import pytest


class _Node:
    pass


def test_garbage_is_collected_by_the_gui_thread_s_timer_only(qapp, qtbot):
    from flexvox_app.gui.widgets.qapp import collect_garbage_on_gui_thread

    collector = collect_garbage_on_gui_thread()
    assert collector is collect_garbage_on_gui_thread()  # one per process
    assert not gc.isenabled() and collector.timer.isActive()
    node = _Node()
    node.me = node  # a cycle: only the cyclic collector frees it
    gone = weakref.ref(node)
    del node
    collector.threshold = (0, 0, 0)  # any count passes: the next tick collects every generation
    try:
        qtbot.waitUntil(lambda: gone() is None, timeout=5000)
    finally:
        collector.threshold = gc.get_threshold()


def test_the_collector_starts_on_the_gui_thread_only(qapp):
    from flexvox_app.gui.widgets.qapp import GuiThreadGarbageCollector

    raised = []

    def start():
        try:
            GuiThreadGarbageCollector()
        except RuntimeError as exc:
            raised.append(str(exc))

    worker = threading.Thread(target=start)
    worker.start()
    worker.join(10)
    assert raised == ["the garbage collector's timer must start on the GUI (main) thread"]


@pytest.mark.parametrize("counts, collected", [((5, 0, 0), []), ((800, 3, 0), [0]), ((800, 20, 0), [0, 1]),
                                              ((800, 20, 20), [0, 1, 2])])
def test_check_collects_the_generations_past_their_thresholds(qapp, monkeypatch, counts, collected):
    from flexvox_app.gui.widgets.qapp import collect_garbage_on_gui_thread

    collector = collect_garbage_on_gui_thread()
    seen = []
    monkeypatch.setattr(collector, "threshold", (700, 10, 10))
    monkeypatch.setattr(gc, "get_count", lambda: counts)
    monkeypatch.setattr(gc, "collect", lambda generation=2: seen.append(generation) or 0)
    collector.check()
    assert seen == collected


def test_automatic_collection_switched_back_on_is_switched_off_again(qapp, caplog):
    from flexvox_app.gui.widgets.qapp import collect_garbage_on_gui_thread

    collector = collect_garbage_on_gui_thread()
    gc.enable()  # as a library might, around its own work
    try:
        assert collect_garbage_on_gui_thread() is collector and not gc.isenabled()
        gc.enable()
        collector.check()  # the timer's tick
        assert not gc.isenabled()
    finally:
        gc.disable()
    assert "automatic garbage collection was switched back on; off again" in caplog.text


_DASK_SLICES = """
import gc, sys
import numpy as np
import dask.array as da  # imported while automatic collection is on, as a notebook would
from flexvox_app.gui.widgets.qapp import disarm_dask_slicing
gc.disable()
da.from_array(np.zeros((4, 4)), chunks=2)[1:3].compute()
before = gc.isenabled()
gc.disable()
was = disarm_dask_slicing()
da.from_array(np.zeros((4, 4)), chunks=2)[1:3].compute()
print(before, was, gc.isenabled(), disarm_dask_slicing())
"""


def test_dask_slicing_no_longer_switches_automatic_collection_back_on():
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _DASK_SLICES], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    # dask switched collection back on after a slice; disarmed, it no longer does (and a second disarm finds it off)
    assert out.stdout.split() == ["True", "True", "False", "False"]
