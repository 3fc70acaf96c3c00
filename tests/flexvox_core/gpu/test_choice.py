"""The GPU local choice (flexvox_core/motion/gpu/local_choice.py, local_choice_weights.py, oriented_nc.py) against
the CPU's stage and its parts: the still-voxel correction, the structure tensor and kernel choice, oriented nc and
its leave-one-out, the pooled weights (full size and on the coarse grid) and the whole stage, with dropped frames
and empty, partial and full gathered sets. Under the simulator the kernels run as Python on pictures of a few
pixels; the tests marked ``gpu`` run them at 480×640 on a card.

Tolerances: float32 sums on the GPU against the CPU's float32 (OpenCV, numpy) and float64 (oriented nc's
compiled kernel) in another order, with fused multiply-adds: a few units in the last place of values near 1."""

import importlib.util
from types import SimpleNamespace

import numpy as np
import pytest

from flexvox_core import capture, code_from_order
from flexvox_core.design import design_code
from flexvox_core.forward import sample_mask, sparse_volume, tiled_order
from flexvox_core.motion import local_choice as cpu_choice
from flexvox_core.motion.options import STEP1_TENSOR, STEP1_TIME, MotionOptions
from flexvox_core.motion.stages import CpuStages, Window
from flexvox_core.reconstruct.diffusion import diffuse
from flexvox_core.reconstruct.oriented_nc import bank_index, oriented_nc, structure

CODE = code_from_order([[0, 2], [3, 1]])  # K = 4
TOL = 1e-6
"""Largest difference allowed between the GPU's and the CPU's values (all lie in [0, 1]); seen: 3e-7."""


def _scene(rng, F=2, H=8, W=10, *, code=CODE, dropped=None, gathered="partial"):
    """Inputs of the local choice as the stages hand them over: a moving edge on cosines, captured; the gather's
    result (the samples kept) and its leave-one-out (NaN where the sample's voxel is not gathered); the high-TR
    video; a flow with a share of voxels slower than the still-voxel speed."""
    K = code.shape[2]
    S = F * K
    t = np.arange(S, dtype=np.float32)[:, None, None]
    y = np.arange(H, dtype=np.float32)[None, :, None]
    x = np.arange(W, dtype=np.float32)[None, None, :]
    truth = (0.5 + 0.2 * np.cos(0.4 * x + 0.3 * y - 0.2 * t) + 0.2 * (x + 0.5 * y > W / 2 + 0.3 * t))
    truth = truth.astype(np.float32)
    frames = capture(truth, code)
    mask = sample_mask(truth.shape, code)
    missing = None
    if dropped is not None:
        missing = np.zeros(F, bool)
        missing[dropped] = True
        frames[dropped] = 0
        mask[dropped * K:(dropped + 1) * K] = False
    video = np.where(mask, sparse_volume(frames, code), truth + rng.normal(0, 0.03, truth.shape)).astype(np.float32)
    high_tr = diffuse(frames, code, tensor=STEP1_TENSOR, time=STEP1_TIME, missing=missing)
    flow = rng.normal(0, 0.3, (*truth.shape, 2)).astype(np.float32)
    chosen = {"partial": rng.random(truth.shape) < 0.6, "full": np.ones(truth.shape, bool),
              "empty": np.zeros(truth.shape, bool)}[gathered]
    order = tiled_order(code, H, W).astype(np.int32)
    loo = np.full(frames.shape, np.nan, np.float32)
    rows, cols = np.mgrid[0:H, 0:W]
    for f in range(F):
        if missing is None or not missing[f]:
            at = chosen[f * K + order, rows, cols]
            loo[f][at] = (frames[f] + rng.normal(0, 0.05, (H, W)))[at]
    present = np.ones(F, bool) if missing is None else ~missing
    return SimpleNamespace(frames=frames, code=code, K=K, mask=mask, missing=missing, present=present, video=video,
                           high_tr=high_tr, flow=flow, gathered=chosen, order=order, loo=loo)


def _device(sc):
    from numba import cuda

    def put(a, dtype):
        return cuda.to_device(np.ascontiguousarray(a, dtype))

    return SimpleNamespace(video=put(sc.video, np.float32), loo=put(sc.loo, np.float32),
                           gathered=put(sc.gathered, np.uint8), mask=put(sc.mask, np.uint8),
                           flow=put(sc.flow, np.float32), frames=put(sc.frames, np.float32),
                           order=put(sc.order, np.int32), present=put(sc.present, np.uint8),
                           high_tr=put(sc.high_tr, np.float32))


