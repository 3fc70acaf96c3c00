"""Motion-aware's GPU stages against the CPU stages they replace, under numba-cuda's simulator (tiny volumes)."""

import numpy as np
import pytest

from flexvox_core import capture, code_from_order
from flexvox_core.forward import sample_mask, sparse_volume
from flexvox_core.motion.gated_flow import gated_flow
from flexvox_core.motion.longreach import LongReachPlan, long_reach, long_reach_nc
from flexvox_core.motion.mcnc import motion_compensated_nc
from flexvox_core.motion.noise_aware import SmoothWeights, frame_noise, wide_sigma
from flexvox_core.motion.options import PERIOD_GATE
from flexvox_core.motion.stages import speed_classes
from flexvox_core.motion.vardiff import variable_tensor_diffusion
from flexvox_core.simulate.scenes import render_scene

CODE = code_from_order([[0, 2], [3, 1]])
K = 4


def _dev(a):
    from numba import cuda

    return cuda.to_device(np.ascontiguousarray(a))


@pytest.fixture
def ws():
    from flexvox_core.gpu.volumes import Workspace

    return Workspace()


@pytest.fixture
def clip(rng):
    """A tiny moving capture: (frames, sparse, mask, flow, truth) with flows from still to 1.5 px per sub-frame."""
    truth = render_scene("balls", 3 * K, 10, 12, seed=1)
    frames = capture(truth, CODE)
    sparse = sparse_volume(frames, CODE)
    mask = sample_mask(sparse.shape, CODE)
    flow = rng.normal(0, 0.8, (*sparse.shape, 2)).astype(np.float32)
    flow[:, :4] = 0  # a still band
    return frames, sparse, mask, flow, truth


@pytest.mark.parametrize("noisy", [False, True])
def test_trajectory_gather_is_the_cpus(rng, ws, clip, noisy):
    from flexvox_core.motion.gpu.mcnc import trajectory_gather
    from flexvox_core.motion.mcnc import default_reach

    frames, sparse, mask, flow, truth = clip
    S = len(sparse)
    gather = rng.random(sparse.shape) > 0.4
    base = rng.random(sparse.shape).astype(np.float32)
    fallback = rng.random(sparse.shape).astype(np.float32)
    wide = rng.random(sparse.shape).astype(np.float32) if noisy else None
    loo = np.full(frames.shape, np.nan, np.float32)
    want = motion_compensated_nc(sparse, mask, flow, time=5.0, fallback=fallback, still=~gather, still_value=base,
                                 loo=loo, wide=list(wide) if noisy else None, wide_sigma=wide_sigma(K))
    out = _dev(base)
    loo_d = _dev(np.full(frames.shape, np.nan, np.float32))
    trajectory_gather(ws, _dev(sparse), _dev(mask.astype(np.uint8)), _dev(flow), _dev(gather.astype(np.uint8)), out,
                      _dev(fallback), time=5.0, c1=0.95, c2=0.05, reach=default_reach(5.0, 0.95, K, S),
                      wide=_dev(wide) if noisy else None, wide_sigma=wide_sigma(K), loo=loo_d)
    got = out.copy_to_host()
    # OpenCV's remap rounds positions to 1/32 px; the GPU reads exactly.
    np.testing.assert_allclose(got, want, atol=3e-3)
    assert np.abs(got - want).mean() < 3e-4
    got_loo = loo_d.copy_to_host()
    np.testing.assert_array_equal(np.isnan(got_loo), np.isnan(loo))
    np.testing.assert_allclose(got_loo[np.isfinite(loo)], loo[np.isfinite(loo)], atol=5e-3)


@pytest.mark.parametrize("noisy", [False, True])
def test_trajectory_gather_is_the_cpus_from_the_frames(rng, ws, clip, noisy):
    """The CPU's gather from the frames and the code reads positions exactly, as the GPU does: the same video and
    leave-one-out up to float32 sums in another order."""
    from flexvox_core.motion.gpu.mcnc import trajectory_gather
    from flexvox_core.motion.mcnc import default_reach
    from flexvox_core.motion.mcnc import trajectory_gather as cpu_gather

    frames, sparse, mask, flow, truth = clip
    S = len(sparse)
    gather = rng.random(sparse.shape) > 0.4
    base = rng.random(sparse.shape).astype(np.float32)
    fallback = rng.random(sparse.shape).astype(np.float32)
    wide = rng.random(sparse.shape).astype(np.float32) if noisy else None
    reach = default_reach(5.0, 0.95, K, S)
    loo = np.full(frames.shape, np.nan, np.float32)
    want = cpu_gather(frames, CODE, flow, time=5.0, fallback=fallback, gathered=gather, still_value=base, loo=loo,
                      wide=list(wide) if noisy else None, wide_sigma=wide_sigma(K), max_reach=reach)
    out = _dev(base)
    loo_d = _dev(np.full(frames.shape, np.nan, np.float32))
    trajectory_gather(ws, _dev(sparse), _dev(mask.astype(np.uint8)), _dev(flow), _dev(gather.astype(np.uint8)), out,
                      _dev(fallback), time=5.0, c1=0.95, c2=0.05, reach=reach, wide=_dev(wide) if noisy else None,
                      wide_sigma=wide_sigma(K), loo=loo_d)
    np.testing.assert_allclose(out.copy_to_host(), want, atol=5e-6)
    got_loo = loo_d.copy_to_host()
    np.testing.assert_array_equal(np.isnan(got_loo), np.isnan(loo))
    np.testing.assert_allclose(got_loo[np.isfinite(loo)], loo[np.isfinite(loo)], atol=2e-5)
    assert np.isfinite(loo).any()


