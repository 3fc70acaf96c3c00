"""The accuracy estimate without ground truth (flexvox_core.accuracy)."""

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

import flexvox_core.methods as methods_pkg
from flexvox_core.accuracy import (
    NoiseModel,
    NotEstimable,
    _demultiplexed,
    estimate_accuracy,
    estimate_recording,
    probe_lattice,
    refusal,
)
from flexvox_core.design import design_code
from flexvox_core.forward import capture, tiled_code
from flexvox_core.methods import Method, MethodOutput
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.recording import Recording, write_simulation
from flexvox_core.simulate import render_scene, simulate_video

CODE = design_code((2, 2)).code
SIGMA = (1.5, 1.0, 1.0)  # the toy smoother's Gaussian (t, y, x)


def toy_nc(frames, code, mask_out=None):
    """Float64 normalized convolution that keeps its samples: the linear smoother the probe is exact for.
    ``mask_out`` (S, H, W) bool: samples taken out (the exact leave-one-out)."""
    F, H, W = frames.shape
    K = code.shape[2]
    m = np.tile(tiled_code(code, H, W), (F, 1, 1)).astype(np.float64)
    vals = np.repeat(np.asarray(frames, np.float64), K, axis=0) * m
    if mask_out is not None:
        m[mask_out] = 0.0
        vals[mask_out] = 0.0
    num = gaussian_filter(vals, SIGMA, mode="nearest")
    den = gaussian_filter(m, SIGMA, mode="nearest")
    return np.where(m > 0, vals, num / den)


@pytest.fixture
def toy(monkeypatch):
    def run(frames, code, method, **kw):
        return MethodOutput(toy_nc(frames, code).astype(np.float32))

    monkeypatch.setattr(methods_pkg, "run", run)


def reference_bounds(frames, code, step=4):
    """The MSE with C_d = 0, the pessimistic and the Cauchy-Schwarz optimistic bounds from exact leave-one-out
    (each probed sample taken out for real), float64, and how many samples were held out."""
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    v0 = toy_nc(frames, code)
    slot = np.argmax(tiled_code(code, H, W), axis=0)
    lo_sum = hi_sum = op_sum = n = 0.0
    probed = 0
    for f in range(F):
        shift = (f % 2) * (step // 2)
        for yy, xx in np.argwhere(probe_lattice(H, W, step, shift)):
            t0 = f * K + slot[yy, xx]
            if t0 - 1 < 0 or t0 + 1 >= S:
                continue
            probed += 1
            out = np.zeros((S, H, W), bool)
            out[t0, yy, xx] = True
            vm = toy_nc(frames, code, out)
            y = float(frames[f, yy, xx])
            loo = (0.5 * (vm[t0 - 1, yy, xx] + vm[t0 + 1, yy, xx]) - y) ** 2
            for d in range(-(K // 2), K - K // 2):
                t = t0 + d
                if not 0 <= t < S:
                    continue
                n += 1
                if d == 0:
                    continue  # the sampled voxel keeps its sample: no error without noise
                a = (v0[t, yy, xx] - vm[t, yy, xx]) / (y - vm[t, yy, xx])  # its response to the sample
                e_d = (vm[t, yy, xx] - y) ** 2 - loo
                lo = (1 - a) ** 2 * loo + a**2 * e_d
                lo_sum += lo
                hi_sum += loo
                # C at its largest: C**2 = L (e - 2C) (Cauchy-Schwarz), or e / 2 (V = 0), whichever is smaller
                c = min(e_d / 2, -loo + math.sqrt(loo * loo + loo * e_d)) if loo * loo + loo * e_d > 0 else 0.0
                op_sum += lo - 2 * a * max(c, 0.0)
    return lo_sum / n, hi_sum / n, op_sum / n, probed


def test_the_probe_gives_exact_leave_one_out_for_a_linear_smoother(toy):
    truth = render_scene("balls", 4 * 4, 16, 20, seed=0).astype(np.float64)
    frames = capture(truth, CODE)
    est = estimate_accuracy(frames, CODE, Method("diffusion"), confidence=1e-9)
    lo, hi, op, probed = reference_bounds(frames, CODE)
    assert op < lo < hi
    assert est.high == pytest.approx(10 * math.log10(1 / op), abs=0.02)
    assert est.low == pytest.approx(10 * math.log10(1 / hi), abs=0.02)
    assert est.psnr == pytest.approx(10 * math.log10(1 / lo), abs=0.02)  # the estimate: the C_d = 0 bound
    assert est.samples == probed == 51


def test_the_probe_lattice_lands_on_every_place_of_the_tile():
    for (m, n), (H, W) in [((4, 4), (64, 96)), ((2, 4), (40, 48)), ((2, 2), (16, 20))]:
        for shift in (0, 2):
            ys, xs = np.nonzero(probe_lattice(H, W, 4, shift))
            assert len({(y % m, x % n) for y, x in zip(ys, xs, strict=True)}) == m * n
            assert ys.min() >= 1 and xs.min() >= 1 and ys.max() < H - 1 and xs.max() < W - 1
    assert not np.any(probe_lattice(64, 96, 4, 0) & probe_lattice(64, 96, 4, 2))
    assert abs(probe_lattice(64, 96, 4).mean() - 1 / 16) < 0.005


def scene(noisy: bool, seed: int = 1):
    truth = render_scene("balls", 4 * 4, 32, 40, seed=0)
    if not noisy:
        return truth, capture(truth, CODE)
    effects = {"photon_noise": {}, "read_noise": {"sigma": 3.0}}
    return truth, simulate_video(truth, CODE, effects=effects, seed=seed).frames


def test_the_noise_term_takes_the_noise_out():
    _, clean = scene(False)
    _, noisy = scene(True)
    m = Method("diffusion")
    noise = NoiseModel.from_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}})
    e_clean = estimate_accuracy(clean, CODE, m)
    e_noisy = estimate_accuracy(noisy, CODE, m, noise=noise)
    e_blind = estimate_accuracy(noisy, CODE, m)
    assert abs(e_noisy.psnr - e_clean.psnr) < abs(e_blind.psnr - e_clean.psnr)
    assert e_blind.psnr < e_noisy.psnr


