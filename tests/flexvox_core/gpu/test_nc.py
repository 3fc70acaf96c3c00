"""The GPU normalized convolution against the CPU's ``diffuse`` (nc solver)."""

import numpy as np
import pytest

from flexvox_core import capture, code_from_order
from flexvox_core.forward import tiled_order
from flexvox_core.reconstruct.diffusion import diffuse


def _gpu_nc(frames, code, tensor, time, missing=None):
    from numba import cuda

    from flexvox_core.gpu.diffusion import NcPlan, nc
    from flexvox_core.gpu.volumes import Workspace

    F, H, W = frames.shape
    K = code.shape[2]
    present = None if missing is None else ~np.asarray(missing)
    kept = frames if present is None else frames[present]
    ws = Workspace()
    out = cuda.device_array((F * K, H, W), np.float32)
    low = nc(ws, cuda.to_device(np.ascontiguousarray(frames, np.float32)),
             cuda.to_device(np.ascontiguousarray(tiled_order(code, H, W), np.int32)),
             cuda.to_device((np.ones(F, bool) if present is None else present).astype(np.uint8)),
             NcPlan(F, K, tensor, time, present), float(kept.min()), float(kept.max()), out)
    return out.copy_to_host(), low


CODE = code_from_order([[0, 2], [3, 1]])


@pytest.mark.parametrize("tensor, time", [((1, 1, 0.05), 2.0), ((0.05, 0.05, 0.95), 5.0), ((0, 0, 1), 2.0),
                                          ((1, 1, 1), 0.25)])
def test_nc_matches_diffuse(rng, tensor, time):
    video = rng.random((8, 5, 7)).astype(np.float32)
    frames = capture(video, CODE)
    got, low = _gpu_nc(frames, CODE, tensor, time)
    want = diffuse(frames, CODE, tensor=tensor, time=time)
    assert low == 0
    np.testing.assert_allclose(got, want, atol=2e-6)


def test_nc_with_a_dropped_frame(rng):
    video = rng.random((12, 4, 6)).astype(np.float32)
    frames = capture(video, CODE)
    missing = np.array([False, True, False])
    frames[1] = 0
    got, low = _gpu_nc(frames, CODE, (1, 1, 0.05), 2.0, missing)
    want = diffuse(frames, CODE, tensor=(1, 1, 0.05), time=2.0, missing=missing)
    assert low == 0
    np.testing.assert_allclose(got, want, atol=2e-6)


def test_nc_counts_voxels_without_a_sample_in_reach(rng):
    video = rng.random((8, 4, 4)).astype(np.float32)
    frames = capture(video, CODE)
    got, low = _gpu_nc(frames, CODE, (0.001, 0.001, 0.001), 0.1)  # tiny kernels: most voxels see no sample
    assert low > 0
    assert np.isnan(got).sum() == low
