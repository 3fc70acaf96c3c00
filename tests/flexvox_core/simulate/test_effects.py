"""Each effect's physics, and the rule that undeclared effects cost nothing."""

import numpy as np
import pytest

from flexvox_core.codes import code_from_order
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.simulate.effects import EFFECTS, Effect, parse_effects
from flexvox_core.simulate.simulator import normalise_frames, simulate_video

CODE = design_code((2, 4)).code  # K = 8


def video(rng, F=3, H=10, W=12, lo=0.1, hi=0.9):
    return rng.uniform(lo, hi, (F * 8, H, W)).astype(np.float32)


def sim(v, *effects, code=CODE, **kw):
    return simulate_video(v, code, effects=list(effects), **kw)


def test_no_effect_is_the_ideal_forward_model_exactly(rng):
    v = video(rng)
    r = sim(v)
    assert np.array_equal(r.frames, capture(v, CODE))
    assert r.effects == {} and r.storage["kind"] == "float"


def test_undeclared_effects_draw_no_random_numbers(rng, monkeypatch):
    drawn = []
    original = Effect.rng
    monkeypatch.setattr(Effect, "rng", lambda self, *a: drawn.append(self.name) or original(self, *a))
    v = video(rng)
    sim(v, *parse_effects({"leakage": {}, "ambient": {}, "dark_current": {}, "read_noise": {}}))
    assert drawn == ["read_noise"]  # the deterministic effects drew nothing


def test_shot_noise_variance_equals_the_mean_in_electrons(rng):
    v = np.full((8 * 40, 32, 32), 0.5, np.float32)
    r = sim(v, EFFECTS["photon_noise"](), electrons_per_unit=200.0, seed=3)
    electrons = r.frames.astype(np.float64) * 200.0
    assert electrons.mean() == pytest.approx(100.0, rel=0.01)
    assert electrons.var() == pytest.approx(electrons.mean(), rel=0.03)
    assert np.allclose(electrons, np.round(electrons), atol=1e-3)  # whole electrons (float32 storage)


def test_leakage_adds_exactly_alpha_times_the_closed_slots(rng):
    v = video(rng)
    alpha = 0.03
    r = sim(v, EFFECTS["leakage"](alpha=alpha))
    ideal = capture(v, CODE)
    closed = capture(v, ~CODE)  # the sum over every closed slot
    assert np.allclose(r.frames, ideal + alpha * closed, rtol=1e-6, atol=1e-6)


def test_whole_slot_phase_offset_relabels_the_code(rng):
    v = video(rng)
    r = sim(v, EFFECTS["sync_phase"](offset=1.0))
    relabelled = np.roll(CODE, 1, axis=2)  # pattern of slot s shown during slot s+1
    assert np.allclose(r.frames, capture(v, relabelled), atol=1e-6)


def test_half_slot_phase_mixes_two_neighbouring_slots(rng):
    v = video(rng)
    r = sim(v, EFFECTS["sync_phase"](offset=0.5))
    want = 0.5 * capture(v, CODE) + 0.5 * capture(v, np.roll(CODE, 1, axis=2))
    assert np.allclose(r.frames, want, atol=1e-6)


def test_jitter_changes_each_frame_and_is_seeded(rng):
    v = video(rng)
    a = sim(v, EFFECTS["sync_phase"](offset=0.0, jitter=0.3), seed=1)
    b = sim(v, EFFECTS["sync_phase"](offset=0.0, jitter=0.3), seed=1)
    c = sim(v, EFFECTS["sync_phase"](offset=0.0, jitter=0.3), seed=2)
    assert np.array_equal(a.frames, b.frames) and not np.array_equal(a.frames, c.frames)
    assert not np.allclose(a.frames, capture(v, CODE))


def test_ambient_reaches_every_slot(rng):
    v = video(rng)
    r = sim(v, EFFECTS["ambient"](level=0.05))
    total = v.reshape(3, 8, 10, 12).sum(axis=1)
    assert np.allclose(r.frames, capture(v, CODE) + 0.05 * total, atol=1e-6)


def test_global_illumination_spreads_a_fraction_of_the_projected_light(rng):
    v = video(rng, H=8, W=16)  # whole tiles: every slot's pattern has mean 1/K
    r = sim(v, EFFECTS["global_illumination"](fraction=0.2))
    total = v.reshape(3, 8, 8, 16).sum(axis=1)
    assert np.allclose(r.frames, capture(v, CODE) + 0.2 / 8 * total, atol=1e-6)


def test_misregistration_by_one_pixel_shifts_the_code(rng):
    v = video(rng, H=8, W=16)
    r = sim(v, EFFECTS["misregistration"](dx=1.0, dy=0.0))
    shifted = np.roll(CODE, -1, axis=1)  # camera pixel x sees projector pixel x+1
    inner = (slice(None), slice(None), slice(0, 15))  # away from the reflected right border
    assert np.allclose(r.frames[inner], capture(v, shifted)[inner], atol=1e-5)


