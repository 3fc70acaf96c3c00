"""The refinement's step reads its trajectory neighbours without clamps where every tap is inside the picture
(with unsigned indices), and is compiled with LLVM's SLP vectorizer: the bits of the clamped reads it replaced,
read by read, step by step and through motion-aware, and of its own source compiled without the vectorizer."""

import functools
import types

import numba
import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.motion import motion_aware
from flexvox_core.motion import vardiff_kernel as K
from flexvox_core.simulate.scenes import render_scene


@functools.cache
def clamped_kernel():
    """:func:`vardiff_step` compiled with the clamped reads everywhere (the step before the unclamped reads)."""
    f = K.vardiff_step.py_func
    glb = {**f.__globals__, "_bilinear": K._clamped_bilinear, "_bicubic": K._clamped_bicubic}
    return numba.njit(parallel=True, nogil=True)(types.FunctionType(f.__code__, glb, f.__name__, f.__defaults__))


@numba.njit
def _reads(plane, ys, xs, cubic):
    out = np.empty((2, ys.size, xs.size))
    for i in range(ys.size):
        for j in range(xs.size):
            if cubic:
                out[0, i, j] = K._bicubic(plane, ys[i], xs[j])
                out[1, i, j] = K._clamped_bicubic(plane, ys[i], xs[j])
            else:
                out[0, i, j] = K._bilinear(plane, ys[i], xs[j])
                out[1, i, j] = K._clamped_bilinear(plane, ys[i], xs[j])
    return out


def positions(n: int, rng) -> np.ndarray:
    """Across the picture and beyond it: a fine grid, every whole pixel, the edges' neighbours, random points."""
    edges = [v for e in (0, 1, 2, n - 3, n - 2, n - 1) for v in (np.nextafter(e, -np.inf), e, np.nextafter(e, np.inf))]
    return np.concatenate([np.arange(-2.5, n + 1.5, 0.125), np.arange(n), edges, rng.uniform(-3, n + 2, 50)])


@pytest.mark.parametrize("H, W", [(1, 1), (1, 6), (2, 3), (3, 4), (4, 5), (7, 9), (12, 13)])
@pytest.mark.parametrize("cubic", [False, True])
def test_the_unclamped_reads_give_the_clamped_reads_bits(H, W, cubic):
    rng = np.random.default_rng(H * 100 + W)
    plane = rng.normal(0.5, 0.4, (H, W)).astype(np.float32)  # negative values too: the clip to four taps' range
    got = _reads(plane, positions(H, rng), positions(W, rng), cubic)
    np.testing.assert_array_equal(got[0].view(np.uint64), got[1].view(np.uint64))


def case(S, H, W, seed, scale):
    rng = np.random.default_rng(seed)
    init = rng.uniform(0.0, 1.0, (S, H, W)).astype(np.float32)
    mask = rng.random(init.shape) < 0.1
    flow = rng.normal(0, scale, (*init.shape, 2)).astype(np.float32)
    flow[rng.random(init.shape) < 0.3] = 0  # still voxels
    flow[0, 0, 0, 0] = np.nan
    flow[-1, -1, -1, 1] = np.inf
    sharp = rng.random(init.shape) < 0.5
    return init, mask, flow, sharp


@pytest.mark.parametrize("S, H, W", [(1, 5, 7), (5, 7, 9), (6, 13, 11), (3, 2, 17)])
@pytest.mark.parametrize("c", [(0.95, 0.0, 0.0), (0.95, 0.05, 0.05)])
@pytest.mark.parametrize("scale", [0.4, 3.0])  # slow trajectories, and fast ones that leave the picture
def test_the_step_gives_the_clamped_reads_step_bits(S, H, W, c, scale):
    init, mask, flow, sharp = case(S, H, W, S + H + W, scale)
    before = clamped_kernel()
    for use_sharp in (False, True):
        for keep, still2, (t0, t1) in ((True, 0.0, (0, S)), (False, 1e-2, (0, S)), (True, 1e-6, (S // 2, S))):
            got, want = np.full_like(init, -7), np.full_like(init, -7)
            args = (flow, mask, keep, *c, 0.4, sharp, use_sharp, t0, t1, still2)
            K.vardiff_step(init, got, *args)
            before(init, want, *args)
            np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
            if S > 1 or c[1] > 0:  # one sub-frame along λ alone: both ends of time, nothing to diffuse
                assert not np.array_equal(got[t0:t1], init[t0:t1])  # the step changed something


@pytest.mark.parametrize("missing", [None, np.array([False, True, False, False, False])])
def test_motion_aware_gives_the_clamped_reads_bits(monkeypatch, missing):
    code = design_code((4, 4)).code
    frames = capture(render_scene("balls", 16 * 5, 27, 37, seed=2), code)  # odd sizes, a dropped frame
    kept = motion_aware(frames, code, missing=missing)
    monkeypatch.setattr(K, "vardiff_step", clamped_kernel())
    before = motion_aware(frames, code, missing=missing)
    np.testing.assert_array_equal(kept.video.view(np.uint32), before.video.view(np.uint32))
    assert kept.stage_seconds["refinement"] > 0  # the refinement ran


def test_the_step_compiled_with_the_slp_vectorizer_gives_its_bits_without_it():
    plain = numba.njit(parallel=True, nogil=True)(K.vardiff_step.py_func)  # numba's default: no SLP vectorizer
    for S, H, W in ((4, 13, 11), (3, 24, 37)):
        init, mask, flow, sharp = case(S, H, W, S * W, 0.6)
        sharp[:] = True  # every moving voxel read by Catmull-Rom: the vectorised read
        for c in ((0.95, 0.0, 0.0), (0.95, 0.05, 0.05)):
            got, want = np.full_like(init, -7), np.full_like(init, -7)
            args = (flow, mask, True, *c, 0.4, sharp, True, 0, S, 1e-6)
            K.vardiff_step(init, got, *args)
            plain(init, want, *args)
            np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    assert numba.config.SLP_VECTORIZE == 0  # set only around the step's own compilation