def test_the_noise_model_of_stated_effects():
    nm = NoiseModel.from_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}, "adc": {"gain": 0.5}},
                                 {"electrons_per_unit": 2000.0})
    assert nm.photon == pytest.approx(1 / 2000)
    assert nm.floor == pytest.approx((3 / 2000) ** 2 + (1 / (0.5 * 2000)) ** 2 / 12)
    np.testing.assert_allclose(nm.variance([0.5, -1.0]), [0.5 / 2000 + nm.floor, nm.floor])
    assert NoiseModel.from_effects({}).variance(0.7) == 0.0


def test_the_estimate_lies_near_the_truth_on_a_small_case():
    truth, frames = scene(False)
    m = Method("diffusion")
    assert refusal(m) is None
    est = estimate_accuracy(frames, CODE, m)
    video = methods_pkg.run(frames, CODE, m, chunk_frames=None).video
    true = 10 * np.log10(1 / np.mean((video.astype(np.float64) - truth) ** 2))
    assert est.low <= true <= est.high
    assert abs(est.psnr - true) < 1.5
    assert est.per_frame.shape == (4,) and np.all(np.isfinite(est.per_frame))
    assert est.line().startswith(f"estimated PSNR {est.psnr:.2f} dB (± ")


def test_ground_truth_is_never_read(tmp_path, monkeypatch):
    truth = render_scene("balls", 4 * 4, 24, 28, seed=0)
    sim = simulate_video(truth, CODE, effects={"read_noise": {"sigma": 2.0}}, seed=2)
    path = write_simulation(tmp_path / "r.zarr", sim)
    before = estimate_recording(path, Method("diffusion"))

    def poisoned(self):
        raise AssertionError("the estimate read the ground truth")

    monkeypatch.setattr(Recording, "ground_truth", property(poisoned))
    monkeypatch.setattr(Recording, "has_ground_truth", property(poisoned))
    after = estimate_recording(path, Method("diffusion"))
    assert after.psnr == before.psnr and after.low == before.low
    assert after.noise.floor == pytest.approx((2.0 / 1000) ** 2)


def test_dropped_frames_are_scored_by_captured_frames_held_out_like_them():
    truth = render_scene("balls", 8 * 4, 24, 28, seed=0)
    frames = capture(truth, CODE)
    missing = np.zeros(8, bool)
    missing[5] = True
    frames[5] = 0
    est = estimate_accuracy(frames, CODE, Method("diffusion"), missing=missing)
    assert "dropped frames scored by captured runs held out like them" in est.scheme
    assert np.all(np.isfinite(est.per_frame)) and est.per_frame[5] < np.median(est.per_frame)  # no samples: worse
    assert est.low <= est.psnr <= est.high


