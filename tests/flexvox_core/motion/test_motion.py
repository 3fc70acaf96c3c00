"""Motion-aware reconstruction: limiting cases and numerical stability on hard flows."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flexvox_core.design import design_code
from flexvox_core.forward import capture, sample_mask, sparse_volume
from flexvox_core.motion import (
    motion_aware,
    motion_compensated_nc,
    resolution_map,
    tensor_field,
    variable_tensor_diffusion,
)
from flexvox_core.planes import band
from flexvox_core.reconstruct.diffusion import diffuse
from flexvox_core.simulate.scenes import render_scene

CODE = design_code((2, 4)).code  # K = 8


@pytest.fixture
def capture_case(rng):
    truth = rng.uniform(0.2, 0.8, (8 * 3, 12, 16)).astype(np.float32)
    frames = capture(truth, CODE)
    return truth, frames, sparse_volume(frames, CODE), sample_mask(truth.shape, CODE)


def test_tensor_of_zero_flow_is_the_fixed_tensor():
    T = tensor_field(np.zeros((2, 3, 2)), (0.95, 0.05, 0.05))
    assert np.allclose(T, np.diag([0.05, 0.05, 0.95]))


def test_tensor_eigen_structure():
    T = tensor_field(np.array([[3.0, -4.0]]), (0.9, 0.3, 0.1))[0]
    lam = np.array([3.0, -4.0, 1.0]) / np.sqrt(26)
    assert np.allclose(T @ lam, 0.9 * lam, atol=1e-6)
    assert np.allclose(np.linalg.eigvalsh(T.astype(np.float64)), [0.1, 0.3, 0.9], atol=1e-6)


def test_zero_flow_gives_the_fixed_tensor_nc(capture_case):
    _, frames, sparse, mask = capture_case
    zero = np.zeros((*sparse.shape, 2), np.float32)
    got = motion_compensated_nc(sparse, mask, zero, c=(0.95, 0.05, 0.05), time=2.0)
    want = diffuse(frames, CODE, tensor=(0.05, 0.05, 0.95), time=2.0)
    # Away from the video's ends (nc reflects time there; a trajectory cannot be reflected).
    # The gather drops trajectory weights below CUTOFF (1e-3 of the voxel's own): within 1e-4.
    assert np.allclose(got[8:16], want[8:16], atol=1e-4)


def hard_flows(shape, rng):
    S, H, W = shape
    yield "huge (50 px per sub-frame)", np.full((S, H, W, 2), 50.0, np.float32)
    nan = rng.normal(0, 2, (S, H, W, 2)).astype(np.float32)
    nan[::2, ::3] = np.nan
    nan[1::3, ::2, :, 0] = np.inf
    yield "NaN and inf", nan
    out = np.zeros((S, H, W, 2), np.float32)
    out[..., 0] = -30.0  # everything leaves through the left border
    yield "out of the image", out
    occl = np.zeros((S, H, W, 2), np.float32)
    occl[:, :, W // 2:, 0] = 3.0  # an occlusion boundary down the middle
    yield "occlusion boundary", occl


@pytest.mark.parametrize("kind", ["mcnc", "vardiff"])
def test_hard_flows_stay_finite_and_within_the_sample_range(capture_case, rng, kind):
    _, frames, sparse, mask = capture_case
    lo, hi = frames.min(), frames.max()
    init = diffuse(frames, CODE, tensor=(1, 1, 0.05), time=2.0)
    for name, flow in hard_flows(sparse.shape, rng):
        if kind == "mcnc":
            out = motion_compensated_nc(sparse, mask, flow, time=2.0, fallback=init)
        else:
            out = variable_tensor_diffusion(init, mask, flow, time=1.5)
        assert np.isfinite(out).all(), name
        assert out.min() >= lo - 1e-6 and out.max() <= hi + 1e-6, name


@given(st.floats(-8, 8), st.floats(-8, 8), st.floats(0.05, 4.0), st.sampled_from([(0.95, 0.05, 0.05), (1, 1, 1),
                                                                                   (1, 0.5, 0), (0.3, 0.1, 0.01)]))
def test_variable_diffusion_keeps_the_maximum_principle(u, v, n, c):
    rng = np.random.default_rng(1)
    init = rng.random((6, 9, 11)).astype(np.float32)
    mask = rng.random(init.shape) < 0.2
    flow = np.empty((*init.shape, 2), np.float32)
    flow[..., 0], flow[..., 1] = u, v
    out = variable_tensor_diffusion(init, mask, flow, c=c, time=n)
    assert np.isfinite(out).all()
    assert out.min() >= init.min() - 1e-6 and out.max() <= init.max() + 1e-6
    assert np.array_equal(out[mask], init[mask])  # data consistency


def test_constant_video_is_unchanged(rng):
    frames = np.full((3, 10, 12), 0.4, np.float32)
    r = motion_aware(frames, CODE)
    assert np.allclose(r.video, 0.4, atol=1e-6)


def test_motion_aware_on_a_moving_scene_outputs_everything():
    truth = render_scene("balls", 8 * 4, 40, 48)
    r = motion_aware(capture(truth, CODE), CODE)
    assert r.video.shape == truth.shape and np.isfinite(r.video).all()
    assert r.flow.flow.shape == (*truth.shape, 2) and r.tr.shape == truth.shape
    assert r.tr.min() >= 1 - 1e-6 and r.tr.max() <= 8 + 1e-6
    assert np.allclose(r.tr * r.sr, 1, atol=1e-5)
    assert set(r.seconds) == {"high_tr", "flow", "diffusion"}


def test_resolution_map_limits():
    still, _ = resolution_map(np.zeros((2, 2, 2)), 16)
    fast, _ = resolution_map(np.full((2, 2, 2), 100.0), 16)
    assert still.max() < 2 and fast.min() > 12


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"passes": 0}, r"`passes` must be a whole number >= 1; got 0"),
        ({"time": 0}, r"`time` must be a finite number > 0; got 0"),
        ({"c": (0.05, 0.95, 0.05)}, r"`c` must satisfy c1 >= c2 >= c3 >= 0"),
        ({"flow": "magic"}, r"`flow` must be one of dis, deepflow, farneback, tvl1; got 'magic'"),
        ({"gate": (0.5, 0.1)}, r"`gate` must be two thresholds"),
        ({"flow_scale": 0}, r"`flow_scale` must be in \(0, 1\] or None; got 0"),
        ({"sample_range": (0.6, 1.0)},
         r"`sample_range` \(0.6, 1.0\) must be finite and contain the frames' values \[0.5, 0.5\]"),
        ({"sample_range": (0.0, np.inf)}, r"`sample_range` .* must be finite"),
        ({"sample_range": "ab"}, r"`sample_range` must be two numbers \(lo, hi\) or None; got 'ab'"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        motion_aware(np.full((2, 8, 8), 0.5, np.float32), CODE, **kwargs)


def test_still_voxels_shortcut_keeps_the_moving_ones_exact(capture_case, rng):
    truth, frames, sparse, mask = capture_case
    flow = np.zeros((*sparse.shape, 2), np.float32)
    flow[:, 3:8, 4:10] = [1.5, -0.5]  # a moving patch
    full = motion_compensated_nc(sparse, mask, flow, time=2.0)
    still = np.hypot(flow[..., 0], flow[..., 1]) < 0.1
    still_value = diffuse(frames, CODE, tensor=(0.05, 0.05, 0.95), time=2.0)
    fast = motion_compensated_nc(sparse, mask, flow, time=2.0, still=still, still_value=still_value)
    assert np.allclose(fast[~still], full[~still], atol=1e-6)
    assert np.array_equal(fast[still & ~mask], still_value[still & ~mask])
    with pytest.raises(ValueError, match=r"`still` and `still_value` go together"):
        motion_compensated_nc(sparse, mask, flow, time=2.0, still=still)
    # The gathered voxels instead of their complement: the same bits.
    loo_still, loo_gathered = (np.full(frames.shape, np.nan, np.float32) for _ in range(2))
    want = motion_compensated_nc(sparse, mask, flow, time=2.0, still=still, still_value=still_value, loo=loo_still)
    got = motion_compensated_nc(sparse, mask, flow, time=2.0, gathered=~still, still_value=still_value,
                                loo=loo_gathered)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(loo_gathered, loo_still)
    assert np.isfinite(loo_still).any()
    with pytest.raises(ValueError, match=r"`gathered` and `still_value` go together"):
        motion_compensated_nc(sparse, mask, flow, time=2.0, gathered=~still)
    with pytest.raises(ValueError, match=r"`still` and `gathered` say the same .*: give one"):
        motion_compensated_nc(sparse, mask, flow, time=2.0, still=still, gathered=~still, still_value=still_value)


def test_automatic_flow_scale_puts_the_shorter_side_near_160_px():
    from flexvox_core.motion.pipeline import auto_flow_scale

    assert auto_flow_scale(96, 128) == 1.0  # never upsampled
    assert auto_flow_scale(480, 640) == pytest.approx(1 / 3)
    assert auto_flow_scale(256, 256) == pytest.approx(0.625)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), speed=st.floats(0, 4), time=st.floats(0, 2),
       c=st.sampled_from([(0.95, 0.05, 0.05), (0.95, 0.3, 0.0), (1.0, 0.0, 0.0), (0.5, 0.5, 0.5)]),
       keep=st.booleans(), sharp=st.sampled_from([None, 0.5, 1.0]))
def test_the_compiled_variable_diffusion_is_the_numpy_reference(seed, speed, time, c, keep, sharp):
    from tests.flexvox_core.motion.vardiff_reference import variable_tensor_diffusion_reference

    rng = np.random.default_rng(seed)
    init = rng.uniform(0.2, 0.8, (6, 9, 11)).astype(np.float32)
    mask = rng.random(init.shape) < 0.2
    flow = rng.normal(0, speed + 1e-3, (*init.shape, 2)).astype(np.float32)
    flow[0, 0, 0, 1] = np.nan  # an unmeasured vector counts as no motion
    if sharp is not None:  # these voxels read their trajectory neighbours by clipped Catmull-Rom
        sharp = rng.random(init.shape) < sharp
    got = variable_tensor_diffusion(init, mask, flow, c=c, time=time, keep_samples=keep, sharp=sharp)
    expected = variable_tensor_diffusion_reference(init, mask, flow, c=c, time=time, keep_samples=keep, sharp=sharp)
    np.testing.assert_allclose(got, expected, atol=2e-6)
    # Monotone: every value stays within the starting range (maximum principle).
    assert got.min() >= init.min() - 1e-6 and got.max() <= init.max() + 1e-6
    if keep:
        np.testing.assert_array_equal(got[mask], init[mask])


@pytest.mark.parametrize("time", [0.0, 0.5, 1.0, 1.5, 2.5])  # 0-5 explicit steps: odd and even counts
def test_the_variable_diffusion_may_write_into_its_own_input(time):
    rng = np.random.default_rng(7)
    init = rng.uniform(0.2, 0.8, (6, 9, 11)).astype(np.float32)
    mask = rng.random(init.shape) < 0.2
    flow = rng.normal(0, 1, (*init.shape, 2)).astype(np.float32)
    expected = variable_tensor_diffusion(init, mask, flow, time=time)
    other = np.empty_like(init)
    assert variable_tensor_diffusion(init, mask, flow, time=time, out=other) is other
    np.testing.assert_array_equal(other, expected)
    same = init.copy()
    variable_tensor_diffusion(same, mask, flow, time=time, out=same)  # what motion_aware does
    np.testing.assert_array_equal(same, expected)


def test_sharp_reads_keep_a_slowly_drifting_texture():
    # Texture drifting 0.3 px per sub-frame, its true flow, the truth as the start: each bilinear read a
    # fraction of a pixel off blurs it; the clipped Catmull-Rom reads (`sharp`) keep it.
    from scipy.ndimage import gaussian_filter, map_coordinates

    rng = np.random.default_rng(0)
    S, H, W = 32, 24, 40
    texture = gaussian_filter(rng.random((H, 4 * W)), 0.8)
    rows, cols = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    truth = np.stack([map_coordinates(texture, [rows, cols + 0.3 * t + 20], order=3) for t in range(S)])
    truth = truth.astype(np.float32)
    mask = sample_mask(truth.shape, design_code((4, 4)).code)
    flow = np.zeros((S, H, W, 2), np.float32)
    flow[..., 0] = -0.3

    def error(sharp):
        out = variable_tensor_diffusion(truth, mask, flow, c=(0.95, 0.0, 0.0), time=1.0, sharp=sharp)
        assert truth.min() <= out.min() and out.max() <= truth.max()  # still within the data's range
        return float(((out - truth)[:, 4:-4, 4:-4] ** 2).mean())

    assert error(np.ones(truth.shape, bool)) < 0.5 * error(None)
    with pytest.raises(ValueError, match=r"`sharp` \(2, 24, 40\) must match `init` \(32, 24, 40\)"):
        variable_tensor_diffusion(truth, mask, flow, time=1.0, sharp=np.ones((2, H, W), bool))


def test_motion_aware_refines_its_slow_voxels_with_sharp_reads(monkeypatch):
    # The voxels of the long-reach gather (slow, not still) are the refinement's `sharp` ones.
    import flexvox_core.motion.stages as stages

    seen = {}
    real = stages.variable_tensor_diffusion
    real_classes = stages.packed_speed_classes

    def spy_classes(*args):
        seen["classes"] = real_classes(*args)
        return seen["classes"]

    def spy(*args, **kwargs):
        seen["sharp"] = kwargs["sharp"]
        return real(*args, **kwargs)

    monkeypatch.setattr(stages, "packed_speed_classes", spy_classes)
    monkeypatch.setattr(stages, "variable_tensor_diffusion", spy)
    truth = render_scene("pan", 6 * 16, 48, 64, seed=0)
    code = design_code((4, 4)).code
    motion_aware(capture(truth, code), code)
    still, slow, _ = seen["classes"]
    assert slow.any()
    np.testing.assert_array_equal(band(seen["sharp"], 0, slow.shape[0]), slow.band(0, slow.shape[0]))


def test_the_compiled_variable_diffusion_gives_the_same_bits_on_any_thread_count():
    import numba

    rng = np.random.default_rng(5)
    init = rng.random((8, 16, 20)).astype(np.float32)
    mask = rng.random(init.shape) < 0.1
    flow = rng.normal(0, 1.5, (*init.shape, 2)).astype(np.float32)
    saved = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = variable_tensor_diffusion(init, mask, flow, time=1.0)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        assert np.array_equal(variable_tensor_diffusion(init, mask, flow, time=1.0), one)
    finally:
        numba.set_num_threads(saved)


def test_the_gather_may_write_into_its_still_values(capture_case):
    truth, frames, sparse, mask = capture_case
    flow = np.zeros((*sparse.shape, 2), np.float32)
    flow[:, 3:8, 4:10] = [1.5, -0.5]
    still = np.hypot(flow[..., 0], flow[..., 1]) < 0.1
    still_value = diffuse(frames, CODE, tensor=(0.05, 0.05, 0.95), time=2.0)
    want = motion_compensated_nc(sparse, mask, flow, time=2.0, still=still, still_value=still_value)
    into = still_value.copy()
    got = motion_compensated_nc(sparse, mask, flow, time=2.0, still=still, still_value=into, out=into)
    assert got is into
    np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError, match="`out` must not share memory"):
        motion_compensated_nc(sparse, mask, flow, time=2.0, out=sparse)


@pytest.mark.parametrize("passes", [1, 2])
def test_still_values_written_in_place_give_the_volumes_result(monkeypatch, passes):
    # motion_aware writes the still voxels' values into the fixed-tensor guide, and the gather into that,
    # instead of two more volumes: the same bits as with them.
    import flexvox_core.motion.stages as P

    code = design_code((4, 4)).code
    truth = render_scene("balls", 16 * 4, 40, 52)
    frames = capture(truth, code)
    got = motion_aware(frames, code, passes=passes).video

    def volume_then_copy(frames, code, out, where, *, tensor, time, missing):
        chosen = P.band(where, 0, len(out))  # the still voxels, held a bit per voxel
        np.copyto(out, diffuse(frames, code, tensor=tensor, time=time, missing=missing), where=chosen)
        return out

    def fresh_out(*args, out=None, **kwargs):
        return gather(*args, **kwargs)

    gather = P.trajectory_gather
    monkeypatch.setattr(P, "diffuse_where", volume_then_copy)
    monkeypatch.setattr(P, "trajectory_gather", fresh_out)
    np.testing.assert_array_equal(got, motion_aware(frames, code, passes=passes).video)


def test_motion_aware_measures_its_flow_with_two_variational_iterations(monkeypatch):
    # Every DIS pair of motion-aware's flow (successive sub-frames, K-averages) refines with DIS_PARAMS, the
    # detector's (the K-average's steps) with DETECTOR_DIS_PARAMS, and the result's flow parameters say so.
    import flexvox_core.motion.gated_flow as pipeline
    from flexvox_core.motion.gated_flow import DETECTOR_DIS_PARAMS, DIS_PARAMS

    built = []
    real = pipeline.make_backend

    def spy(name="dis", **params):
        built.append((name, params))
        return real(name, **params)

    monkeypatch.setattr(pipeline, "make_backend", spy)
    truth = render_scene("balls", 3 * 16, 32, 48, seed=0)
    code = design_code((4, 4)).code
    result = motion_aware(capture(truth, code), code)
    measuring = [params for name, params in built if name == "dis" and params]
    assert measuring == [DIS_PARAMS, DETECTOR_DIS_PARAMS] == [{"variational_iterations": 2}] * 2
    assert result.flow.params["variational_iterations"] == 2


def _whole_volume_local_choice(self, video, loo, gathered, flow, high_tr):
    """The local choice as it ran before it ran in bands: oriented nc into a whole volume, then one blend."""
    from flexvox_core.motion import local_choice
    from flexvox_core.reconstruct.oriented_nc import oriented_nc

    w = self.window
    if not np.isfinite(loo).any():
        return
    gathered = band(gathered, 0, w.S)  # the whole bool volume, as it was held then
    if w.scores_still_voxels:
        local_choice.still_voxel_loo(loo, video, w.frames, gathered, self._mask(), flow.flow, w.K)
    other, other_loo = oriented_nc(w.frames, w.code, high_tr, where=gathered, fallback=video, missing=w.missing)
    local_choice.blend(video, other, local_choice.local_weights(loo, other_loo, w.frames), gathered, w.K)


@pytest.mark.parametrize("dropped", [False, True])
def test_the_local_choice_in_bands_gives_the_whole_volumes_bits(monkeypatch, dropped):
    import flexvox_core.motion.stages as P

    code = design_code((4, 4)).code
    frames = capture(render_scene("balls", 16 * 5, 40, 52, seed=1), code)
    missing = np.array([False, False, True, False, False]) if dropped else None
    banded = []
    for least, threads in ((1, 1), (32, 1), (1, 40)):  # a frame a band; two frames (the last band one); all in one
        monkeypatch.setattr(P.local_choice, "BAND", least)
        monkeypatch.setattr(P, "workers", lambda threads=threads: threads)
        banded.append(motion_aware(frames, code, missing=missing).video)
    monkeypatch.setattr(P.CpuStages, "local_choice", _whole_volume_local_choice)
    whole = motion_aware(frames, code, missing=missing).video
    for got in banded:
        np.testing.assert_array_equal(got, whole)
    monkeypatch.setattr(P.CpuStages, "local_choice", lambda *args: None)
    assert not np.array_equal(motion_aware(frames, code, missing=missing).video, whole)  # the choice blended


def test_the_refinement_and_the_local_choice_make_no_volume(monkeypatch):
    # Their working memory is band-sized: below half of one (S, H, W) float32 volume here (they took a whole one,
    # the scratch volume, before).
    import tracemalloc

    import flexvox_core.motion.stages as P
    import flexvox_core.motion.vardiff as V
    import flexvox_core.threads

    monkeypatch.setattr(V, "band_length", lambda steps, threads: 4)
    monkeypatch.setattr(P, "workers", lambda: 1)
    monkeypatch.setattr(P.local_choice, "BAND", 1)  # a frame a band
    monkeypatch.setattr(flexvox_core.threads, "workers", lambda: 2)
    peaks = {}
    measuring = [False]

    def measured(name, real):
        def stage(self, *args):
            if not measuring[0]:
                return real(self, *args)
            tracemalloc.start()
            try:
                real(self, *args)
                peaks[name] = tracemalloc.get_traced_memory()[1]
            finally:
                tracemalloc.stop()
        return stage

    for name in ("refinement", "local_choice"):
        monkeypatch.setattr(P.CpuStages, name, measured(name, getattr(P.CpuStages, name)))
    code = design_code((4, 4)).code
    F, H, W = 20, 40, 52  # 20 frames: a band (a frame, and the float16 guide's band made float32) is 1/20 of it
    frames = capture(render_scene("balls", 16 * F, H, W, seed=1), code)
    motion_aware(frames, code)  # a first call loads the stages' kernels and modules (about 1 MB of Python objects)
    measuring[0] = True
    motion_aware(frames, code)
    volume = 16 * F * H * W * 4
    assert set(peaks) == {"refinement", "local_choice"}
    assert max(peaks.values()) < volume / 2, (peaks, volume)


def test_high_tr_is_held_in_float16_after_the_flow_and_given_back_as_float32(monkeypatch, capture_case):
    """The flow reads the high-TR video as computed; every later stage and the result read it rounded to float16
    (the result's ``high_tr`` is float32 of those values); HIGH_TR_HELD = float32 keeps it as computed."""
    import flexvox_core.motion.stages as pipeline
    from flexvox_core.motion.options import STEP1_TENSOR, STEP1_TIME

    _, frames, _, _ = capture_case
    computed = diffuse(frames, CODE, tensor=STEP1_TENSOR, time=STEP1_TIME)
    flow_read, guides = [], []
    kept_flow = pipeline.gated_flow

    def flow_spy(current, *a, **kw):
        flow_read.append(current.copy())
        return kept_flow(current, *a, **kw)

    class OrientedSpy(pipeline.OrientedNc):
        def __init__(self, f, c, guide, **kw):
            guides.append(guide)
            super().__init__(f, c, guide, **kw)

    monkeypatch.setattr(pipeline, "gated_flow", flow_spy)
    monkeypatch.setattr(pipeline, "OrientedNc", OrientedSpy)
    held = motion_aware(frames, CODE)
    np.testing.assert_array_equal(flow_read[0], computed)
    assert flow_read[0].dtype == np.float32 and guides and all(g.dtype == np.float16 for g in guides)
    assert held.high_tr.dtype == np.float32
    np.testing.assert_array_equal(held.high_tr, computed.astype(np.float16).astype(np.float32))
    assert (held.high_tr != computed).any()
    monkeypatch.setattr(pipeline, "HIGH_TR_HELD", np.float32)
    kept = motion_aware(frames, CODE)
    assert kept.high_tr.dtype == np.float32
    np.testing.assert_array_equal(kept.high_tr, computed)


@pytest.mark.parametrize(("tile", "frames", "time", "reach"), [
    ((4, 4), 6, 5.0, 4),  # ⌈1.25 √(2·5·0.95)⌉ = ⌈3.85⌉, at any K (the sampling period no longer sets it)
    ((2, 4), 6, 5.0, 4),
    ((4, 4), 6, 20.0, 8),  # ⌈1.25 √38⌉ = ⌈7.71⌉
    ((2, 2), 1, 20.0, 3),  # at most S − 1
])
def test_the_gather_reaches_one_and_a_quarter_trajectory_deviations(tile, frames, time, reach):
    from flexvox_core.motion.options import MotionOptions
    from flexvox_core.motion.stages import Window

    code = design_code(tile).code
    window = Window.plan(np.zeros((frames, 16, 16), np.float32), code, MotionOptions(time=time), (0.0, 1.0))
    assert window.gather_reach == reach
