"""Motion-aware reconstruction and ``nc`` on an NVIDIA GPU: the pipeline's stages as CUDA kernels.

The kernels are written in Python with numba-cuda (the ``gpu`` extra: ``pip install 'flexvox[gpu]'``). Each
stage of :mod:`flexvox_core.motion.stages` has a GPU twin here that takes and returns device arrays, so a
window's data stays on the card from the upload of the camera frames to the download of the result.

Nothing here is imported by the CPU path: :mod:`flexvox_core.gpu.device` (which GPU, if any; what ``auto``
picks) imports numba-cuda only when asked, and a core install without it says what is missing.

Every kernel also runs under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``: plain Python, slow, no GPU),
which is how the tests run it on machines without one, and compiles for a real GPU without one
(:func:`flexvox_core.gpu.launch.compile_all`).
"""

from flexvox_core.gpu.device import DeviceUnavailable, cuda_status, describe_gpus, resolve_device

__all__ = ["DeviceUnavailable", "cuda_status", "describe_gpus", "resolve_device"]
