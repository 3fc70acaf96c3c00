"""Start-up hook for a dry run of ``bench/gpu_check.sh`` (``GPU_CHECK_SMALL=1``), loaded by every Python process
of it because the script puts this folder first on ``PYTHONPATH``. It does nothing unless told:

- ``GPU_CHECK_ABSENT=zarr,dask,...``: importing one of these top-level packages (or anything under it) raises
  ``ModuleNotFoundError``, as it would on the GPU machine's image, which lacks them, even where this machine's
  Python has them.
- ``GPU_CHECK_COUNTS=DIR``: counts numba-cuda simulator launches (through ``flexvox_core.gpu.cudasim.run``,
  which every launch under the simulator goes through), their threads, the bytes of the arrays each is passed
  (a launch reads or writes each of its arrays about once: the traffic a card would move), and the bytes copied
  between host and device; writes ``DIR/<GPU_CHECK_STAGE>-<pid>.json`` at exit. ``bench/gpu_dry_counts.py``
  sums them per stage into the card-time estimate.
"""

from __future__ import annotations

import atexit
import importlib.abc
import json
import os
import sys

ABSENT = frozenset(n for n in os.environ.get("GPU_CHECK_ABSENT", "").split(",") if n)
COUNTS = {"launches": 0, "threads": 0, "kernel_bytes": 0, "h2d_bytes": 0, "d2h_bytes": 0}


class _Absent(importlib.abc.MetaPathFinder):
    """Refuses the packages the card's image lacks."""

    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in ABSENT:
            raise ModuleNotFoundError(f"No module named {name!r} (absent from the GPU machine's image)", name=name)
        return None


def _nbytes(value) -> int:
    return int(getattr(value, "nbytes", 0)) if hasattr(value, "shape") else 0


def _count_run(module) -> None:
    real = module.run

    def run(dispatcher, grid, block, args):
        COUNTS["launches"] += 1
        COUNTS["threads"] += grid * block
        COUNTS["kernel_bytes"] += sum(_nbytes(a) for a in args)
        return real(dispatcher, grid, block, args)

    module.run = run


def _count_transfers(cuda) -> None:
    from numba.cuda.simulator.cudadrv.devicearray import FakeCUDAArray

    to_device, copy_to_host = cuda.to_device, FakeCUDAArray.copy_to_host
    copy_to_device = FakeCUDAArray.copy_to_device

    def counted_to_device(ary, *args, **kwargs):
        COUNTS["h2d_bytes"] += _nbytes(ary)
        return to_device(ary, *args, **kwargs)

    def counted_copy_to_host(self, *args, **kwargs):
        COUNTS["d2h_bytes"] += _nbytes(self)
        return copy_to_host(self, *args, **kwargs)

    def counted_copy_to_device(self, ary, *args, **kwargs):
        if not isinstance(ary, FakeCUDAArray):
            COUNTS["h2d_bytes"] += _nbytes(ary)
        return copy_to_device(self, ary, *args, **kwargs)

    cuda.to_device = counted_to_device
    FakeCUDAArray.copy_to_device = counted_copy_to_device
    FakeCUDAArray.copy_to_host = counted_copy_to_host


_AFTER_IMPORT = {"flexvox_core.gpu.cudasim": _count_run, "numba.cuda": _count_transfers}


class _Patch(importlib.abc.MetaPathFinder):
    """Patches a module of ``_AFTER_IMPORT`` right after it is first executed."""

    def find_spec(self, name, path=None, target=None):
        if name not in _AFTER_IMPORT:
            return None
        for finder in sys.meta_path:
            if finder is self or isinstance(finder, _Absent):
                continue
            spec = finder.find_spec(name, path, target) if hasattr(finder, "find_spec") else None
            if spec is not None and spec.loader is not None:
                exec_module = spec.loader.exec_module

                def patched(module, exec_module=exec_module, name=name):
                    exec_module(module)
                    _AFTER_IMPORT[name](module)

                spec.loader.exec_module = patched
                return spec
        return None


def _write() -> None:
    folder = os.environ["GPU_CHECK_COUNTS"]
    stage = os.environ.get("GPU_CHECK_STAGE", "unnamed")
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, f"{stage}-{os.getpid()}.json")
    with open(path + ".part", "w") as f:
        json.dump({"stage": stage, "argv": sys.argv, **COUNTS}, f)
    os.replace(path + ".part", path)


if ABSENT:
    sys.meta_path.insert(0, _Absent())
if os.environ.get("GPU_CHECK_COUNTS"):
    sys.meta_path.insert(0, _Patch())
    atexit.register(_write)