def _cpu_stage(sc, score_still_voxels: bool):
    """CpuStages.local_choice on copies of the scene's video and leave-one-out: (video, loo)."""
    # The default options' slow class holds every gathered voxel above 0.6 px per sub-frame: no still-voxel
    # scoring; without a slow class the gather's leave-one-out is corrected.
    options = MotionOptions(slow_speed=None) if score_still_voxels else MotionOptions()
    win = Window.plan(sc.frames, sc.code, options, (0.0, 1.0), missing=sc.missing)
    scores = not (options.slow_speed is not None and options.slow_speed >= cpu_choice.STILL_VOXEL_SPEED
                  and win.slow_class)
    assert scores == score_still_voxels
    engine = CpuStages(win)
    engine.mask = sc.mask
    video, loo = sc.video.copy(), sc.loo.copy()
    engine.local_choice(video, loo, sc.gathered, SimpleNamespace(flow=sc.flow), sc.high_tr)
    return video, loo


def _gpu_stage(sc, score_still_voxels: bool):
    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.local_choice import local_choice

    d = _device(sc)
    H, W = sc.frames.shape[1:]
    done = local_choice(Workspace(), d.video, d.loo, d.gathered, d.mask, d.flow, d.frames, d.order, d.present,
                        d.high_tr, sc.K, score_still_voxels=score_still_voxels,
                        still_speed=cpu_choice.STILL_VOXEL_SPEED, sigma=cpu_choice.pooling_sigma(H, W))
    return d.video.copy_to_host(), d.loo.copy_to_host(), done


def _close(got, want, tol=TOL):
    assert np.array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got, want, atol=tol, rtol=0)


# ------------------------------------------------------------------------------------------- the parts


def test_the_still_voxel_correction_matches_the_cpu(rng):
    from flexvox_core.motion.gpu.local_choice import still_voxel_loo

    sc = _scene(rng, 3, 10, 12, dropped=1)
    want = sc.loo.copy()
    cpu_choice.still_voxel_loo(want, sc.video, sc.frames, sc.gathered, sc.mask, sc.flow, sc.K)
    assert np.nanmax(np.abs(want - sc.loo)) > 0.01  # the correction changes the leave-one-out
    d = _device(sc)
    still_voxel_loo(d.loo, d.video, d.frames, d.gathered, d.mask, d.flow, speed=cpu_choice.STILL_VOXEL_SPEED)
    _close(d.loo.copy_to_host(), want)


@pytest.mark.parametrize("shape", [(10, 12), (6, 8)])
def test_the_structure_tensor_and_the_kernel_choice_match_the_cpu(rng, shape):
    from numba import cuda

    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.oriented_nc import structure_bank

    sc = _scene(rng, 2, *shape)
    S = sc.high_tr.shape[0]
    bank = cuda.device_array(sc.high_tr.shape, np.uint8)
    j = cuda.device_array((3, *sc.high_tr.shape), np.float32)
    structure_bank(Workspace(), cuda.to_device(sc.high_tr), bank, j)
    got_j, got_bank = j.copy_to_host(), bank.copy_to_host()
    want_j = np.stack([structure(sc.high_tr[s]) for s in range(S)], axis=1)
    # The gradients are differences of blurred values ~50 times larger: float32 rounding there is ~1e-6 of them.
    np.testing.assert_allclose(got_j, want_j, atol=1e-5 * np.abs(want_j).max(), rtol=0)  # seen: 1.5e-6
    np.testing.assert_array_equal(got_bank, bank_index(*want_j))
    np.testing.assert_array_equal(got_bank, bank_index(*got_j))  # the device's comparisons are the CPU's
    assert (got_bank == 0).any() and (got_bank > 8).any()  # isotropic and strongly oriented kernels both chosen


