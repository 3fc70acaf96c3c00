"""A quiet exit for processes that used zarr: its I/O thread is stopped, and waited for, before zarr's own exit hook.

zarr 3 runs its asynchronous I/O on an event loop in a daemon thread. At exit its ``atexit`` hook asks that loop to
stop, waits 0.2 s for the thread, then closes the loop. On a loaded machine the thread may not run within 0.2 s: the
close then fails on the still-running loop, and after a command has finished Python prints "Exception ignored in
atexit callback" with a traceback (and zarr a warning) on stderr.

Importing this module (the modules of flexvox_core that use zarr do) registers :func:`stop_zarr_io` with ``atexit``.
It is registered after zarr's hook, so it runs before it (``atexit`` runs the last registered first): it does what
zarr's hook does, waiting up to :data:`WAIT_S` for the thread instead of 0.2 s, and leaves zarr's hook nothing to do.
"""

from __future__ import annotations

import atexit
import logging

from zarr.core import sync as _sync

_logger = logging.getLogger(__name__)

WAIT_S = 30.0
"""Seconds to wait at exit for zarr's I/O thread to stop."""


def stop_zarr_io(wait_s: float = WAIT_S) -> bool:
    """Stop zarr's I/O event loop and its thread, as zarr's exit hook does but waiting up to ``wait_s`` seconds.

    True when it stopped (or never ran); False when the thread still runs after ``wait_s`` (zarr's own hook is then
    left to deal with it). Only for the end of a process: zarr starts a new loop if it is used afterwards.
    """
    executor = _sync._executor
    if executor is not None:
        executor.shutdown(wait=True, cancel_futures=True)
        _sync._executor = None
    loop, thread = _sync.loop[0], _sync.iothread[0]
    if loop is None:
        return True
    with _sync._get_lock():
        if not loop.is_closed():
            loop.call_soon_threadsafe(loop.stop)
        if thread is not None:
            thread.join(wait_s)
            if thread.is_alive():
                _logger.warning("zarr's I/O thread did not stop within %g s at exit", wait_s)
                return False
        if not loop.is_closed():
            loop.close()
        _sync.loop[0] = None
        _sync.iothread[0] = None
    return True


atexit.register(stop_zarr_io)
