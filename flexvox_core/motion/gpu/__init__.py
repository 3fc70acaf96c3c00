"""Motion-aware's stages on an NVIDIA GPU (:class:`~flexvox_core.motion.gpu.engine.CudaStages`).

Each stage of :mod:`flexvox_core.motion.stages` has a twin here made of CUDA kernels (numba-cuda, the ``gpu``
extra) on device arrays: a window's data stays on the card from the upload of the camera frames to the
download of the result. The building blocks that are not motion-aware's own (normalized convolution, resizing,
the DIS optical flow, device buffers) are in :mod:`flexvox_core.gpu`; motion-aware's own, the local choice among
them, are here. Each module is named as its CPU twin (``motion/mcnc.py`` ↔ ``motion/gpu/mcnc.py``; oriented nc's
structure tensor, :mod:`flexvox_core.reconstruct.oriented_nc`'s, in :mod:`~flexvox_core.motion.gpu.oriented_nc`).
Nothing here is imported on the CPU path.
"""

from flexvox_core.gpu.launch import KERNEL_PACKAGES as _GENERIC

KERNEL_PACKAGES = (*_GENERIC, "flexvox_core.motion.gpu")
"""The packages whose modules declare motion-aware's kernels and the generic ones it uses (what
:func:`flexvox_core.gpu.launch.compile_all` compiles in the tests)."""