@pytest.mark.parametrize(("F", "dropped", "gathered"), [(2, None, "partial"), (3, 1, "full"), (2, 0, "empty")])
def test_oriented_nc_and_its_leave_one_out_match_the_cpu(rng, F, dropped, gathered):
    """With the CPU's kernel choice uploaded: oriented nc blended in with weight 0 is oriented nc itself."""
    from numba import cuda

    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.local_choice import OrientedPlan, oriented_blend, oriented_loo, time_blur

    sc = _scene(rng, F, dropped=dropped, gathered=gathered)
    want_video, want_loo = oriented_nc(sc.frames, sc.code, sc.high_tr, where=sc.gathered, fallback=sc.video,
                                       missing=sc.missing)
    S, H, W = sc.video.shape
    bank = np.stack([bank_index(*structure(sc.high_tr[s])) for s in range(S)]).astype(np.uint8)
    d = _device(sc)
    ws = Workspace()
    plan = OrientedPlan(ws, F, sc.K)
    vt, mt = time_blur(ws, d.frames, d.order, d.present, plan, S)
    loo = cuda.device_array((F, H, W), np.float32)
    bank_d = cuda.to_device(bank)
    oriented_loo(vt, mt, d.frames, d.order, d.present, d.gathered, bank_d, plan, loo)
    oriented_blend(d.video, vt, mt, d.frames, d.order, d.present, d.gathered, bank_d, plan,
                   cuda.to_device(np.zeros((F, H, W), np.float32)))
    got_video, got_loo = d.video.copy_to_host(), loo.copy_to_host()
    _close(got_loo, want_loo)
    _close(got_video, want_video)
    kept = sc.mask & sc.gathered
    np.testing.assert_array_equal(got_video[kept], sc.video[kept])  # the samples, exactly
    np.testing.assert_array_equal(got_video[~sc.gathered], sc.video[~sc.gathered])
    if gathered == "empty":
        assert np.isnan(got_loo).all()
    else:
        assert np.isfinite(got_loo).sum() > 0.5 * H * W
    if dropped is not None:
        assert np.isnan(got_loo[dropped]).all()


@pytest.mark.parametrize(("shape", "sigma"), [((3, 10, 12), 3.0),  # full size
                                              ((3, 6, 8), None),  # the default σ: 3 px
                                              ((3, 10, 14), 12.0),  # coarse grid 4×5, fractional cells
                                              ((3, 12, 15), 12.0),  # coarse grid 4×5, whole cells of 3×3
                                              ((2, 9, 11), 9.5)])  # coarse grid 5×6 of 2×2 and part cells
def test_the_pooled_weights_match_the_cpu(rng, shape, sigma):
    from numba import cuda

    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.local_choice_weights import coarse_step, local_weights

    y = rng.uniform(0.1, 0.9, shape).astype(np.float32)
    a = (y + rng.normal(0, 0.05, shape) * np.linspace(0.2, 2, shape[2])).astype(np.float32)
    b = (y + rng.normal(0, 0.05, shape) * np.linspace(2, 0.2, shape[2])).astype(np.float32)
    a[rng.random(shape) < 0.2] = np.nan
    b[rng.random(shape) < 0.2] = np.nan
    a[1] = np.nan  # a frame without a pixel both estimate: weight 1
    want = cpu_choice.local_weights(a, b, y, sigma=sigma)
    if sigma is None:
        sigma = cpu_choice.pooling_sigma(*shape[1:])
    out = cuda.device_array(shape, np.float32)
    local_weights(Workspace(), cuda.to_device(a), cuda.to_device(b), cuda.to_device(y), out, sigma=sigma)
    got = out.copy_to_host()
    np.testing.assert_allclose(got, want, atol=TOL, rtol=0)
    assert (got[1] == 1).all()
    assert np.ptp(got[0]) > 0.05  # the weights follow the errors across the picture
    assert (coarse_step(sigma) > 0) == (sigma > cpu_choice.COARSE_SIGMA)


# ------------------------------------------------------------------------------------------- the stage


@pytest.mark.parametrize(("F", "dropped", "gathered", "score", "coarse"),
                         [(2, None, "partial", True, False), (2, None, "partial", False, True),
                          (3, 1, "partial", True, False), (2, 1, "full", False, False)])
def test_the_stage_matches_the_cpu(rng, monkeypatch, F, dropped, gathered, score, coarse):
    if coarse:  # a pooling σ of 12 px, as a picture 192 px high has: the coarse grid on both sides
        monkeypatch.setattr(cpu_choice, "MIN_SIGMA", 12.0)
    sc = _scene(rng, F, dropped=dropped, gathered=gathered)
    want_video, want_loo = _cpu_stage(sc, score)
    got_video, got_loo, done = _gpu_stage(sc, score)
    assert done
    _close(got_loo, want_loo)
    _close(got_video, want_video)
    assert np.abs(want_video - sc.video).max() > 0.01  # the choice blends oriented nc in somewhere
    assert np.array_equal(np.isnan(want_loo), np.isnan(sc.loo))
    assert (np.nanmax(np.abs(want_loo - sc.loo)) > 0.01) == score  # the correction ran, or not


def test_nothing_to_choose_leaves_the_video(rng):
    sc = _scene(rng, 2, 6, 8, gathered="empty")
    assert np.isnan(sc.loo).all()
    want_video, _ = _cpu_stage(sc, True)
    got_video, got_loo, done = _gpu_stage(sc, True)
    assert not done
    np.testing.assert_array_equal(want_video, sc.video)
    np.testing.assert_array_equal(got_video, sc.video)
    assert np.isnan(got_loo).all()


