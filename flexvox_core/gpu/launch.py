"""How flexvox's CUDA kernels are declared, launched and compiled without a GPU.

A kernel is a plain Python function decorated with :func:`kernel`, which names the argument types it is
launched with (numba signature strings). On a GPU it compiles on its first launch; under numba-cuda's
simulator it runs as Python, and :func:`launch` checks every argument against the declared types, so the
tests prove that the declared types are the ones the pipeline passes; a kernel that never synchronises its block
runs its simulated threads one after another (:mod:`flexvox_core.gpu.cudasim`). :func:`compile_all` compiles every
declared signature to PTX for a chosen compute capability with no GPU present (numba-cuda's deviceless
compile; it needs NVVM, which the ``gpu`` and ``test`` extras install).

Kernels take 1-D grids over flat indices (:func:`launch` with a count of threads): the volumes are small
enough that one thread per voxel (or per pixel of a plane) keeps every kernel simple, and contiguous threads
read contiguous memory.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

BLOCK = 256
"""Threads per block of every 1-D launch."""
SIM_BLOCK = 32
"""Threads per block under the simulator (a kernel that synchronises its block runs each simulated thread as a
Python thread: fewer per block is faster; the others run their threads in turn, :mod:`flexvox_core.gpu.cudasim`)."""

KERNEL_PACKAGES = ("flexvox_core.gpu",)
"""The packages whose modules declare this package's kernels (motion-aware's own: :mod:`flexvox_core.motion.gpu`,
whose ``KERNEL_PACKAGES`` adds itself)."""


def modules_of(packages) -> tuple[str, ...]:
    """Every module of ``packages`` (names), found with :mod:`pkgutil`: importing them registers every kernel
    they declare (:data:`REGISTRY`)."""
    import pkgutil

    found = []
    for name in packages:
        package = importlib.import_module(name)
        found += [f"{name}.{m.name}" for m in pkgutil.iter_modules(package.__path__) if not m.ispkg]
    return tuple(sorted(found))


@dataclass(frozen=True)
class Kernel:
    """A declared kernel: its Python function, its compiled dispatcher and the signatures it is launched with."""

    name: str
    py_func: object
    dispatcher: object
    signatures: tuple[str, ...]


REGISTRY: dict[str, Kernel] = {}


def cuda():
    """numba's ``cuda`` module (numba-cuda), imported when first needed. Its warning about launches too small
    to fill the card is off: flexvox launches small grids on purpose (a frame's few numbers, a tiny window)."""
    from numba import config
    from numba import cuda as module

    config.CUDA_LOW_OCCUPANCY_WARNINGS = 0
    return module


def kernel(*signatures: str):
    """Declare a CUDA kernel launched with these numba signatures (``"void(float32[:, :, ::1], int32)"``)."""
    if not signatures:
        raise ValueError("a kernel declares at least one signature")

    def wrap(fn):
        dispatcher = cuda().jit(fn, cache=not _sim())
        name = f"{fn.__module__}.{fn.__name__}"
        REGISTRY[name] = Kernel(name, fn, dispatcher, tuple(signatures))
        dispatcher.flexvox_name = name
        return dispatcher

    return wrap


def device(fn):
    """Declare a device function (inlined into the kernels that call it)."""
    return cuda().jit(device=True, inline=True)(fn)


def _sim() -> bool:
    from flexvox_core.gpu.device import simulator

    return simulator()


def launch(dispatcher, count: int, *args) -> None:
    """Run ``dispatcher`` on ``count`` threads (1-D grid; threads past ``count`` return at once in the kernel)."""
    if count <= 0:
        return
    if not _sim():
        dispatcher[math.ceil(count / BLOCK), BLOCK](*args)
        return
    from flexvox_core.gpu import cudasim

    check_arguments(REGISTRY[dispatcher.flexvox_name], args)
    cudasim.run(dispatcher, math.ceil(count / SIM_BLOCK), SIM_BLOCK, args)


def _arg_type(value):
    """numba's type of an argument as the GPU would see it (device arrays under the simulator too)."""
    from numba import typeof, types

    if hasattr(value, "copy_to_host") and hasattr(value, "strides"):  # a (simulated) device array
        layout = "C" if value.is_c_contiguous() else ("F" if value.is_f_contiguous() else "A")
        return types.Array(typeof(np.empty(0, value.dtype)).dtype, value.ndim, layout)
    return typeof(value)


def check_arguments(k: Kernel, args) -> None:
    """Raise TypeError unless ``args`` match one of ``k``'s declared signatures (what a GPU would compile)."""
    from numba.core import sigutils

    got = tuple(_arg_type(a) for a in args)
    for sig in k.signatures:
        want, _ = sigutils.normalize_signature(sig)
        if len(want) == len(got) and all(_fits(w, g) for w, g in zip(want, got, strict=True)):
            return
    raise TypeError(f"kernel {k.name} launched with ({', '.join(map(str, got))}); declared: "
                    f"{'; '.join(k.signatures)}")


def _fits(want, got) -> bool:
    from numba import types

    if isinstance(want, types.Array):
        return (isinstance(got, types.Array) and got.dtype == want.dtype and got.ndim == want.ndim
                and (want.layout == "A" or got.layout == want.layout))
    if isinstance(want, types.Integer):
        return isinstance(got, types.Integer | types.Boolean)
    if isinstance(want, types.Float):
        return isinstance(got, types.Float | types.Integer)
    if isinstance(want, types.Boolean):
        return isinstance(got, types.Boolean)
    return want == got


class PtxStats(NamedTuple):
    """What :func:`compile_all` found in one kernel's PTX, summed over its signatures."""

    chars: int
    """Characters of PTX."""
    f64: int
    """Double-precision instructions (``.f64``): nonzero only where a kernel computes in float64 on purpose."""


def compile_all(packages=KERNEL_PACKAGES, cc: tuple[int, int] = (9, 0)) -> dict[str, PtxStats]:
    """Compile every declared signature of every kernel of the modules of ``packages`` (:func:`modules_of`) to PTX
    for compute capability ``cc`` without a GPU (numba-cuda's deviceless compile). Returns {kernel name:
    :class:`PtxStats`}; raises on the first failure."""
    import re

    modules = modules_of(packages)
    for module in modules:
        importlib.import_module(module)
    out = {}
    for name, k in sorted(REGISTRY.items()):
        if k.py_func.__module__ not in modules:
            continue
        chars = f64 = 0
        for sig in k.signatures:
            ptx, _ = cuda().compile_ptx(k.py_func, sig, cc=cc)
            chars += len(ptx)
            f64 += len(re.findall(r"\.f64\b", ptx))
        out[name] = PtxStats(chars, f64)
    return out
