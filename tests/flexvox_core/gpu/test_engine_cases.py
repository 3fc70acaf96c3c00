"""The GPU engine against the CPU pipeline case by case: noise, dropped frames, kept sub-frames, passes, streams.

Under numba-cuda's simulator every kernel runs as Python: the windows here are tiny (a few frames of 12×16
pixels at K = 4). The same comparisons at full size, on a GPU, are marked ``gpu``.
"""


import numpy as np
import pytest

from flexvox_core.metrics import psnr
from flexvox_core.motion.options import MotionOptions, sample_bounds
from flexvox_core.motion.pipeline import run_window
from tests.flexvox_core.gpu.tiny import CODE, K, tiny_capture


def _both(frames, options, missing=None, keep=None, pairs="cpu"):
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.stages import Window, run_stages

    bounds = sample_bounds(frames, missing, None)
    cpu = run_window(frames, CODE, options, bounds, missing=missing, keep=keep)
    gpu = run_stages(CudaStages(Window.plan(frames, CODE, options, bounds, missing=missing, keep=keep), pairs=pairs))
    return cpu, gpu


CASES = ("noisy", "dropped frame", "kept sub-frames", "two passes", "no refinement")


@pytest.mark.parametrize("case", CASES)
def test_the_gpu_engine_follows_the_cpu_in_each_case(case):
    F = 3 if case in ("dropped frame", "kept sub-frames") else 2
    truth, frames = tiny_capture("balls", F, 12, 12, noise=0.02 if case == "noisy" else 0.0)
    options = MotionOptions(passes=2 if case == "two passes" else 1,
                            refine_time=0.0 if case == "no refinement" else None)
    missing = keep = None
    if case == "dropped frame":
        missing = np.array([False, True, False])
        frames[1] = 0
    if case == "kept sub-frames":
        keep = (K, 2 * K)
    cpu, gpu = _both(frames, options, missing=missing, keep=keep)
    assert gpu.video.shape == cpu.video.shape
    # A second pass measures flow on the first pass's result, through 8-bit images: a float rounding there can
    # move a flow vector, so that case is held to the quality, the others to the values.
    if case == "two passes":
        assert abs(psnr(gpu.video, truth) - psnr(cpu.video, truth)) < 0.05
    else:
        np.testing.assert_allclose(gpu.video, cpu.video, atol=2e-4)

def test_a_result_read_after_its_workspace_was_reused_says_so():
    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.stages import Window, run_stages

    truth, frames = tiny_capture("balls", 2, 8, 8)
    ws = Workspace()
    window = Window.plan(frames, CODE, MotionOptions(refine_time=0.0, local_choice=False, noise_aware=False),
                         (0.0, 1.0))
    first = run_stages(CudaStages(window, ws=ws, pairs="cpu"))
    run_stages(CudaStages(window, ws=ws, pairs="cpu"))
    with pytest.raises(RuntimeError, match="overwritten by a later window of the same workspace"):
        first.high_tr  # noqa: B018

def test_a_stream_on_the_gpu_reuses_its_workspace_and_follows_the_cpus(monkeypatch):
    from flexvox_core.motion.gpu import gate
    from flexvox_core.motion.streaming import StreamingMotionAware

    class HostPairs(gate.PairFlow):  # OpenCV's DIS for the pairs: the simulator's DIS is tested on its own
        def __init__(self, ws, where, params):
            super().__init__(ws, "cpu", params)

    monkeypatch.setattr(gate, "PairFlow", HostPairs)
    truth, frames = tiny_capture("balls", 3, 8, 8)
    options = {"refine_time": 0.0, "local_choice": False, "noise_aware": False}
    cpu, gpu = StreamingMotionAware(CODE, **options), StreamingMotionAware(CODE, device="cuda", **options)
    assert gpu.device == "cuda" and cpu.device == "cpu"
    got, want = [], []
    for frame in frames:
        got += gpu.push(frame)
        want += cpu.push(frame)
    got += gpu.finish()
    want += cpu.finish()
    assert [g.index for g in got] == [w.index for w in want] == [0, 1, 2]
    buffers = gpu._workspace.nbytes
    assert buffers > 0  # one workspace served every window
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g.video, w.video, atol=2e-4)