def test_pattern_blur_keeps_the_light_and_spreads_it(rng):
    v = np.full((8, 16, 16), 0.5, np.float32)
    r = sim(v, EFFECTS["pattern_blur"](sigma=1.0))
    assert r.frames.mean() == pytest.approx(0.5, rel=1e-3)
    assert np.allclose(r.frames, 0.5, atol=0.02)  # a constant scene stays constant
    v2 = video(rng, H=16, W=16)
    assert not np.allclose(sim(v2, EFFECTS["pattern_blur"](sigma=1.0)).frames, capture(v2, CODE), atol=1e-3)


def test_read_noise_has_the_declared_spread(rng):
    v = np.full((8 * 20, 32, 32), 0.5, np.float32)
    r = sim(v, EFFECTS["read_noise"](sigma=5.0), electrons_per_unit=1000.0)
    noise = (r.frames.astype(np.float64) - 0.5) * 1000.0
    assert noise.std() == pytest.approx(5.0, rel=0.03)
    assert abs(noise.mean()) < 0.2


def test_dark_current_adds_rate_times_exposure(rng):
    v = video(rng)
    r = sim(v, EFFECTS["dark_current"](rate=300.0), rate_hz=15.0, electrons_per_unit=1000.0)
    assert np.allclose(r.frames, capture(v, CODE) + 300.0 / 15.0 / 1000.0, atol=1e-6)


def test_saturation_clips_at_full_well(rng):
    v = video(rng, lo=0.0, hi=1.0)
    r = sim(v, EFFECTS["saturation"](full_well=500.0), electrons_per_unit=1000.0)
    assert np.isclose(r.frames.max(), 0.5)
    assert np.allclose(r.frames, np.minimum(capture(v, CODE), 0.5), atol=1e-6)


def test_adc_counts_and_normalisation(rng):
    v = video(rng)
    r = sim(v, EFFECTS["adc"](bits=12, gain=0.5, black_level=100), electrons_per_unit=1000.0)
    assert r.frames.dtype == np.uint16 and r.storage["kind"] == "counts"
    want = np.clip(np.rint(capture(v, CODE).astype(np.float64) * 1000 * 0.5 + 100), 0, 4095)
    assert np.array_equal(r.frames, want.astype(np.uint16))
    back = normalise_frames(r.frames, r.storage)
    assert np.allclose(back, capture(v, CODE), atol=1 / (0.5 * 1000))  # within one count


def test_adc_clips_at_the_bit_depth(rng):
    v = np.ones((8, 4, 4), np.float32)
    r = sim(v, EFFECTS["adc"](bits=8, gain=1.0, black_level=0), electrons_per_unit=1000.0)
    assert r.frames.max() == 255


def test_dropped_frames_are_flagged_zero_rows_and_seeded(rng):
    v = video(rng, F=40, H=4, W=4)
    a = sim(v, EFFECTS["dropped_frames"](probability=0.5), seed=5)
    b = sim(v, EFFECTS["dropped_frames"](probability=0.5), seed=5)
    assert np.array_equal(a.dropped, b.dropped) and 5 < a.dropped.sum() < 35
    assert np.all(a.frames[a.dropped] == 0)
    assert np.array_equal(a.frames[~a.dropped], capture(v, CODE)[~a.dropped])


def test_each_effect_has_its_own_noise_stream(rng):
    v = np.full((8 * 4, 8, 8), 0.5, np.float32)
    alone = sim(v, EFFECTS["read_noise"](sigma=2.0), seed=9).frames - capture(v, CODE)
    with_dark = sim(v, EFFECTS["read_noise"](sigma=2.0), EFFECTS["dark_current"](rate=150.0), seed=9).frames
    with_dark = with_dark - capture(v, CODE) - 150.0 / 15.0 / 1000.0
    assert np.allclose(alone, with_dark, atol=1e-6)


def test_effects_record_exactly_what_was_applied(rng):
    r = sim(video(rng), *parse_effects({"read_noise": {"sigma": 2.5}, "leakage": {}}), seed=4)
    assert r.effects == {"leakage": {"alpha": 0.01}, "read_noise": {"sigma": 2.5}}
    assert list(r.effects) == ["leakage", "read_noise"]  # pipeline order
    assert r.seed == 4


def test_multiplexed_code_through_the_simulator(rng):
    from flexvox_core.multiplex import multiplexed_code

    mc = multiplexed_code((1, 3))
    v = rng.random((6, 5, 7)).astype(np.float32)
    assert np.array_equal(simulate_video(v, mc.code).frames, capture(v, mc.code))


@pytest.mark.parametrize(
    "table, match",
    [
        ({"blur": {}}, r"unknown effect 'blur'; effects: misregistration, pattern_blur"),
        ({"read_noise": {"sigma": -1}}, r"read_noise.sigma must be between 0 and 10000 e- rms; got -1"),
        ({"read_noise": {"sgima": 1}}, r"effect 'read_noise' has no parameter 'sgima'; its parameters: sigma"),
        ({"leakage": {"alpha": 2}}, r"leakage.alpha must be between 0 and 1 fraction; got 2"),
        ({"adc": {"bits": 12.5}}, r"adc.bits must be a whole number; got 12.5"),
        ({"adc": {"bits": 8, "black_level": 300}},
         r"adc.black_level must be below the 8-bit ADC's largest count 255; got 300 \(every pixel would read 255\)"),
        ({"ambient": {"level": "lots"}}, r"ambient.level must be a number"),
        ({"leakage": 3}, r"effect 'leakage' needs a table of parameters"),
    ],
)
def test_bad_effect_declarations(table, match):
    with pytest.raises(ValueError, match=match):
        parse_effects(table)