def test_dropped_frames_with_no_run_to_hold_out_are_left_out():
    truth = render_scene("balls", 5 * 4, 24, 28, seed=0)
    frames = capture(truth, CODE)
    missing = np.array([False, True, False, True, False])
    frames[missing] = 0
    est = estimate_accuracy(frames, CODE, Method("diffusion"), missing=missing)
    assert "dropped frames not scored" in est.scheme
    assert np.all(np.isnan(est.per_frame[missing])) and np.all(np.isfinite(est.per_frame[~missing]))


def test_a_multiplexed_capture_is_refused_and_estimated_unchecked_after_demultiplexing():
    mc = multiplexed_code((1, 3))
    truth = render_scene("balls", 4 * 3, 24, 27, seed=0)
    frames = capture(truth, mc.code)
    with pytest.raises(NotEstimable, match=r"on a multiplexed capture: the estimate of a demultiplexed capture has "
                                           r"not met the acceptance: .* a 3x5 tile 4\.1 dB low"):
        estimate_accuracy(frames, mc, Method("diffusion"))
    est = estimate_accuracy(frames, mc, Method("diffusion"), unchecked=True)
    assert "demultiplexed" in est.scheme and "unchecked" in est.scheme and est.low <= est.psnr <= est.high


def test_demultiplexing_carries_the_noise_float64():
    mc = multiplexed_code((1, 3))
    rng = np.random.default_rng(0)
    frames = rng.random((2, 4, 6))
    nm = NoiseModel(photon=0.01, floor=0.001)
    _, code, var = _demultiplexed(frames, mc, nm)
    tiles = frames.reshape(2, 4, 2, 3)
    for f, r, tx in [(0, 0, 0), (1, 3, 1)]:
        v = 0.01 * tiles[f, r, tx] + 0.001
        slots = (mc.demux.astype(np.float64) ** 2) @ v
        for j in range(3):
            assert var[f, r, 3 * tx + j] == pytest.approx(slots[mc.placement[0, j]])
    assert code.shape == (1, 3, 3)


@pytest.mark.parametrize(("method", "match"), [
    (Method("motion-aware"), "even with the first run.s flow held"),
    (Method("gap-tv"), "3 of the 4 runs on the SCI clips"),
    (Method("rebin", interpolate=False), r"re-binning without interpolation .* \(8 of 12 runs within 1 dB"),
    (Method("diffusion", solver="explicit"), r"up to 1\.86 dB high at a 2x2 code \(K = 4; 6 of 8 within 1 dB"),
    (Method("diffusion", solver="steady"), r"up to 1\.99 dB high at a 2x2 code \(K = 4; 6 of 8 within 1 dB"),
])
def test_methods_it_cannot_estimate_are_refused(method, match):
    assert refusal(method) is not None
    _, frames = scene(False)
    with pytest.raises(NotEstimable, match=match):
        estimate_accuracy(frames, CODE, method)


def test_a_method_that_copies_its_samples_onto_their_neighbours_is_refused():
    _, frames = scene(False)  # nc at a short time fills from the nearest sample: no prediction without it
    with pytest.raises(NotEstimable, match=r"copies 100% of the probed samples onto a temporal neighbour"):
        estimate_accuracy(frames, CODE, Method("diffusion", time=0.25))


def test_a_capture_too_small_to_probe_is_refused():
    with pytest.raises(NotEstimable, match="too small to probe"):
        estimate_accuracy(np.zeros((2, 8, 8), np.float32), CODE, Method("diffusion"))


def test_a_method_is_named_or_given_and_anything_else_is_refused_naming_fv_method():
    import flexvox_core as fv

    code = fv.design_code((2, 2)).code
    frames = fv.capture(fv.render_scene("balls", 16, 24, 32), code)
    by_name = fv.estimate_accuracy(frames, code, "diffusion")
    assert by_name.psnr == fv.estimate_accuracy(frames, code, fv.Method("diffusion")).psnr
    with pytest.raises(TypeError, match=r"`method` must be an fv.Method"):
        fv.estimate_accuracy(frames, code, 3)


