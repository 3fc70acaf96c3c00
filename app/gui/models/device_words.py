"""Where a reconstruction ran, in the window's words (Qt-free): the CPU, or the GPU by its name.

Every result the window shows says it (Review's result line and Compare list, the live preview's line), as the
command line prints ``device: …``. Where a GPU is there but was not used, the words say why: the method or its
values have no GPU path (the runner's ``device_note``), numba-cuda is not installed beside an NVIDIA driver,
the driver cannot be used. numba-cuda's simulator is named as such, never as a GPU. The facts come from
:mod:`flexvox_core.gpu.device` (``cuda_status``, ``describe_gpus``, ``driver_library``), asked once per process.
"""

from __future__ import annotations

import functools


@functools.cache
def gpu_status() -> tuple[bool, str, bool]:
    """(usable, reason, driver present) of :func:`flexvox_core.gpu.device.cuda_status`, asked once."""
    from flexvox_core.gpu.device import cuda_status, driver_library

    ok, reason = cuda_status()
    return ok, reason, driver_library() is not None


@functools.cache
def gpu_name() -> str | None:
    """The first GPU's name as the driver gives it (None: no GPU the driver lists, or the simulator)."""
    from flexvox_core.gpu.device import describe_gpus

    try:
        gpus = describe_gpus()
    except Exception:  # noqa: BLE001 - a driver failing to describe its card must not break a result's line
        return None
    return gpus[0].name if gpus else None


def where_it_ran(device: str, note: str | None = None) -> str:
    """"on the CPU", "on the GPU (NVIDIA H200)", "on numba-cuda's simulator (no GPU)", with why not on the GPU
    when one is there (``note``: the runner's ``device_note``).

    >>> where_it_ran("cpu", "gap-tv has no GPU path")
    'on the CPU (gap-tv has no GPU path)'
    """
    from flexvox_core.gpu.device import simulator

    if device == "cuda":
        if simulator():
            return "on numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1: no GPU, slower than the CPU)"
        name = gpu_name()
        return f"on the GPU ({name})" if name else "on the GPU"
    if note:
        return f"on the CPU ({note})"
    usable, reason, driver = gpu_status()
    if usable and not simulator():
        return "on the CPU (the GPU was not asked for)"
    if driver and not usable:  # an NVIDIA driver is here: there is a card flexvox does not use
        return f"on the CPU (a GPU is here but unused: {reason})"
    return "on the CPU"


def short_where(device: str) -> str:
    """Where it ran, without the reasons: "on the CPU", "on the GPU (its name)", "on numba-cuda's simulator"."""
    from flexvox_core.gpu.device import simulator

    if device == "cuda":
        return "on numba-cuda's simulator" if simulator() else where_it_ran(device)
    return "on the CPU"
