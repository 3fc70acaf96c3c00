"""The device memory a motion-aware GPU run holds against the estimate the runner sizes chunks with
(:meth:`MotionAware.gpu_voxel_bytes <flexvox_core.methods.motion_aware_method.MotionAware.gpu_voxel_bytes>`), with
:mod:`tests.flexvox_core.gpu.workspace_size`."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.motion.options import MotionOptions, check_sample_range
from flexvox_core.motion.stages import Window
from tests.flexvox_core.gpu.tiny import CODE, tiny_capture
from tests.flexvox_core.gpu.workspace_size import buffers, no_kernels, planned_peak, run_workspace

METHOD = Method("motion-aware")
ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(("H", "W"), [(8, 8), (16, 16), (44, 44), (40, 80), (120, 160), (240, 320), (480, 640)])
@pytest.mark.parametrize("side", [2, 4])
def test_the_estimate_bounds_the_workspace_of_every_stage(H, W, side):
    """Two passes, every branch taken, DIS's buffers counted: the workspace's peak stays within the estimate, and
    at 640x480 within 10 % of it (the runner would otherwise cut chunks it need not)."""
    code = design_code((side, side)).code
    K = code.shape[2]
    peak, voxels = planned_peak(H, W, 9 if K == 4 else 3, code, MotionOptions(passes=2))
    estimate = METHOD.gpu_voxel_bytes(K, H, W)
    assert peak <= estimate * voxels, f"{H}x{W}, K = {K}: {peak / voxels:.1f} bytes per voxel > {estimate:.1f}"
    if H * W >= 480 * 640:
        assert estimate * voxels <= 1.1 * peak


def test_the_estimate_follows_the_flows_size():
    """Pictures up to 160 px a side run their flow at full size and hold more per voxel than 640x480, whose flow
    runs at a third; the pipeline's explicit flow scale counts."""
    assert METHOD.gpu_voxel_bytes(16, 120, 160) > 1.5 * METHOD.gpu_voxel_bytes(16, 480, 640) > 1.5 * 140
    half = METHOD.spec.gpu_voxel_bytes(MotionOptions(flow_scale=0.5), 16, 480, 640)
    assert half > METHOD.gpu_voxel_bytes(16, 480, 640)


@pytest.mark.slow_sim
def test_a_real_run_holds_what_the_plan_holds_and_fits_the_estimate():
    """A whole run under the simulator (a noisy capture, a dropped frame, two passes): every buffer it holds is one
    the kernel-less plan holds, of the same shape, and its peak fits the estimate; the plan is what the table of
    :mod:`tests.flexvox_core.gpu.workspace_size` and the test above measure at larger sizes."""
    _, frames = tiny_capture("balls", 3, 8, 8, noise=0.01)
    missing = np.array([False, True, False])
    frames[1] = 0
    options = MotionOptions(passes=2)
    w = Window.plan(frames, CODE, options, check_sample_range(frames, missing, None), missing=missing)
    real = run_workspace(w)
    with no_kernels():
        plan = run_workspace(w)
    held, planned = buffers(real), buffers(plan)
    assert set(held) <= set(planned), sorted(set(held) - set(planned))
    assert all(held[n] == planned[n] for n in held)
    assert real.peak_nbytes <= plan.peak_nbytes
    voxels = w.S * 8 * 8
    assert real.peak_nbytes <= METHOD.gpu_voxel_bytes(4, 8, 8) * voxels
    assert real.peak_nbytes > 0.5 * plan.peak_nbytes  # the plan is not a gross overcount


def test_an_explicit_flow_scale_is_bounded_too():
    options = MotionOptions(passes=2, flow_scale=0.5)
    code = design_code((4, 4)).code
    peak, voxels = planned_peak(240, 320, 3, code, options)
    assert peak <= METHOD.spec.gpu_voxel_bytes(options, 16, 240, 320) * voxels


def test_skipping_the_kernels_leaves_every_launch_as_it_was():
    """In a fresh process (no kernel module imported yet), every module's ``launch`` after :func:`no_kernels` is
    the real one: a module first imported inside it must not keep the stand-in."""
    script = textwrap.dedent("""
        import importlib
        from tests.flexvox_core.gpu.workspace_size import no_kernels
        with no_kernels():
            inside = importlib.import_module("flexvox_core.gpu.diffusion").launch
        from flexvox_core.gpu import launch as L
        assert inside is not L.launch  # the stand-in while inside
        from flexvox_core.motion.gpu import KERNEL_PACKAGES
        modules = [importlib.import_module(n) for n in L.modules_of(KERNEL_PACKAGES)]
        print(sum(hasattr(m, "launch") for m in modules),
              [m.__name__ for m in modules if getattr(m, "launch", L.launch) is not L.launch])
    """)
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1", PYTHONPATH=os.pathsep.join([str(ROOT),
                                                                                  os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    count, wrong = done.stdout.split(maxsplit=1)
    assert int(count) >= 10 and wrong.strip() == "[]", done.stdout