def test_motion_aware_runs_for_the_estimate_equal_the_method_and_hold_the_first_flow(monkeypatch):
    from flexvox_core.accuracy_runs import HeldRuns
    from flexvox_core.motion import stages

    truth = render_scene("fan", 4 * 4, 24, 28, seed=0)
    frames = capture(truth, CODE).astype(np.float32)
    m = Method("motion-aware")
    runs = HeldRuns(frames, CODE, m)
    np.testing.assert_allclose(runs(frames), methods_pkg.run(frames, CODE, m, chunk_frames=None).video, atol=1e-6)
    assert len(runs.flows) == m.options.passes

    def no_flow(*args, **kwargs):
        raise AssertionError("the probe computed the flow again")

    monkeypatch.setattr(stages, "gated_flow", no_flow)
    probed = frames.copy()
    probed[:, 5, 5] += 0.05
    moved = runs(probed)
    assert moved.shape == (16, 24, 28) and not np.array_equal(moved, runs(frames))


def test_a_given_motion_aware_reconstruction_needs_the_flow_alone(monkeypatch):
    from flexvox_core.accuracy_runs import HeldRuns

    truth = render_scene("fan", 4 * 4, 24, 28, seed=0)
    frames = capture(truth, CODE).astype(np.float32)
    m = Method("motion-aware")
    full = HeldRuns(frames, CODE, m)
    video = full(frames)
    flow_only = HeldRuns(frames, CODE, m)
    flow_only.flow_only(frames)
    np.testing.assert_array_equal(flow_only.flows[0].flow, full.flows[0].flow)
    np.testing.assert_array_equal(flow_only(frames), video)


def gap_tv_reference(frames, code, video):
    """Float64 ((K − 1)·L + SURE)/K over every sample whose temporal neighbours lie in the clip (noiseless), and
    their count."""
    F, H, W = frames.shape
    K = code.shape[2]
    v = np.asarray(video, np.float64)
    slot = np.argmax(tiled_code(code, H, W), axis=0)
    total, count = 0.0, 0
    for f in range(F):
        for yy in range(H):
            for xx in range(W):
                t0 = f * K + slot[yy, xx]
                if t0 - 1 < 0 or t0 + 1 >= F * K:
                    continue
                y = float(frames[f, yy, xx])
                loo = (0.5 * (v[t0 - 1, yy, xx] + v[t0 + 1, yy, xx]) - y) ** 2
                total += ((K - 1) * loo + (v[t0, yy, xx] - y) ** 2) / K
                count += 1
    return total / count, count


def test_gap_tv_holds_out_every_sample_by_its_temporal_neighbours():
    truth, frames = scene(False)
    m = Method("gap-tv", iterations=10)
    est = estimate_accuracy(frames, CODE, m, unchecked=True)  # refused by the API: measured here all the same
    video = methods_pkg.run(frames, CODE, m, chunk_frames=None).video
    ref, count = gap_tv_reference(frames, CODE, video)
    assert est.mse == pytest.approx(ref, rel=1e-4)
    assert est.samples == count
    assert "exact leave-one-out of every sample" in est.scheme and "4-fold hold-out" in est.scheme
    assert est.low < est.psnr <= est.high


def test_the_k_fold_hold_out_against_a_float64_reference():
    from flexvox_core.accuracy_folds import folds, held_out_error, masked_run
    from flexvox_core.reconstruct.gaptv import gap_tv_masks

    _, frames = scene(False)
    F, H, W = frames.shape
    got = held_out_error(frames, CODE, masked_run(Method("gap-tv", iterations=10)), np.zeros(F, bool),
                         np.zeros(frames.shape))
    masks = tiled_code(CODE, H, W).astype(np.float64)
    slot = np.argmax(masks, axis=0)
    yy, xx = np.mgrid[0:H, 0:W]
    errs = []
    for fold in folds(CODE, H, W):
        for f in range(F):
            y = np.where(fold, 0.0, frames[f].astype(np.float64))
            v = gap_tv_masks(y[None], masks * ~fold, iterations=10, dtype=np.float64)
            errs.append(((v[slot, yy, xx] - frames[f]) ** 2)[fold])
    assert got == pytest.approx(float(np.mean(np.concatenate(errs))), rel=1e-3)
    assert [int(f.sum()) for f in folds(CODE, H, W)] == [320] * 4  # 32x40: 16x20 tiles of 2x2, a quarter each