def test_simulator_rejects_bad_inputs(rng):
    with pytest.raises(ValueError, match=r"must have shape \(S, H, W\); got 2 dimensions"):
        simulate_video(np.zeros((8, 8)), CODE)
    with pytest.raises(ValueError, match=r"each effect may be declared once"):
        simulate_video(video(rng), CODE, effects=[EFFECTS["leakage"](), EFFECTS["leakage"]()])
    v = video(rng)
    v[3, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"sub-frame 3 holds NaN"):
        simulate_video(v, CODE)


def test_a_float_video_outside_0_1_is_refused_as_the_command_line_refuses_its_file(rng):
    # a float clip in 0..255 had been simulated 255 times too bright, its ground truth recorded in counts
    v = video(rng)
    with pytest.raises(ValueError, match=r"`video` values must lie in \[0, 1\] \(white = 1\); got 25.* to 229.* "
                                         r"\(8-bit values in a float array\? divide by 255\)"):
        simulate_video(v * 255, CODE)
    with pytest.raises(ValueError, match=r"`video` values must lie in \[0, 1\] \(white = 1\); got -0.3.* to 0.3.*"):
        simulate_video(v - 0.5, CODE)
    assert np.array_equal(simulate_video(np.round(v * 255).astype(np.uint8), CODE).ground_truth,
                          np.round(v * 255).astype(np.float32) / 255)  # counts: read in [0, 1] by their dtype


def test_partial_border_tiles_with_effects(rng):
    v = rng.random((8, 7, 9)).astype(np.float32)
    r = sim(v, EFFECTS["leakage"](alpha=0.0))
    assert np.allclose(r.frames, capture(v, code_from_order(design_code((2, 4)).order)), atol=1e-6)


def test_render_exposures_with_arbitrary_light_and_streams(rng):
    from flexvox_core.simulate.simulator import render_exposures

    v = video(rng)
    light = rng.random((8, 10, 12)).astype(np.float32)  # any pattern, not a tiled code
    frames, dropped, storage = render_exposures(v, light)
    want = np.einsum("fkhw,khw->fhw", v.reshape(3, 8, 10, 12).astype(np.float64), light.astype(np.float64))
    assert np.allclose(frames, want, atol=1e-5) and not dropped.any() and storage["kind"] == "float"
    noisy = [EFFECTS["read_noise"](sigma=2.0)]
    a, _, _ = render_exposures(v, light, effects=noisy, stream=0)
    b, _, _ = render_exposures(v, light, effects=noisy, stream=1)
    c, _, _ = render_exposures(v, light, effects=noisy, stream=1)
    assert not np.array_equal(a, b) and np.array_equal(b, c)
    with pytest.raises(ValueError, match=r"`light` .* does not match 3 frames of K = 8"):
        render_exposures(v, light[:, :5])


def test_a_list_of_effect_names_is_simulated_at_their_defaults_in_pipeline_order(rng):
    code = design_code((2, 2)).code
    v = rng.random((3 * 4, 8, 8)).astype(np.float32)
    table = simulate_video(v, code, effects={"photon_noise": {}, "read_noise": {}}, seed=2)
    for effects in (["photon_noise", "read_noise"], ["read_noise", "photon_noise"],
                    [EFFECTS["read_noise"](), "photon_noise"]):
        sim = simulate_video(v, code, effects=effects, seed=2)
        assert list(sim.effects) == ["photon_noise", "read_noise"]
        np.testing.assert_array_equal(sim.frames, table.frames)
    assert list(simulate_video(v, code, effects="read_noise").effects) == ["read_noise"]
    with pytest.raises(ValueError, match=r"unknown effect 'photon'; effects: misregistration, .*photon_noise"):
        simulate_video(v, code, effects=["photon"])
    with pytest.raises(ValueError, match=r"`effects` items must be effect names \(misregistration, .*\) or Effect "
                                         r"objects; got 3"):
        simulate_video(v, code, effects=[3])


@pytest.mark.parametrize("seed", [None, -1, 1.5, "3", True])
def test_a_seed_that_is_no_whole_number_is_refused_in_words(seed):
    video = np.zeros((4, 4, 4), np.float32)
    with pytest.raises(ValueError, match=r"`seed` must be a whole number >= 0; got "):
        simulate_video(video, design_code((2, 2)).code, seed=seed)


@pytest.mark.parametrize("rate", ["15", None])
def test_a_rate_that_is_no_number_is_refused_in_words(rate):
    with pytest.raises(ValueError, match=r"`rate_hz` and `electrons_per_unit` must be numbers > 0; got "):
        simulate_video(np.zeros((4, 4, 4), np.float32), design_code((2, 2)).code, rate_hz=rate)
