"""The GPU engine around the parity matrix (``test_parity.py``): the device choice, the deviceless compile, the
memory a chunk may take, the routes to the CPU, a workspace reused by a stream.

Under numba-cuda's simulator every kernel runs as Python: the windows here are tiny (a few frames of 8×8 to 12×16
pixels at K = 4). The same comparisons at full size, on a GPU, are marked ``gpu``.
"""

import importlib.util
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from flexvox_core import capture
from flexvox_core.design import design_code
from flexvox_core.metrics import psnr
from flexvox_core.motion.options import MotionOptions
from flexvox_core.motion.pipeline import motion_aware
from flexvox_core.simulate.scenes import render_scene
from tests.flexvox_core.gpu.tiny import CODE, tiny_capture


def test_device_choice(monkeypatch):
    from flexvox_core.gpu import device

    assert device.resolve_device("cpu") == "cpu"
    assert device.resolve_device("cuda") == "cuda"  # the simulator, asked for by name
    assert device.resolve_device("auto") == "cpu"
    with pytest.raises(ValueError, match=r"`device` must be one of auto, cpu, cuda; got 'gpu'"):
        device.resolve_device("gpu")
    monkeypatch.setattr(device.importlib.util, "find_spec", lambda name: None)
    assert device.cuda_status() == (False, "numba-cuda is not installed (pip install '.[gpu]' in a clone of flexvox)")
    with pytest.raises(device.DeviceUnavailable, match=r"^device='cuda': numba-cuda is not installed") as info:
        device.resolve_device("cuda")
    assert info.value.reason == "numba-cuda is not installed (pip install '.[gpu]' in a clone of flexvox)"
    assert device.resolve_device("auto") == "cpu"


def _declared_kernels(packages) -> set[str]:
    """The functions decorated ``@kernel(...)`` in the packages' source files, read with ast (not imported)."""
    import ast
    import pathlib

    root = pathlib.Path(__file__).resolve().parents[3]
    names = set()
    for package in packages:
        for path in sorted((root / package.replace(".", "/")).glob("*.py")):
            module = f"{package}.{path.stem}"
            for node in ast.walk(ast.parse(path.read_text())):
                decorators = getattr(node, "decorator_list", ())
                if isinstance(node, ast.FunctionDef) and any(
                        isinstance(d, ast.Call) and getattr(d.func, "id", None) == "kernel" for d in decorators):
                    names.add(f"{module}.{node.name}")
    return names


@pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None, reason="numba-cuda is not installed")
def test_every_kernel_compiles_for_a_gpu_without_one():
    """numba-cuda's deviceless compile of every declared signature, for the H100's compute capability: every kernel
    the packages' files declare (found in their source, not in a hand-kept list) compiles to PTX. Of DIS's kernels
    only the resampling ones compute in float64 (OpenCV's coordinate and area-weight tables, in double there too)."""
    from flexvox_core.motion.gpu import KERNEL_PACKAGES

    code = textwrap.dedent("""
        import json
        from flexvox_core.gpu.launch import compile_all
        from flexvox_core.motion.gpu import KERNEL_PACKAGES
        print(json.dumps(compile_all(KERNEL_PACKAGES, cc=(9, 0))))
    """)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    import json

    stats = json.loads(done.stdout.splitlines()[-1])
    declared = _declared_kernels(KERNEL_PACKAGES)
    assert "flexvox_core.motion.gpu.oriented_nc._structure_y" in declared
    assert set(stats) == declared
    assert min(chars for chars, _ in stats.values()) > 1000  # PTX with an entry point, not an empty module
    dis = {n.rsplit(".", 1)[1]: f64 for n, (_, f64) in stats.items() if n.startswith("flexvox_core.gpu.dis")}
    assert set(dis) == {"_area_down", "_sobel", "_tensor", "_search", "_densify", "_upsample", "_to_output", "_zero",
                        "_warp", "_derivatives", "_smoothness", "_system", "_sor", "_add"}
    assert {n for n, f64 in dis.items() if f64} == {"_area_down", "_upsample", "_to_output"}


@pytest.mark.gpu
@pytest.mark.parametrize("scene", ["balls", "pan"])
def test_full_size_gpu_against_cpu(scene):
    """A 640×480, K = 16 clip of 4 frames: the GPU within 0.1 dB of the CPU, and the same bits on a rerun."""
    code = design_code((4, 4)).code
    truth = render_scene(scene, 4 * 16, 480, 640, seed=0)
    frames = capture(truth, code)
    cpu = motion_aware(frames, code)
    gpu = motion_aware(frames, code, device="cuda")
    again = motion_aware(frames, code, device="cuda")
    assert abs(psnr(gpu.video, truth) - psnr(cpu.video, truth)) < 0.1
    np.testing.assert_array_equal(gpu.video, again.video)