def test_the_gpu_engine_holds_the_first_flow_too(monkeypatch):
    from flexvox_core.accuracy_runs import HeldRuns
    from flexvox_core.motion.gpu import engine
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.stages import Window, run_stages
    from tests.flexvox_core.gpu.tiny import CODE as TINY
    from tests.flexvox_core.gpu.tiny import tiny_capture

    _, frames = tiny_capture("balls", 2, 8, 8)
    m = Method("motion-aware", refine_time=0.0, local_choice=False, noise_aware=False)
    runs = HeldRuns(frames, TINY, m, device="cuda")
    assert runs.device == "cuda"
    first = runs(frames)
    window = Window.plan(frames, TINY, m.options, (float(frames.min()), float(frames.max())))
    np.testing.assert_allclose(first, run_stages(CudaStages(window)).video, atol=1e-6)
    assert len(runs.flows) == 1 and isinstance(runs.flows[0], np.ndarray)

    def no_flow(*args, **kwargs):
        raise AssertionError("the probe computed the flow again")

    monkeypatch.setattr(engine.gate, "gated_flow", no_flow)
    np.testing.assert_allclose(runs(frames), first, atol=1e-6)


class Stop(Exception):
    """What a progress callback raises to stop (as Review's cancel token's Cancelled)."""


def test_a_progress_that_raises_after_the_first_run_stops_before_the_probe(monkeypatch):
    runs = []

    def run(frames, code, method, **kw):
        runs.append(frames.copy())
        return MethodOutput(toy_nc(frames, code).astype(np.float32))

    monkeypatch.setattr(methods_pkg, "run", run)
    seen = []

    def progress(done, total):
        seen.append((done, total))
        if done >= 4:  # the first run (4 frames) is done: cancel
            raise Stop("cancelled")

    _, frames = scene(False)
    with pytest.raises(Stop, match="cancelled"):
        estimate_accuracy(frames, CODE, Method("diffusion"), progress=progress)
    assert len(runs) == 1  # the reconstruction ran; the probe did not
    assert seen == [(4, 8)]  # two runs planned, four frames each


def test_the_progress_counts_each_runs_chunks_and_leaves_the_estimate_as_it_was():
    _, frames = scene(False)
    m = Method("diffusion")
    seen = []
    est = estimate_accuracy(frames, CODE, m, chunk_frames=2, progress=lambda done, total: seen.append((done, total)))
    assert seen == [(2, 8), (4, 8), (4, 8), (6, 8), (8, 8), (8, 8)]  # each chunk of each run, then the run
    assert est.as_dict() == estimate_accuracy(frames, CODE, m, chunk_frames=2).as_dict()