@pytest.mark.parametrize("missing", [None, [False, True, False]])
def test_long_reach_is_the_cpus(rng, ws, clip, missing):
    from flexvox_core.codes import order_from_code
    from flexvox_core.forward import tiled_order
    from flexvox_core.motion.gpu.longreach import long_reach as gpu_long_reach
    from flexvox_core.motion.longreach_kernel import corner_table

    frames, sparse, mask, flow, truth = clip
    flow = flow * np.float32(0.3)
    select = (rng.random(sparse.shape) > 0.5) & ~mask
    guide = np.clip(truth + rng.normal(0, 0.05, truth.shape), 0, 1).astype(np.float32)
    plan = LongReachPlan.of(sparse.shape[0], reach=6, sigma_t=6, sigma_s=0.3, h=0.1)
    miss = None if missing is None else np.array(missing)
    want = long_reach(frames, CODE, flow, guide, select, plan, missing=miss, write_samples=True)
    present = np.ones(len(frames), np.uint8) if miss is None else (~miss).astype(np.uint8)
    video = _dev(guide)
    gpu_long_reach(ws, _dev(frames), _dev(tiled_order(CODE, *frames.shape[1:]).astype(np.int32)), _dev(present),
                   corner_table(order_from_code(CODE)), _dev(flow), video, _dev(select.astype(np.uint8)), plan)
    got = video.copy_to_host()
    np.testing.assert_allclose(got, want, atol=2e-6, rtol=0)  # the same reads and sums; float32 rounding
    assert np.abs(got - guide)[select].max() > 0.01  # the gather did something
    # and the remap gather it replaced, to that one's 1/32 px rounding of the positions
    old = long_reach_nc(sparse, mask, flow, guide, select, reach=6, sigma_t=6, sigma_s=0.3, h=0.1)
    np.copyto(old, sparse, where=mask)
    if miss is None:
        np.testing.assert_allclose(got, old, atol=5e-3)
        assert np.abs(got - old).mean() < 5e-4


