"""Reconstruction on an NVIDIA GPU: CUDA kernels, and which device runs a reconstruction.

The kernels are written in Python with numba-cuda (the ``gpu`` extra: ``pip install '.[gpu]'`` in a clone of
flexvox). This
package holds the building blocks: normalized convolution (:mod:`~flexvox_core.gpu.diffusion`), resizing, the DIS
optical flow, device buffers, and how kernels are declared and launched (:mod:`~flexvox_core.gpu.launch`).
Motion-aware's own stages are in :mod:`flexvox_core.motion.gpu`, built on these.

Nothing here is imported by the CPU path: :mod:`flexvox_core.gpu.device` (which GPU, if any; what ``auto``
picks) imports numba-cuda only when asked, and a core install without it says what is missing.

Every kernel also runs under numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``: plain Python, slow, no GPU),
which is how the tests run it on machines without one, and compiles for a real GPU without one
(:func:`flexvox_core.gpu.launch.compile_all`).
"""

from flexvox_core.gpu.device import DeviceUnavailable, cuda_status, describe_gpus, resolve_device

__all__ = ["DeviceUnavailable", "cuda_status", "describe_gpus", "resolve_device"]