def test_the_folds_runs_report_progress_too():
    seen = []
    _, frames = scene(False)
    est = estimate_accuracy(frames, CODE, Method("gap-tv"), unchecked=True,
                            progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (24, 24)  # the reconstruction, the probe and 4 folds, 4 frames each
    assert "4-fold" in est.scheme


def test_a_progress_that_is_no_callback_is_refused():
    _, frames = scene(False)
    with pytest.raises(TypeError, match=r"`progress` must be True \(a bar\), False or None \(nothing\), or a callable"):
        estimate_accuracy(frames, CODE, Method("diffusion"), progress=3)


def test_integer_counts_are_read_as_the_runner_reads_them_not_as_relative_units():
    from flexvox_core import capture, render_scene
    from flexvox_core.design import design_code

    code = design_code((2, 2)).code
    f = capture(render_scene("balls", 16, 24, 32), code)
    est = estimate_accuracy(f, code, "diffusion")
    u16 = np.round(f * 65535).astype(np.uint16)  # counts: 65535 is white
    assert estimate_accuracy(u16, code, "diffusion").psnr == pytest.approx(est.psnr, abs=0.01)
    twelve = np.round(f * 4095).astype(np.uint16)  # a 12-bit camera's counts in uint16
    assert estimate_accuracy(twelve, code, "diffusion", white=4095).psnr == pytest.approx(est.psnr, abs=0.05)
    with pytest.raises(ValueError, match=r"`white` must be"):
        estimate_accuracy(u16, code, "diffusion", white=-1)


def test_a_noise_model_larger_than_the_samples_error_is_refused_not_scored_100_db():
    from flexvox_core import capture, render_scene
    from flexvox_core.choice import choose
    from flexvox_core.design import design_code

    code = design_code((2, 2)).code
    f = capture(render_scene("balls", 32, 48, 64), code)  # noiseless
    overstated = NoiseModel(photon=0.05, floor=0.0)
    with pytest.raises(NotEstimable, match=r"the held-out samples' error less the noise the capture states "
                                           r"\(photon 0\.05, floor 0: .*\) is .*, not above zero"):
        estimate_accuracy(f, code, "diffusion", noise=overstated)
    with pytest.raises(NotEstimable, match=r"no candidate could be estimated"):
        choose(f, code, "diffusion", "time", (1.5, 6.0), noise=overstated)


def test_missing_of_the_wrong_length_is_refused_in_words():
    from flexvox_core import capture, render_scene
    from flexvox_core.design import design_code

    code = design_code((2, 2)).code
    f = capture(render_scene("balls", 32, 24, 32), code)
    with pytest.raises(ValueError, match=r"`missing` must be 8 booleans, one per camera frame; got bool \(7,\)"):
        estimate_accuracy(f, code, "diffusion", missing=np.zeros(7, bool), reconstruction=np.zeros((32, 24, 32)))


def test_the_noise_of_a_recording_is_at_the_electrons_per_unit_it_was_simulated_at(tmp_path):
    from flexvox_core import render_scene, simulate_video, write_simulation
    from flexvox_core.accuracy import noise_of
    from flexvox_core.design import design_code
    from flexvox_core.recording import open_recording

    code = design_code((2, 2)).code
    sim = simulate_video(render_scene("balls", 8, 12, 16), code, effects={"photon_noise": {}}, seed=1,
                         electrons_per_unit=30.0)
    noise = noise_of(open_recording(write_simulation(tmp_path / "r.zarr", sim)))
    assert noise.photon == pytest.approx(1 / 30) and "not stated" not in noise.source
    old = NoiseModel.from_effects({"photon_noise": {}}, {"kind": "float"})  # a recording that does not say
    assert old.photon == pytest.approx(1e-3) and old.source.endswith(
        "at 1000 electrons per unit (the simulator's default: not stated)")


@pytest.mark.parametrize(("kw", "message"), [
    ({"step": 0}, r"`step` must be a whole number >= 1; got 0"),
    ({"step": 2.5}, r"`step` must be a whole number >= 1; got 2\.5"),
])
def test_a_bad_probe_step_is_refused_in_words(kw, message):
    from flexvox_core import capture, render_scene
    from flexvox_core.design import design_code

    code = design_code((2, 2)).code
    f = capture(render_scene("balls", 16, 24, 32), code)
    with pytest.raises(ValueError, match=message):
        estimate_accuracy(f, code, "diffusion", **kw)
    with pytest.raises(ValueError, match=r"`shift` must be a whole number >= 0; got -1"):
        probe_lattice(8, 8, 4, -1)


def test_a_recording_whose_code_light_spills_gets_its_estimate_called_an_upper_bound(tmp_path):
    from flexvox_core.accuracy import estimate_recording, spill_caveat
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    assert spill_caveat({"kind": "simulated", "effects": {"photon_noise": {}}}) is None
    assert spill_caveat({"kind": "simulated", "effects": {"pattern_blur": {}, "misregistration": {}}}).startswith(
        "the recording states pattern_blur and misregistration, so a slot's light spills")
    assert spill_caveat({"kind": "captured", "effects": {}}).startswith("a rig's projector blurs its code")
    with pytest.raises(TypeError, match=r"`attrs` must be a recording's attribute dict \(`recording.attrs`\); got str"):
        spill_caveat("rec.zarr")
    code = design_code((2, 2)).code
    video = render_scene("drummer", 4 * 4, 32, 48)
    for effects, caveat in (({}, False), ({"pattern_blur": {}}, True)):
        path = write_simulation(tmp_path / f"r{len(effects)}.zarr", simulate_video(video, code, effects=effects))
        est = estimate_recording(path, Method("diffusion"))
        assert (est.caveat is not None) == caveat
        assert ("; an upper bound: the recording states pattern_blur" in est.line()) == caveat
        assert est.line().endswith(")") and est.as_dict()["caveat"] == est.caveat