def test_chunks_shrink_to_fit_the_cards_free_memory(monkeypatch):
    from flexvox_core.gpu import device
    from flexvox_core.methods import Method
    from flexvox_core.methods.runner import gpu_chunk_frames

    method = Method("motion-aware")  # 4 frames of context each side at K = 16
    per_frame = method.gpu_voxel_bytes(16, 480, 640) * 16 * 480 * 640  # about 150 bytes per voxel at 640x480
    monkeypatch.setattr(device, "free_memory", lambda: int(12 * per_frame / 0.8) + 1024)
    assert gpu_chunk_frames(method, 16, 480, 640, 100, 16) == 4  # 12 frames fit: 4 and 4 + 4 of context
    assert gpu_chunk_frames(method, 16, 480, 640, 4, None) is None  # the whole clip fits
    monkeypatch.setattr(device, "free_memory", lambda: int(8 * per_frame))
    with pytest.raises(ValueError, match=r"needs about .* GiB of GPU memory for one 480x640 frame and its context; "
                                         r".* GiB are free: reconstruct on the CPU$"):
        gpu_chunk_frames(method, 16, 480, 640, 100, 16)
    monkeypatch.setattr(device, "free_memory", lambda: None)  # the simulator: no limit known
    assert gpu_chunk_frames(method, 16, 480, 640, 100, 16) == 16


def test_options_the_gpu_does_not_run_go_to_the_cpu_with_a_note():
    """The GPU's flow is DIS without backward flow: farneback with flow_consistency asked for on the GPU runs on
    the CPU, gives the CPU's video bit for bit and says why (the result, the method's ``cpu_only``, the runner's
    ``device_note``); never another flow in silence."""
    from flexvox_core.methods import Method
    from flexvox_core.methods.runner import run

    _, frames = tiny_capture("balls", 2, 12, 16)
    options = {"flow": "farneback", "flow_consistency": True}
    cpu = motion_aware(frames, CODE, **options)
    gpu = motion_aware(frames, CODE, device="cuda", **options)
    note = ("flow='farneback' runs on the CPU (the GPU's optical flow is DIS); "
            "flow_consistency runs on the CPU (the GPU's DIS has no backward flow)")
    assert (gpu.device, gpu.device_note) == ("cpu", note) and cpu.device_note is None
    assert gpu.flow.params["backend"] == "farneback" and gpu.flow.params["consistency"] is True
    np.testing.assert_array_equal(gpu.video, cpu.video)
    method = Method("motion-aware", flow="farneback")
    assert method.cpu_only(CODE) == "flow='farneback' runs on the CPU (the GPU's optical flow is DIS)"
    assert Method("motion-aware").cpu_only(CODE) is None
    out = run(frames, CODE, method, device="cuda")
    assert (out.device, out.device_note) == ("cpu", method.cpu_only(CODE))
    from flexvox_core.motion.streaming import StreamingMotionAware

    stream = StreamingMotionAware(CODE, device="cuda", flow="tvl1")
    assert (stream.device, stream.device_note) == ("cpu", "flow='tvl1' runs on the CPU (the GPU's optical flow is DIS)")
    assert StreamingMotionAware(CODE, device="cuda").device_note is None


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
    from flexvox_core.motion.gpu import gated_flow as gate
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


def test_high_tr_is_rounded_through_float16_as_numpy_rounds():
    """The GPU holds high-TR in float32 rounded through float16 from the flow on: the CPU's float16 values, ties to
    even, subnormals, infinities and NaN alike (high-TR's values lie within the samples': none overflows)."""
    from numba import cuda

    from flexvox_core.gpu.volumes import through_half

    e = 2.0 ** -11
    odd = [1 + e, 1 + 3 * e, 2.0 ** -25, 3 * 2.0 ** -25, 65519.0, -0.0, np.nan, -np.inf, 1e-8]
    a = np.concatenate([np.array(odd, np.float32),
                        np.random.default_rng(5).normal(0.5, 0.3, 999).astype(np.float32)]).reshape(2, 3, 168)
    d = cuda.to_device(a)
    through_half(d)
    want = a.astype(np.float16).astype(np.float32)
    got = d.copy_to_host()
    np.testing.assert_array_equal(got, want)
    assert got[0, 0, 0] == 1 and got[0, 0, 1] == 1 + 4 * e and got[0, 0, 4] == 65504
    assert np.signbit(got[0, 0, 5]) and (got != a)[np.isfinite(a)].any()
