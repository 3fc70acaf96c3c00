"""Review's reconstruction jobs and the napari plugin take the GPU when one is usable, and say where they ran."""

import numpy as np

from flexvox_app.gui.models.jobs import run_reconstruction
from flexvox_core import capture, code_from_order
from flexvox_core.methods import Method

CODE = code_from_order([[0, 2], [3, 1]])


def test_a_job_runs_where_it_is_asked_and_says_so():
    frames = capture(np.random.default_rng(3).random((8, 6, 8)).astype(np.float32), CODE)
    on_gpu = run_reconstruction(frames, CODE, Method("diffusion"), device="cuda")  # the simulator stands in
    assert on_gpu.device == "cuda" and "on numba-cuda's simulator" in on_gpu.label()  # named as what it is
    by_default = run_reconstruction(frames, CODE, Method("diffusion"))  # auto: the simulator is never taken
    assert by_default.device == "cpu" and "on the CPU" in by_default.label() and "GPU" not in by_default.label()
    np.testing.assert_allclose(on_gpu.video, by_default.video, atol=2e-6)
    rebin = run_reconstruction(frames, CODE, Method("rebin"), device="cuda")
    assert rebin.device == "cpu" and rebin.device_note == "rebin has no GPU path"
    assert rebin.where == "on the CPU (rebin has no GPU path)"