def test_refinement_is_the_cpus(rng, ws, clip):
    from flexvox_core.motion.gpu.vardiff import refine
    from flexvox_core.motion.options import REFINE_C

    frames, sparse, mask, flow, truth = clip
    init = rng.random(sparse.shape).astype(np.float32)
    sharp = rng.random(sparse.shape) > 0.5
    want = variable_tensor_diffusion(init, mask, flow, c=REFINE_C, time=1.0, sharp=sharp)
    video = _dev(init)
    refine(ws, video, _dev(mask.astype(np.uint8)), _dev(flow), _dev(sharp.astype(np.uint8)), c=REFINE_C, time=1.0)
    np.testing.assert_allclose(video.copy_to_host(), want, atol=2e-6)
    # A window of the volume, as the engine refines only the gathered sub-frames.
    video = _dev(init)
    refine(ws, video[4:8], _dev(mask.astype(np.uint8))[4:8], _dev(flow)[4:8], _dev(sharp.astype(np.uint8))[4:8],
           c=(0.95, 0.05, 0.02), time=0.5)
    want = init.copy()
    want[4:8] = variable_tensor_diffusion(init[4:8], mask[4:8], flow[4:8], c=(0.95, 0.05, 0.02), time=0.5,
                                          sharp=sharp[4:8])
    np.testing.assert_allclose(video.copy_to_host(), want, atol=2e-6)
    # The voxels slower than a still speed taken as still: half of them here (a speed between two voxels').
    speeds = np.unique(np.hypot(flow[..., 0].astype(np.float64), flow[..., 1].astype(np.float64)))
    still = float(speeds[len(speeds) // 2] + speeds[len(speeds) // 2 + 1]) / 2
    want = variable_tensor_diffusion(init, mask, flow, c=REFINE_C, time=1.0, sharp=sharp, still_speed=still)
    assert not np.array_equal(want, variable_tensor_diffusion(init, mask, flow, c=REFINE_C, time=1.0, sharp=sharp))
    video = _dev(init)
    refine(ws, video, _dev(mask.astype(np.uint8)), _dev(flow), _dev(sharp.astype(np.uint8)), c=REFINE_C, time=1.0,
           still_speed=still)
    np.testing.assert_allclose(video.copy_to_host(), want, atol=2e-6)


def test_speed_classes_are_the_cpus(rng, ws, clip):
    from flexvox_core.motion.gpu.gated_flow import speed_classes as gpu_classes

    flow = clip[3] * np.float32(0.5)
    S = len(flow)
    skip = np.zeros(S, bool)
    skip[-3:] = True
    still, slow, gathered = speed_classes(flow, 0.2, 0.6, skip)
    assert still.any() and slow.any() and gathered.any() and not (slow[skip].any() or gathered[skip].any())
    np.testing.assert_array_equal(gathered, ~(still | slow | skip[:, None, None]))
    d = [_dev(np.zeros(still.shape, np.uint8)) for _ in range(3)]
    counts = gpu_classes(ws, _dev(flow), 0.2, 0.6, skip, *d)
    g_still, g_slow, g_gather = (a.copy_to_host().astype(bool) for a in d)
    np.testing.assert_array_equal(g_still, still)
    np.testing.assert_array_equal(g_slow, slow)
    np.testing.assert_array_equal(g_gather, gathered)
    assert counts == (int(still.sum()), int(slow.sum()))
    for still_speed, slow_speed in ((None, 0.6), (0.2, None), (None, None)):  # a class that does not exist
        still, slow, gathered = speed_classes(flow, still_speed, slow_speed)
        counts = gpu_classes(ws, _dev(flow), still_speed, slow_speed, None, *d)
        for want, got in zip((still, slow, gathered), d, strict=True):
            np.testing.assert_array_equal(got.copy_to_host().astype(bool), want)
        assert (still_speed is not None or not still.any()) and (slow_speed is not None or not slow.any())


@pytest.mark.parametrize("pixels", ["all still", "some still", "too few"])
def test_the_noise_median_is_selected_exactly(rng, ws, pixels):
    from flexvox_core.motion.gpu.noise_aware import frame_noise as gpu_noise

    F, H, W = 4, 16, 16
    frames = rng.random((F, H, W)).astype(np.float32)
    mask = sample_mask((F * K, H, W), CODE)
    still = np.ones(mask.shape, bool) if pixels == "all still" else rng.random(mask.shape) > 0.3
    if pixels == "too few":
        still[:] = False
        still[:, :3, :3] = True  # 9 pixels a frame: fewer than MIN_PIXELS
    want = frame_noise(frames, still, mask, K)
    got = gpu_noise(ws, _dev(frames), _dev(still.astype(np.uint8)), _dev(mask.astype(np.uint8)), K)
    np.testing.assert_allclose(got, want, rtol=1e-6)
    assert got.any() if pixels != "too few" else not got.any()


def test_noise_weights_are_the_cpus(rng, ws, clip):
    from flexvox_core.motion.gpu.noise_aware import noise_weights

    frames, sparse, mask, flow, truth = clip
    noisy = np.clip(frames + rng.normal(0, 0.03, frames.shape), 0, 1).astype(np.float32)
    still = np.ones(sparse.shape, bool)
    noise = frame_noise(noisy, still, mask, K)
    assert noise.any()
    current = truth.astype(np.float32)
    cpu = SmoothWeights(current, np.repeat(noise, K))
    out = _dev(np.zeros(sparse.shape, np.float32))
    dev = (_dev(still.astype(np.uint8)), _dev(mask.astype(np.uint8)))
    assert noise_weights(ws, _dev(noisy), _dev(current), *dev, K, out)
    np.testing.assert_allclose(out.copy_to_host(), np.stack([cpu[t] for t in range(len(sparse))]), atol=2e-5)
    # A noiseless capture (every difference 0): no weights.
    assert not noise_weights(ws, _dev(frames), _dev(current), *dev, K, out)


def test_gated_flow_is_the_cpus(ws):
    """The gate, the K-average's velocity and the resizes, with the pairs' DIS on the host as the CPU runs it."""
    from flexvox_core.motion.gated_flow import DETECTOR_DIS_PARAMS, DIS_PARAMS
    from flexvox_core.motion.gpu.gated_flow import PairFlow
    from flexvox_core.motion.gpu.gated_flow import gated_flow as gpu_gated

    video = render_scene("pan", 6 * K, 20, 24, seed=2)
    want = gated_flow(video, K, backend="dis", scale=0.8, slow_speed=0.6, period_gate=PERIOD_GATE).flow
    out = _dev(np.zeros((*video.shape, 2), np.float32))
    gpu_gated(ws, _dev(video), K, gate=(0.03, 0.15), scale=0.8, slow_speed=0.6, period_gate=PERIOD_GATE,
              pair_flow=PairFlow(ws, "cpu", DIS_PARAMS), detector_flow=PairFlow(ws, "cpu", DETECTOR_DIS_PARAMS),
              out=out)
    np.testing.assert_allclose(out.copy_to_host(), want, atol=2e-4)


@pytest.mark.parametrize("shape, finest", [((80, 106), 2), ((48, 64), 1), ((20, 24), 0)])
def test_pair_flows_dis_searches_the_level_the_cpus_does(ws, shape, finest):
    # A finest_scale coarser than the images' coarsest level is clamped there, on both engines (the CPU's DisFlow).
    from flexvox_core.flow.backends import dis_finest_scale
    from flexvox_core.motion.gated_flow import DIS_PARAMS
    from flexvox_core.motion.gpu.gated_flow import PairFlow

    assert PairFlow(ws, "gpu", {**DIS_PARAMS, "finest_scale": 2}).params_for(shape).finest_scale == finest
    assert dis_finest_scale(shape, 2, 8) == finest
    assert PairFlow(ws, "gpu", DIS_PARAMS).params_for(shape).finest_scale == 1  # the preset's, as OpenCV's own


def test_pair_flow_refuses_an_unknown_place(ws):
    from flexvox_core.motion.gpu.gated_flow import PairFlow

    with pytest.raises(ValueError, match=r"`pairs` must be one of gpu, cpu; got 'tpu'"):
        PairFlow(ws, "tpu", {})


@pytest.mark.parametrize("lost", [[False, True, False, False], [True, False, True, True], [False, False, True, True]])
def test_dropped_frames_are_bridged_as_on_the_cpu(rng, lost):
    from flexvox_core.gaps import bridge, bridge_flow
    from flexvox_core.motion.gpu import gaps

    missing = np.array(lost)
    video = rng.random((4 * K, 6, 7)).astype(np.float32)
    flow = rng.normal(0, 1.5, (*video.shape, 2)).astype(np.float32)
    want_flow = flow.copy()
    bridge_flow(want_flow, missing, K, margin=K // 2)
    want = video.copy()
    bridge(want, missing, K, flow=want_flow)
    v, f = _dev(video), _dev(flow)
    gaps.bridge_flow(f, missing, K, K // 2)
    np.testing.assert_allclose(f.copy_to_host()[~np.repeat(missing, K)], want_flow[~np.repeat(missing, K)],
                               atol=1e-6)
    gaps.bridge(v, f, missing, K)
    np.testing.assert_allclose(f.copy_to_host(), want_flow, atol=1e-5)
    # OpenCV's remap rounds positions to 1/32 px.
    np.testing.assert_allclose(v.copy_to_host(), want, atol=0.02)
    assert np.abs(v.copy_to_host() - want).mean() < 2e-3


def test_both_engines_implement_the_stages_protocol_with_the_same_signatures():
    """Every method of :class:`Stages` is on :class:`CpuStages` and :class:`CudaStages` with its signature (names,
    kinds, defaults and annotations), and both set the protocol's attributes."""
    import inspect
    import typing

    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.stages import CpuStages, Stages

    methods = [n for n, v in vars(Stages).items() if inspect.isfunction(v) and not n.startswith("_")]
    assert set(methods) >= {"sync", "high_tr", "gated_flow", "trajectory_gather", "local_choice", "gaps", "result"}
    for engine in (CpuStages, CudaStages):
        for name in methods:
            assert inspect.signature(getattr(engine, name)) == inspect.signature(getattr(Stages, name)), (engine, name)
        assert engine.device in ("cpu", "cuda")
    assert set(typing.get_type_hints(Stages)) == {"device", "window"}
    assert list(inspect.signature(CudaStages.__init__).parameters)[:2] == ["self", "window"]


@pytest.mark.slow_sim
def test_the_gpu_engine_sets_its_state_in_init():
    """A stage sets no attribute that ``__init__`` did not: what a stage leaves for the next is declared there."""
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.options import MotionOptions
    from flexvox_core.motion.stages import Window, run_stages
    from tests.flexvox_core.gpu.tiny import CODE, tiny_capture

    _, frames = tiny_capture("balls", 2, 8, 8)
    engine = CudaStages(Window.plan(frames, CODE, MotionOptions(passes=2), (0.0, 1.0)))
    declared = set(vars(engine))
    generation = engine.ws.generation
    run_stages(engine)
    assert set(vars(engine)) == declared
    assert engine.generation == generation and engine.passes_run == 2