def test_inputs_of_the_wrong_type_or_shape_are_refused(rng):
    from numba import cuda

    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.local_choice import local_choice
    from flexvox_core.motion.gpu.local_choice_weights import local_weights

    sc = _scene(rng, 2, 6, 8)
    d = _device(sc)
    bad = cuda.to_device(sc.gathered.astype(np.float32))
    with pytest.raises(ValueError, match=r"`gathered` must be uint8 \(8, 6, 8\) \(F = 2 frames, K = 4\); "
                                         r"got float32 \(8, 6, 8\)"):
        local_choice(Workspace(), d.video, d.loo, bad, d.mask, d.flow, d.frames, d.order, d.present, d.high_tr,
                     4, score_still_voxels=True, still_speed=0.15, sigma=3.0)
    with pytest.raises(ValueError, match=r"`video` must be float32 \(12, 6, 8\) \(F = 2 frames, K = 6\)"):
        local_choice(Workspace(), d.video, d.loo, d.gathered, d.mask, d.flow, d.frames, d.order, d.present,
                     d.high_tr, 6, score_still_voxels=True, still_speed=0.15, sigma=3.0)
    out = cuda.device_array(sc.frames.shape, np.float32)
    with pytest.raises(ValueError, match=r"`sigma` must be > 0 and `power` a whole number >= 1; got 0.0, 2"):
        local_weights(Workspace(), d.loo, d.loo, d.frames, out, sigma=0.0)
    with pytest.raises(ValueError, match=r"`loo_b` must be \(F, H, W\) = \(2, 6, 8\) like `out`; got \(8, 6, 8\)"):
        local_weights(Workspace(), d.loo, d.video, d.frames, out, sigma=3.0)


def test_the_gpu_constants_are_the_cpus():
    """flexvox_core.gpu does not import flexvox_core.motion (which imports it to pick the device): its copies of
    the pooling's constants must be the CPU's."""
    from flexvox_core.motion.gpu import local_choice_weights as choice_pool

    assert choice_pool.COARSE_SIGMA == cpu_choice.COARSE_SIGMA
    assert choice_pool.POWER == cpu_choice.POWER


@pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None, reason="numba-cuda is not installed")
# ------------------------------------------------------------------------------------------- on a card, full size


def _full_size(rng, **kw):
    return _scene(rng, 15, 480, 640, code=design_code((4, 4)).code, **kw)


@pytest.mark.gpu
@pytest.mark.parametrize(("dropped", "score"), [(None, False), (7, True)])
def test_full_size_stage_matches_the_cpu(rng, dropped, score):
    """F = 15, K = 16, 480×640 (pooling σ 30 px: the coarse grid). The kernel choice reads float32 structure
    tensors summed in another order than OpenCV's: a voxel whose tensor sits on a sector's edge may take the
    neighbouring kernel, so a few voxels may differ by more than the rounding (J perturbed by 2e-6 of itself
    changes the kernel of 3e-6 of the voxels of such a scene)."""
    sc = _full_size(rng, dropped=dropped)
    want_video, want_loo = _cpu_stage(sc, score)
    got_video, got_loo, done = _gpu_stage(sc, score)
    assert done
    _close(got_loo, want_loo)
    diff = np.abs(got_video - want_video)
    assert (diff > 1e-5).mean() < 1e-4, f"{(diff > 1e-5).sum()} voxels differ by more than 1e-5"
    assert float(np.median(diff)) < TOL


@pytest.mark.gpu
def test_full_size_kernel_choice_and_weights_match_the_cpu(rng):
    from numba import cuda

    from flexvox_core.gpu.volumes import Workspace
    from flexvox_core.motion.gpu.local_choice_weights import local_weights
    from flexvox_core.motion.gpu.oriented_nc import structure_bank

    sc = _full_size(rng)
    ws = Workspace()
    bank = cuda.device_array(sc.high_tr.shape, np.uint8)
    structure_bank(ws, cuda.to_device(sc.high_tr), bank)
    got = bank.copy_to_host()
    want = np.stack([bank_index(*structure(p)) for p in sc.high_tr])
    assert (got != want).mean() < 1e-4, f"{(got != want).sum()} voxels take another kernel"
    other = (sc.frames + rng.normal(0, 0.05, sc.frames.shape)).astype(np.float32)
    out = cuda.device_array(sc.frames.shape, np.float32)
    d = _device(sc)
    local_weights(ws, d.loo, cuda.to_device(other), d.frames, out, sigma=cpu_choice.pooling_sigma(*sc.frames.shape[1:]))
    np.testing.assert_allclose(out.copy_to_host(), cpu_choice.local_weights(sc.loo, other, sc.frames), atol=TOL,
                               rtol=0)
