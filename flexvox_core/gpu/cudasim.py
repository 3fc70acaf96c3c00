"""Kernels under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM``), one simulated thread after another where a kernel
allows it. (The simulated *rig* is another thing: :mod:`flexvox_core.simulate` and ``rig_drivers/simulated_rig.py``.)

The simulator runs every thread of a block as a Python thread, so that ``cuda.syncthreads()`` can hold them at a
barrier; starting those threads and switching between them costs most of a simulated launch (a tiny window's whole
GPU run, ``bench/bench_simulator.py``: 48.4 s on the simulator's threads, 11.4 s in turn, on 2 quiet cores). A
kernel that never synchronises its block (no ``syncthreads``, no shared memory, in its own code or in a device
function it calls) gives the same result whatever order its threads run in, so :func:`sequential_blocks` runs each
block's threads in turn on the launching thread: the same kernel code, the same simulated arrays, the same
``cuda.grid`` and atomics, without the Python threads. :func:`needs_threads` tells the two kinds apart by reading
each function's code; :func:`run`, which :func:`flexvox_core.gpu.launch.launch` calls, launches each kind its way,
one launch at a time across threads.

This leans on the simulator's own classes (``BlockManager``, ``Dim3``, ``swapped_cuda_module``), which are not
numba-cuda's public API; ``tests/flexvox_core/gpu/test_cudasim.py`` fails when they change, and
``FLEXVOX_SIM_THREADS=1`` runs every kernel on the simulator's threads as it ships.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from functools import cache
from types import FunctionType
from typing import Any

import numpy as np

BLOCK_SYNC_NAMES = frozenset({"syncthreads", "syncthreads_count", "syncthreads_and", "syncthreads_or", "syncwarp",
                              "shared", "shfl_sync", "shfl_up_sync", "shfl_down_sync", "shfl_xor_sync", "all_sync",
                              "any_sync", "eq_sync", "ballot_sync", "match_any_sync", "match_all_sync"})
"""The ``cuda.`` attributes that tie a block's (or a warp's) threads together: a kernel, or a device function it
calls, that names any of them runs on the simulator's threads. A kernel misjudged fails loudly rather than wrongly:
run in turn, its barrier finds no simulated thread to wait on (AttributeError)."""


_THREAD_ATTRS = ("blockIdx", "threadIdx", "thread_id")
"""What the simulator reads from ``threading.current_thread()`` for a simulated thread's index."""


def _callees(fn: FunctionType) -> list[FunctionType]:
    """The device functions ``fn``'s code names (its module's globals that wrap a Python function)."""
    found = []
    for name in fn.__code__.co_names:
        value = fn.__globals__.get(name)
        inner = getattr(value, "py_func", None)
        if inner is not None and hasattr(inner, "__code__") and inner is not fn:
            found.append(inner)
    return found


def _reachable(fn: FunctionType) -> list[FunctionType]:
    """``fn`` and every device function it calls, directly or not (each once)."""
    seen: set[int] = set()
    todo, out = [fn], []
    while todo:
        f = todo.pop()
        if id(f) in seen:
            continue
        seen.add(id(f))
        out.append(f)
        todo.extend(_callees(f))
    return out


@cache
def needs_threads(fn: FunctionType) -> bool:
    """Whether kernel ``fn`` (its Python function) synchronises its block, itself or through a device function
    it calls: it names one of :data:`BLOCK_SYNC_NAMES`. True for every kernel with ``FLEXVOX_SIM_THREADS=1``."""
    if os.environ.get("FLEXVOX_SIM_THREADS", "0") not in ("", "0"):
        return True
    return any(BLOCK_SYNC_NAMES & set(f.__code__.co_names) for f in _reachable(fn))


@cache
def _module_representatives(fn: FunctionType) -> tuple[FunctionType, ...]:
    """One function per module whose globals ``fn`` and its device functions run in."""
    by_module: dict[int, FunctionType] = {}
    for f in _reachable(fn):
        by_module.setdefault(id(f.__globals__), f)
    return tuple(by_module.values())


@cache
def _sequential_manager() -> tuple[Any, type, type]:
    """(numba's simulator kernel module, the sequential block manager, the simulator's own)."""
    from numba.cuda.simulator import kernel as simkernel_module
    from numba.cuda.simulator import kernelapi

    simkernel: Any = simkernel_module  # numba-cuda's simulator is untyped
    Dim3: Any = kernelapi.Dim3
    swapped_cuda_module: Any = kernelapi.swapped_cuda_module

    class SequentialBlock(simkernel.BlockManager):  # type: ignore[misc]
        """A block whose threads run one after another on the calling thread (see the module docstring)."""

        def run(self, grid_point: tuple[int, ...], *args: Any) -> None:
            me: Any = threading.current_thread()
            saved: dict[str, Any] = {a: me.__dict__[a] for a in _THREAD_ATTRS if a in me.__dict__}
            me.blockIdx = Dim3(*grid_point)
            bx, by, _ = self._block_dim
            context = simkernel._get_kernel_context()
            try:
                with ExitStack() as stack:
                    # The fake ``cuda`` swapped into every module once per block, and the device functions called
                    # as the plain functions they wrap, not through the simulator's wrapper at every call.
                    for f in _module_representatives(self._f):
                        stack.enter_context(swapped_cuda_module(f, context))
                        stack.enter_context(_plain_device_functions(f.__globals__))
                    for point in np.ndindex(*self._block_dim):
                        me.threadIdx = Dim3(*point)
                        me.thread_id = point[0] + bx * (point[1] + by * point[2])
                        self._f(*args)
            finally:
                for a in _THREAD_ATTRS:
                    me.__dict__.pop(a, None)
                me.__dict__.update(saved)

    return simkernel, SequentialBlock, simkernel.BlockManager


@contextmanager
def _plain_device_functions(module_globals: dict[str, Any]) -> Iterator[None]:
    """Within the block, each simulated device function in ``module_globals`` is the Python function it wraps."""
    wrapped = {name: v for name, v in module_globals.items()
               if getattr(v, "_device", False) and callable(getattr(v, "py_func", None))}
    module_globals.update({name: v.py_func for name, v in wrapped.items()})
    try:
        yield
    finally:
        module_globals.update(wrapped)


_LAUNCH_LOCK = threading.Lock()
"""Held for each simulated launch from :func:`run`: one thread's launch cannot see another's swap of numba's block
manager or undo it (the simulator runs one launch at a time anyway)."""


@contextmanager
def sequential_blocks() -> Iterator[None]:
    """Within the block, a simulated launch runs each block's threads in turn on the calling thread."""
    simkernel, manager, threaded = _sequential_manager()
    simkernel.BlockManager = manager
    try:
        yield
    finally:
        simkernel.BlockManager = threaded


def run(dispatcher: Any, grid: int, block: int, args: tuple[Any, ...]) -> None:
    """Launch ``dispatcher[grid, block](*args)`` under the simulator: in turn unless its kernel
    :func:`needs_threads`, one launch at a time across threads."""
    with _LAUNCH_LOCK:
        if needs_threads(dispatcher.py_func):
            dispatcher[grid, block](*args)
            return
        with sequential_blocks():
            dispatcher[grid, block](*args)
