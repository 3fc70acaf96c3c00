"""Which device runs a reconstruction: ``cpu``, ``cuda`` (an NVIDIA GPU through numba-cuda) or ``auto``.

``auto`` takes the GPU when one is usable (numba-cuda installed, a driver and a card it can talk to) and the
CPU otherwise. ``cuda`` asked for and not usable raises :class:`DeviceUnavailable` with one line naming what is
missing. numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) counts as a GPU only when ``cuda`` is asked for
by name (the tests run the GPU path on it); ``auto`` never picks it.
"""

from __future__ import annotations

import importlib.util
import itertools
import logging
import os
from dataclasses import dataclass
from importlib import metadata

_logger = logging.getLogger(__name__)

DEVICES = ("auto", "cpu", "cuda")
"""The values of every ``--device`` option."""

INSTALL_HINT = "pip install '.[gpu]' in a clone of flexvox"

NUMPY_LIMIT = (2, 5)
"""The first numpy release that numba-cuda up to :data:`NUMBA_CUDA_CHECKED` does not work with. pyproject.toml's
``gpu`` and ``test`` extras cap numpy below it (``numpy<2.5``); tests/test_dependencies.py checks the two agree."""

NUMBA_CUDA_CHECKED = (0, 30, 4)
"""The newest numba-cuda known to fail with numpy :data:`NUMPY_LIMIT` (its simulator warns that NumPy's 'generic'
timedelta unit is deprecated; on a card it fails). A newer numba-cuda is given the benefit of the doubt, and
tests/test_dependencies.py fails until someone checks it and lifts the cap or moves this version."""


class DeviceUnavailable(RuntimeError):
    """``device='cuda'`` was asked for and no usable GPU is there: ``reason`` says what is missing (the message
    is ``device='cuda': <reason>``; a front end words it its own way, the command line as ``--device cuda``)."""

    def __init__(self, reason: str):
        super().__init__(f"device='cuda': {reason}")
        self.reason = reason


@dataclass(frozen=True)
class GpuInfo:
    """One GPU as the driver describes it."""

    index: int
    name: str
    compute_capability: tuple[int, int]
    memory_total: int
    memory_free: int
    driver: str

    def line(self) -> str:
        cc = ".".join(map(str, self.compute_capability))
        return (f"GPU {self.index}: {self.name}, compute capability {cc}, {self.memory_total / 2**30:.1f} GiB "
                f"({self.memory_free / 2**30:.1f} free), driver {self.driver}")


def simulator() -> bool:
    """Whether numba-cuda's simulator stands in for the GPU in this process."""
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


def _version(text: str) -> tuple[int, ...]:
    """The leading numeric parts of a version string ("2.5.0rc1" -> (2, 5, 0))."""
    parts = []
    for part in text.split("."):
        digits = "".join(itertools.takewhile(str.isdigit, part))
        if not digits:
            break
        parts.append(int(digits))
        if digits != part:
            break
    return tuple(parts)


def stack_problem(numpy_version: str | None = None, numba_cuda_version: str | None = None) -> str | None:
    """Why the installed numba-cuda and numpy do not work together, in one line naming both versions and the fix;
    None when they do (or numba-cuda is not installed). The versions default to the installed ones (read from the
    packages' metadata, without importing numba-cuda)."""
    if numba_cuda_version is None:
        try:
            numba_cuda_version = metadata.version("numba-cuda")
        except metadata.PackageNotFoundError:
            return None
    if numpy_version is None:
        import numpy

        numpy_version = numpy.__version__
    if _version(numpy_version)[:2] >= NUMPY_LIMIT and _version(numba_cuda_version) <= NUMBA_CUDA_CHECKED:
        limit = ".".join(map(str, NUMPY_LIMIT))
        return (f"numba-cuda {numba_cuda_version} does not work with numpy {numpy_version} (numpy {limit} and newer); "
                f"pip install 'numpy<{limit}' (or pip install '.[gpu]' in a clone of flexvox, which caps it)")
    return None


def cuda_status() -> tuple[bool, str]:
    """(usable, reason): whether kernels can run on a GPU here, and if not, the one thing that is missing.
    With the simulator on, (True, "numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1)"). A numba-cuda that does not
    work with the installed numpy (:func:`stack_problem`) counts as unusable, simulator or not."""
    if importlib.util.find_spec("numba_cuda") is None:
        return False, f"numba-cuda is not installed ({INSTALL_HINT})"
    problem = stack_problem()
    if problem is not None:
        return False, problem
    if simulator():
        return True, "numba-cuda's simulator (NUMBA_ENABLE_CUDASIM=1)"
    if not driver_library():  # without the driver, numba's CUDA module (half a second to import) can do nothing
        return False, "no NVIDIA driver found (libcuda)"
    try:
        from numba import cuda

        if not cuda.is_available():
            return False, "no NVIDIA driver or GPU found (numba-cuda: CUDA is not available)"
        cuda.get_current_device()
    except Exception as exc:  # the driver's own words: library not found, no device, wrong version
        return False, f"the CUDA driver cannot be used: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
    return True, "CUDA"


def driver_library() -> str | None:
    """The NVIDIA driver's library, if this machine has it (looked for without importing numba-cuda)."""
    import ctypes
    import sys

    names = ("nvcuda.dll",) if sys.platform == "win32" else ("libcuda.so.1", "libcuda.so")
    for name in names:
        try:
            ctypes.CDLL(name)
        except OSError:
            continue
        return name
    return None


def describe_gpus() -> list[GpuInfo]:
    """Every GPU the driver lists ([] when none is usable or under the simulator)."""
    ok, _ = cuda_status()
    if not ok or simulator():
        return []
    from numba import cuda

    driver = cuda.cudadrv.driver.driver.get_version()
    out = []
    for gpu in cuda.gpus:
        with gpu:
            dev = cuda.get_current_device()
            free, total = cuda.current_context().get_memory_info()
            name = dev.name.decode() if isinstance(dev.name, bytes) else str(dev.name)
            out.append(GpuInfo(int(dev.id), name, tuple(dev.compute_capability), int(total), int(free),
                               ".".join(map(str, driver))))
    return out


def free_memory() -> int | None:
    """Bytes free on the current GPU (None under the simulator, whose memory is the host's)."""
    if simulator():
        return None
    from numba import cuda

    free, _ = cuda.current_context().get_memory_info()
    return int(free)


def resolve_device(requested: str = "auto") -> str:
    """``cpu`` or ``cuda`` for ``requested`` (one of :data:`DEVICES`); ``cuda`` unusable raises
    :class:`DeviceUnavailable`."""
    if requested not in DEVICES:
        raise ValueError(f"`device` must be one of {', '.join(DEVICES)}; got {requested!r}")
    if requested == "cpu":
        return "cpu"
    ok, reason = cuda_status()
    if requested == "cuda":
        if not ok:
            raise DeviceUnavailable(reason)
        return "cuda"
    if ok and not simulator():
        return "cuda"
    if not ok and stack_problem() is not None:  # a GPU stack that is installed but broken: worth a warning
        _logger.warning("device auto: the CPU, because %s", reason)
    else:
        _logger.info("device auto: the CPU (%s)", reason if not ok else "the simulator is not picked by auto")
    return "cpu"
