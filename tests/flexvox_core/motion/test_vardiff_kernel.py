"""The refinement's step reads its trajectory neighbours without clamps where every tap is inside the picture
(with unsigned indices), and is compiled with LLVM's SLP vectorizer: the clamped reads it replaced, read by read,
step by step and through motion-aware, and its own source compiled without the vectorizer, to the last bit or two
(:data:`ULPS`: the step's FMA contraction). Its
reads take the cell of a whole pixel plus a float32 offset exactly: the float64 reference's reads at float32
rounding of the values, far from the origin too."""

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

ULPS = 4e-7
"""Two code paths' reads and steps agree to this (values within [-1, 2]; float32 eps 1.2e-7): the step is compiled
with FMA contraction, which LLVM chooses for each inlined copy of a read's sums, so a read's last bits differ."""


@functools.cache
def clamped_kernel():
    """:func:`vardiff_step` compiled with the clamped reads everywhere (the step before the unclamped reads)."""
    f = K.vardiff_step.py_func
    glb = {**f.__globals__, "_bilinear": K._clamped_bilinear, "_bicubic": K._clamped_bicubic}
    return numba.njit(**K.STEP_OPTIONS)(types.FunctionType(f.__code__, glb, f.__name__, f.__defaults__))


@numba.njit(fastmath={"contract"})  # the step's flags
def _reads(plane, ys, dys, xs, dxs, cubic):
    """The reads at (ys[i] + dys[i], xs[j] + dxs[j]): the unclamped and the clamped."""
    out = np.empty((2, ys.size, xs.size), np.float32)
    for i in range(ys.size):
        for j in range(xs.size):
            if cubic:
                out[0, i, j] = K._bicubic(plane, ys[i], xs[j], dys[i], dxs[j])
                out[1, i, j] = K._clamped_bicubic(plane, ys[i], xs[j], dys[i], dxs[j])
            else:
                out[0, i, j] = K._bilinear(plane, ys[i], xs[j], dys[i], dxs[j])
                out[1, i, j] = K._clamped_bilinear(plane, ys[i], xs[j], dys[i], dxs[j])
    return out


