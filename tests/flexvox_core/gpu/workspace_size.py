"""The device memory motion-aware's GPU engine holds, measured against
:meth:`MotionAware.gpu_voxel_bytes <flexvox_core.methods.motion_aware_method.MotionAware.gpu_voxel_bytes>`.

:func:`planned_peak` runs the engine's host code on a window with every launch skipped (:func:`no_kernels`): the
stages ask the workspace for the buffers a run on a card holds, DIS's included, at sizes the simulator could
not run in a day, and every branch that depends on the data is taken (still and slow voxels, a noisy capture,
a finite leave-one-out estimate for the local choice). ``tests/flexvox_core/gpu/test_workspace_size.py`` checks
that a real run under the simulator holds no buffer the plan lacks, and that the estimate bounds the plan.
``NUMBA_ENABLE_CUDASIM=1 python -m tests.flexvox_core.gpu.workspace_size`` prints the table the estimate was
derived from.
"""

from __future__ import annotations

import contextlib
import importlib

import numpy as np

SIZES = [(8, 8), (12, 12), (8, 16)] + [(s, s) for s in range(16, 100, 4)] + [(s, 2 * s) for s in range(16, 90, 4)] \
    + [(s, (4 * s) // 3) for s in range(16, 200, 8)] + [(s, 2 * s) for s in range(100, 340, 20)] \
    + [(480, 640), (720, 1280), (1080, 1920)]
"""Picture sizes (H, W) of the table: every few pixels where DIS's pyramid changes, then the common ones."""
CODES = (2, 4)
"""The codes' tile sides (K = 4 and 16)."""


@contextlib.contextmanager
def no_kernels():
    """Every launch of the GPU engine's modules skipped, and each decision read back from the card taken the way
    that allocates the most: still and slow voxels exist, every frame is noisy, a leave-one-out estimate is
    finite."""
    from flexvox_core.gpu.launch import modules_of
    from flexvox_core.motion.gpu import KERNEL_PACKAGES
    from flexvox_core.motion.gpu import gated_flow as gate
    from flexvox_core.motion.gpu import local_choice as choice
    from flexvox_core.motion.gpu import noise_aware as noise

    saved = []

    def patch(module, name, value):
        saved.append((module, name, getattr(module, name)))
        setattr(module, name, value)

    speed_classes, frame_noise, any_finite = gate.speed_classes, noise.frame_noise, choice.any_finite
    try:
        # Every module imported before any is patched: one imported after ``launch.launch`` was patched would take
        # the stand-in as its own ``launch`` and keep it after the restore.
        modules = [importlib.import_module(name) for name in modules_of(KERNEL_PACKAGES)]
        for module in modules:
            if hasattr(module, "launch"):
                patch(module, "launch", lambda *args: None)
        patch(gate, "speed_classes", lambda *a, **k: (speed_classes(*a, **k), (1, 1))[1])
        patch(noise, "frame_noise", lambda ws, frames, *a: (frame_noise(ws, frames, *a),
                                                            np.full(frames.shape[0], 0.01, np.float32))[1])
        patch(choice, "any_finite", lambda *a: (any_finite(*a), True)[1])
        yield
    finally:
        for module, name, value in reversed(saved):
            setattr(module, name, value)


def window(H: int, W: int, F: int, code, options, frames=None):
    from flexvox_core.motion.options import check_sample_range
    from flexvox_core.motion.stages import Window

    if frames is None:
        frames = np.random.default_rng(0).random((F, H, W), np.float32)
    return Window.plan(frames, code, options, check_sample_range(frames, None, None))


def run_workspace(w):
    """The workspace of a GPU run of window ``w`` (kernels run unless under :func:`no_kernels`)."""
    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.stages import run_stages

    ws = Workspace()
    run_stages(CudaStages(w, ws=ws))
    return ws


def planned_peak(H: int, W: int, F: int, code, options) -> tuple[int, int]:
    """(the workspace's peak bytes, the window's voxels S·H·W) of a GPU run with its kernels skipped."""
    w = window(H, W, F, code, options)
    with no_kernels():
        ws = run_workspace(w)
    return ws.peak_nbytes, w.S * H * W


def buffers(ws) -> dict[str, tuple]:
    """The workspace's buffers by name: (shape, dtype), or the bytes of a held object (DIS's)."""
    out: dict[str, tuple] = {n: (tuple(b.shape), np.dtype(b.dtype).str) for n, b in ws._buffers.items()}
    out.update({n: ("held", int(h.nbytes)) for n, h in ws._held.items()})
    return out


def table(sizes=SIZES, codes=CODES, frames: int = 9) -> str:
    """Measured bytes per voxel (two passes) against the estimate, as markdown."""
    from flexvox_core.design import design_code
    from flexvox_core.methods import Method
    from flexvox_core.motion.options import MotionOptions

    method = Method("motion-aware")
    rows = ["| H×W | K | measured B/voxel | estimate | estimate / measured |", "|---|---|---|---|---|"]
    for H, W in sizes:
        for side in codes:
            code = design_code((side, side)).code
            K = code.shape[2]
            peak, voxels = planned_peak(H, W, frames, code, MotionOptions(passes=2))
            got, want = peak / voxels, method.gpu_voxel_bytes(K, H, W)
            rows.append(f"| {H}×{W} | {K} | {got:.1f} | {want:.1f} | {want / got:.3f} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table())