def positions(n: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """Whole pixels and float32 offsets (|offset| ≤ n, as the step gives them) to points across the picture and
    beyond it: a fine grid, every whole pixel, the edges' neighbours, random points; every other one from its nearest
    pixel (the edges' neighbours a tiny offset away), the rest from a random pixel."""
    edges = [v for e in (0, 1, 2, n - 3, n - 2, n - 1) for v in (np.nextafter(e, -np.inf), e, np.nextafter(e, np.inf))]
    at = np.concatenate([np.arange(-2.5, n + 1.5, 0.125), np.arange(n), edges, rng.uniform(-3, n + 2, 50)])
    nearest = np.clip(np.round(at), 0, n - 1).astype(np.int64)
    pixel = np.where(np.arange(at.size) % 2 == 0, nearest, rng.integers(0, n, at.size))
    return pixel, np.clip(at - pixel, -n, n).astype(np.float32)


@pytest.mark.parametrize("H, W", [(1, 1), (1, 6), (2, 3), (3, 4), (4, 5), (7, 9), (12, 13)])
@pytest.mark.parametrize("cubic", [False, True])
def test_the_unclamped_reads_are_the_clamped_reads(H, W, cubic):
    rng = np.random.default_rng(H * 100 + W)
    plane = rng.normal(0.5, 0.4, (H, W)).astype(np.float32)  # negative values too: the clip to four taps' range
    got = _reads(plane, *positions(H, rng), *positions(W, rng), cubic)
    np.testing.assert_allclose(got[0], got[1], rtol=0, atol=ULPS)


@pytest.mark.parametrize("cubic", [False, True])
def test_the_reads_are_the_float64_references_far_from_the_origin(cubic):
    from tests.flexvox_core.motion.vardiff_reference import _sample, _sample_sharp

    rng = np.random.default_rng(5)
    H, W = 7, 4001  # columns up to 4000: a float32 position x + u would be 2.4e-4 px off there
    plane = rng.uniform(0, 1, (H, W)).astype(np.float32)
    ys, dys = np.arange(H), rng.uniform(-2, 2, H).astype(np.float32)
    xs = np.concatenate([rng.integers(0, W, 300), [0, 1, W - 2, W - 1]])
    dxs = rng.uniform(-3, 3, xs.size).astype(np.float32)
    dxs[:50] = np.round(dxs[:50])  # whole offsets: the pixel itself
    dxs[50:100] = np.round(dxs[50:100]) + np.float32(2.0**-20)  # just past a pixel (lost in a float32 position)
    got = _reads(plane, ys, dys, xs, dxs, cubic)[0].astype(np.float64)
    gy, gx = np.meshgrid(ys + dys.astype(np.float64), xs + dxs.astype(np.float64), indexing="ij")
    want = (_sample_sharp if cubic else _sample)(plane, gy, gx)
    np.testing.assert_allclose(got, want, rtol=0, atol=5e-7)  # float32 sums of values in [0, 1]: a few ulp of 1


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
def test_the_step_is_the_clamped_reads_step(S, H, W, c, scale):
    init, mask, flow, sharp = case(S, H, W, S + H + W, scale)
    before = clamped_kernel()
    for use_sharp in (False, True):
        for keep, still2, (t0, t1) in ((True, 0.0, (0, S)), (False, 1e-2, (0, S)), (True, 1e-6, (S // 2, S))):
            got, want = np.full_like(init, -7), np.full_like(init, -7)
            args = (flow, mask, keep, *c, 0.4, sharp, use_sharp, t0, t1, still2)
            K.vardiff_step(init, got, *args)
            before(init, want, *args)
            np.testing.assert_allclose(got, want, rtol=0, atol=ULPS)
            if S > 1 or c[1] > 0:  # one sub-frame along λ alone: both ends of time, nothing to diffuse
                assert not np.array_equal(got[t0:t1], init[t0:t1])  # the step changed something


@pytest.mark.parametrize("missing", [None, np.array([False, True, False, False, False])])
def test_motion_aware_is_the_clamped_reads_one(monkeypatch, missing):
    code = design_code((4, 4)).code
    frames = capture(render_scene("balls", 16 * 5, 27, 37, seed=2), code)  # odd sizes, a dropped frame
    kept = motion_aware(frames, code, missing=missing)
    monkeypatch.setattr(K, "vardiff_step", clamped_kernel())
    before = motion_aware(frames, code, missing=missing)
    np.testing.assert_allclose(kept.video, before.video, rtol=0, atol=ULPS)
    assert kept.stage_seconds["refinement"] > 0  # the refinement ran


def test_the_step_compiled_with_the_slp_vectorizer_is_the_step_without_it():
    plain = numba.njit(**K.STEP_OPTIONS)(K.vardiff_step.py_func)  # numba's default: no SLP vectorizer
    for S, H, W in ((4, 13, 11), (3, 24, 37)):
        init, mask, flow, sharp = case(S, H, W, S * W, 0.6)
        sharp[:] = True  # every moving voxel read by Catmull-Rom: the vectorised read
        for c in ((0.95, 0.0, 0.0), (0.95, 0.05, 0.05)):
            got, want = np.full_like(init, -7), np.full_like(init, -7)
            args = (flow, mask, True, *c, 0.4, sharp, True, 0, S, 1e-6)
            K.vardiff_step(init, got, *args)
            plain(init, want, *args)
            np.testing.assert_allclose(got, want, rtol=0, atol=ULPS)
    assert numba.config.SLP_VECTORIZE == 0  # set only around the step's own compilation


@pytest.mark.parametrize("c", [(1.0, 0.0, 0.0), (0.95, 0.0, 0.0), (0.95, 0.05, 0.05), (0.7, 0.3, 0.1),
                               (1 / 3, 1 / 3, 1 / 3)])
def test_the_float32_step_at_its_bound_keeps_the_data_range(c):
    from flexvox_core.motion.vardiff import STEP_MARGIN, float32_step, variable_tensor_diffusion

    bound = 1 / (2 * sum(c))
    *c32, dt32, still2 = float32_step(c, bound, 1e-6)
    trace = sum(float(v) for v in c32)
    assert 1 - 4 * STEP_MARGIN < 2 * float(dt32) * trace <= 1 - STEP_MARGIN  # rounded down, no further than needed
    assert 2 * float(np.nextafter(dt32, np.float32(1))) * trace > 1 - STEP_MARGIN
    assert all(type(v) is np.float32 for v in (*c32, dt32, still2)) and still2 == np.float32(1e-6)
    assert float32_step(c, 0.5 * bound, 0.0)[3] == np.float32(0.5 * bound)  # within the bound: float32 as it is
    rng = np.random.default_rng(11)
    for steps in (1, 2, 3):  # dt at the bound: every neighbour's weight as large as it may be
        init = rng.uniform(0.2, 0.8, (6, 17, 19)).astype(np.float32)
        init[rng.random(init.shape) < 0.3] = np.float32(0.8)  # many voxels at either end of the range
        init[rng.random(init.shape) < 0.2] = np.float32(0.2)
        mask = rng.random(init.shape) < 0.1
        flow = rng.normal(0, 1, (*init.shape, 2)).astype(np.float32)
        flow[rng.random(init.shape) < 0.4] = 0
        got = variable_tensor_diffusion(init, mask, flow, c=c, time=steps * bound, sharp=rng.random(init.shape) < 0.5)
        assert np.float32(0.2) <= got.min() and got.max() <= np.float32(0.8)  # exactly: no rounding past either end
        assert not np.array_equal(got, init)
