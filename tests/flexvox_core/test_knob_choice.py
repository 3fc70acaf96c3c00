"""Choosing a knob by the estimated accuracy (flexvox_core.choice)."""

import re

import numpy as np
import pytest

import flexvox_core.accuracy as accuracy
import flexvox_core.methods as methods_pkg
from flexvox_core.accuracy import NoiseModel, NotEstimable, estimate_accuracy, refusal
from flexvox_core.choice import AUTO_KNOBS, MOTION_TIMES, TIMES, Choice, candidates_for, choose, choose_recording
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method
from flexvox_core.metrics import psnr
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct.rebin import supported_divisions
from flexvox_core.recording import Recording, open_recording, write_simulation
from flexvox_core.simulate import render_scene, simulate_video

CODE = design_code((2, 2)).code


@pytest.fixture(scope="module")
def scene():
    """A small moving scene, its capture with photon and read noise, and the noise model (seeded)."""
    truth = render_scene("balls", 6 * 4, 32, 40, seed=0)
    effects = {"photon_noise": {}, "read_noise": {"sigma": 3.0}}
    sim = simulate_video(truth, CODE, effects=effects, seed=1)
    return truth, np.asarray(sim.frames, np.float32), NoiseModel.from_effects(effects)


@pytest.fixture
def counted(monkeypatch):
    """Every reconstruction the choice makes, counted (the real runner underneath)."""
    calls = []
    real = methods_pkg.run

    def run(frames, code, method, **kw):
        calls.append(method)
        return real(frames, code, method, **kw)

    monkeypatch.setattr(methods_pkg, "run", run)
    return calls


def test_the_choice_on_a_simple_scene_is_the_truly_best_time_or_within_the_estimates_error(scene):
    truth, frames, noise = scene
    choice = choose(frames, CODE, "diffusion", "time", noise=noise)  # the truth is not given
    assert [c.value for c in choice.candidates] == list(TIMES)
    estimates = [c.estimate.psnr for c in choice.candidates]
    assert choice.value == TIMES[int(np.argmax(estimates))] and choice.method == Method("diffusion", time=choice.value)
    true = [float(psnr(truth, methods_pkg.run(frames, CODE, Method("diffusion", time=t)).video)) for t in TIMES]
    # the truth spans more than a decibel over the grid: the choice has something to get right
    assert max(true) - min(true) > 1.0, true
    assert max(true) - true[TIMES.index(choice.value)] <= 1.0, (true, estimates)  # the estimate's acceptance: 1 dB
    assert choice.video is not None
    assert np.array_equal(choice.video, methods_pkg.run(frames, CODE, choice.method).video)


def test_each_candidate_costs_its_reconstruction_and_the_estimates_probe_and_nothing_is_run_again(scene, counted):
    _, frames, noise = scene
    choice = choose(frames, CODE, Method("diffusion", tensor=(1, 1, 1)), "time", (2.0, 3.0, 4.0), noise=noise)
    assert len(counted) == 6 == choice.runs  # 3 candidates x (their reconstruction, the probe)
    assert [c.runs for c in choice.candidates] == [2, 2, 2]
    assert all(m.tensor == (1.0, 1.0, 1.0) for m in counted)  # the method's other options are kept
    assert choice.seconds >= sum(c.seconds for c in choice.candidates) > 0
    assert all(0 < c.run_seconds < c.seconds for c in choice.candidates)
    assert re.fullmatch(r"choosing cost \d+\.\d\d s: 3 candidates x \(a reconstruction and its estimate's probe\), "
                        r"6 reconstructions in all", choice.cost())


def test_the_choice_prints_the_choice_each_candidates_line_and_the_cost(scene):
    _, frames, noise = scene
    choice = choose(frames, CODE, "diffusion", "time", (2.0, 4.0), noise=noise, keep_video=False)
    lines = choice.lines()
    assert lines[0].startswith(f"chose time {choice.value:g} for diffusion by the estimated PSNR "
                               f"({choice.estimate.psnr:.2f} dB)")
    assert re.fullmatch(r"  diffusion nc \(.*\) n=2: estimated PSNR \d+\.\d\d dB \(± .*\) in \d+\.\d\d s", lines[1])
    assert lines[-1] == choice.cost() and len(lines) == 4
    assert choice.video is None and choice.output is None
    assert re.fullmatch(r"<Choice diffusion time = [24] of 2 candidates: estimated PSNR \d+\.\d\d dB, "
                        r"4 reconstructions in \d+\.\d\d s>", repr(choice))
    with pytest.raises(AttributeError):
        choice.value = 3.0  # frozen
    rivals = {c.value for c in choice.rivals}
    other = next(c for c in choice.candidates if c.value != choice.value)
    assert rivals == ({other.value} if choice.estimate.low <= other.estimate.psnr <= choice.estimate.high else set())


def test_a_candidate_the_estimate_cannot_score_keeps_its_reason_and_the_others_are_chosen_from(scene):
    _, frames, noise = scene
    choice = choose(frames, CODE, "diffusion", "time", (0.25, 2.0), noise=noise)
    short = choice.candidates[0]
    assert short.estimate is None and "copies" in short.why and short.runs == 2
    assert choice.value == 2.0
    assert "estimated PSNR: none (cannot estimate the accuracy of diffusion" in short.line()
    with pytest.raises(NotEstimable, match=r"cannot choose diffusion's time by the estimated accuracy: no candidate "
                                           r"could be estimated \(0\.25: cannot estimate .* copies"):
        choose(frames, CODE, "diffusion", "time", (0.25,), noise=noise)


@pytest.mark.parametrize("name", sorted(AUTO_KNOBS))
def test_a_knob_of_a_method_the_estimate_refuses_is_refused_with_its_reason_before_anything_runs(name, counted,
                                                                                                 monkeypatch):
    method = Method(name)
    why = refusal(method)
    if why is None:  # offered today: refuse it here by the estimate's own table, as it would be
        why = "not checked against the truth (made up)"
        monkeypatch.setitem(accuracy.REFUSED, name, why)
    with pytest.raises(NotEstimable, match=re.escape(f"cannot choose {name}'s {AUTO_KNOBS[name][0]} by the "
                                                     f"estimated accuracy: {why}")):
        choose(capture(render_scene("balls", 8, 24, 24), CODE), CODE, method, AUTO_KNOBS[name][0])
    assert counted == []


def test_a_candidate_value_the_estimate_refuses_keeps_the_reason_and_costs_nothing(scene, counted, monkeypatch):
    import flexvox_core.choice as choice_mod

    def refusing(method):  # as accuracy.refusal would refuse one setting (a solver, a time) and not the others
        return "n = 3 refused here" if method.time == 3.0 else None

    monkeypatch.setattr(choice_mod, "refusal", refusing)
    _, frames, noise = scene
    choice = choose(frames, CODE, "diffusion", "time", (2.0, 3.0), noise=noise)
    refused = choice.candidates[1]
    assert refused.estimate is None and refused.why == "n = 3 refused here" and refused.runs == 0
    assert choice.value == 2.0 and choice.runs == 2 == len(counted)
    assert re.fullmatch(r"choosing cost \d+\.\d\d s: 1 candidate x \(a reconstruction and its estimate's probe\), "
                        r"2 reconstructions in all", choice.cost())


def test_default_candidates_per_knob():
    assert candidates_for("diffusion", "time", CODE) == TIMES == (1.5, 2.0, 3.0, 4.0, 6.0)
    assert candidates_for("motion-aware", "time", CODE) == MOTION_TIMES == (1.5, 3.0, 5.0, 8.0, 12.0)
    assert candidates_for("rebin", "block", CODE) == tuple(supported_divisions(CODE))
    assert [d.label for d in candidates_for("rebin", "block", CODE)] == ["1x1x4", "1x2x2", "2x1x2", "2x2x1"]
    mux = multiplexed_code((1, 3))  # by the placement of its demultiplexed slots
    assert [d.label for d in candidates_for(Method("rebin"), "block", mux)] == ["1x1x3", "1x3x1"]
    with pytest.raises(ValueError, match=r"gap-tv's iterations has no default candidates \(they exist for "
                                         r"diffusion: time; motion-aware: time; rebin: block\); give `candidates`"):
        candidates_for("gap-tv", "iterations", CODE)
    with pytest.raises(ValueError, match=r"diffusion has no option 'block' \(its options: "):
        candidates_for("diffusion", "block", CODE)


def test_a_bad_candidate_is_refused_before_anything_runs(counted):
    with pytest.raises(ValueError, match=r"`time` must be a positive finite number; got -1"):
        choose(np.zeros((2, 24, 24), np.float32), CODE, "diffusion", "time", (2.0, -1))
    with pytest.raises(ValueError, match=r"`candidates` for diffusion's time must hold at least one value; got none"):
        choose(np.zeros((2, 24, 24), np.float32), CODE, "diffusion", "time", ())
    with pytest.raises(ValueError, match=r"diffusion has no option 'iterations'"):
        choose(np.zeros((2, 24, 24), np.float32), CODE, "diffusion", "iterations", (1,))
    assert counted == []


def test_a_crop_off_the_tile_grid_is_chosen_on_with_the_code_s_phase_given_by_origin(scene):
    # the guide's region: reconstruct_video takes origin=(row, col); choose without it reconstructed and estimated
    # every candidate at the wrong phase, a wrong choice that looks right
    import flexvox_core as fv

    _, frames, noise = scene
    crop = frames[:, 3:27, 1:31]
    choice = choose(crop, CODE, "diffusion", "time", (2.0, 4.0), noise=noise, origin=(3, 1))
    np.testing.assert_array_equal(choice.video, fv.reconstruct_video(crop, CODE, choice.method, origin=(3, 1)))
    rolled = np.roll(CODE, (-3, -1), axis=(0, 1))
    assert choice.estimate.psnr == estimate_accuracy(crop, rolled, choice.method, noise=noise).psnr
    wrong = choose(crop, CODE, "diffusion", "time", (2.0, 4.0), noise=noise)
    assert not np.array_equal(wrong.video, choice.video)
    with pytest.raises(ValueError, match=r"`origin` must be two whole numbers >= 0"):
        choose(crop, CODE, "diffusion", "time", (2.0,), origin=(-1, 0))


def test_dropped_frames_given_as_indices_are_refused_before_anything_runs(counted):
    frames = np.zeros((4, 24, 24), np.float32)
    with pytest.raises(ValueError, match=r"`missing` must be 4 booleans \(or 0/1\), one per camera frame; got the "
                                         r"values 0 to 2"):
        choose(frames, CODE, "diffusion", "time", (2.0,), missing=[0, 2, 0, 1])
    assert counted == []


def test_a_recording_given_to_choose_or_to_the_estimate_says_which_call_takes_it(tmp_path, counted):
    # read as an array it was "`frames` must hold real numbers ...; got dtype object" (a path: "dtype <U..")
    sim = simulate_video(render_scene("balls", 2 * 4, 16, 16, seed=0), CODE, seed=2)
    path = write_simulation(tmp_path / "r.zarr", sim)
    for given, what in ((path, r"a path \(.*r.zarr\)"), (str(path), r"a path \(.*r.zarr\)"),
                        (open_recording(path), r"a Recording")):
        with pytest.raises(TypeError, match=rf"`frames` is {what}: a recording goes to fv.choose_recording\(recording, "
                                            r"method, knob\), which reads its code and dropped frames; fv.choose "
                                            r"takes frames \(F, H, W\) and a code"):
            choose(given, CODE, "diffusion", "time", (2.0,))
        with pytest.raises(TypeError, match=rf"`frames` is {what}: a recording goes to "
                                            r"fv.estimate_recording\(recording, method\), which reads"):
            estimate_accuracy(given, CODE, Method("diffusion"))
    assert counted == []


def test_a_recording_is_chosen_on_without_reading_its_ground_truth(tmp_path, monkeypatch):
    truth = render_scene("balls", 4 * 4, 24, 28, seed=0)
    sim = simulate_video(truth, CODE, effects={"read_noise": {"sigma": 2.0}}, seed=2)
    path = write_simulation(tmp_path / "r.zarr", sim)

    def poisoned(self):
        raise AssertionError("the choice read the ground truth")

    monkeypatch.setattr(Recording, "ground_truth", property(poisoned))
    monkeypatch.setattr(Recording, "has_ground_truth", property(poisoned))
    done = []
    choice = choose_recording(path, "diffusion", "time", (2.0, 4.0), progress=lambda d, t: done.append((d, t)))
    assert list(dict.fromkeys(done)) == [(0, 2), (1, 2), (2, 2)]  # within each candidate, and after it
    assert choice.candidates[0].estimate.noise.floor == pytest.approx((2.0 / 1000) ** 2)  # the recording's noise
    framed = choose(sim.frames, CODE, "diffusion", "time", (2.0, 4.0), noise=choice.estimate.noise, chunk_frames=16)
    assert [c.estimate.psnr for c in choice.candidates] == pytest.approx([c.estimate.psnr for c in framed.candidates])
    assert isinstance(choice, Choice) and choice.video.shape == truth.shape


def test_progress_is_called_within_each_candidate_so_that_raising_stops_the_choice_there(scene, counted):
    _, frames, noise = scene
    seen = []
    choose(frames, CODE, "diffusion", "time", (2.0, 4.0), noise=noise, progress=lambda d, t: seen.append((d, t)))
    done = [d for d, _ in seen]
    assert set(t for _, t in seen) == {2} and done == sorted(done) and done[-1] == 2
    assert done.count(0) > 1 and done.count(1) > 1  # between the chunks and runs of each, not only after it

    class Stop(Exception):
        pass

    def stop(done, total):
        if len(counted) == 5:  # inside the second candidate's probe (2 runs a candidate, a third call)
            raise Stop

    counted.clear()
    with pytest.raises(Stop):
        choose(frames, CODE, "diffusion", "time", (2.0, 4.0, 6.0), noise=noise, progress=stop)
    assert len(counted) == 5  # no candidate after it started


def test_integer_counts_are_chosen_on_as_relative_units(scene):
    _, frames, noise = scene
    relative = choose(frames, CODE, "diffusion", "time", (2.0, 4.0), noise=noise)
    counts = choose(np.round(frames * 4095).astype(np.uint16), CODE, "diffusion", "time", (2.0, 4.0), noise=noise,
                    white=4095)
    assert counts.value == relative.value
    assert counts.estimate.psnr == pytest.approx(relative.estimate.psnr, abs=0.05)


def test_a_single_value_for_candidates_is_refused_in_words(scene):
    _, frames, noise = scene
    with pytest.raises(TypeError, match=r"`candidates` must be a sequence of time values \(e\.g\. \(2\.0, 4\.0\)\); "
                                        r"got 2\.0"):
        choose(frames, CODE, "diffusion", "time", 2.0, noise=noise)


def test_a_candidate_refused_before_its_probe_counts_only_its_reconstruction(scene, counted, monkeypatch):
    real = accuracy.estimate_accuracy

    def refusing_early(frames, code, method, **kw):  # as a capture too small to probe is refused: before any run
        if method.time == 3.0:
            raise NotEstimable("refused before its probe")
        return real(frames, code, method, **kw)

    monkeypatch.setattr(accuracy, "estimate_accuracy", refusing_early)
    _, frames, noise = scene
    choice = choose(frames, CODE, "diffusion", "time", (2.0, 3.0), noise=noise)
    refused = choice.candidates[1]
    assert refused.why == "refused before its probe" and refused.runs == 1  # its reconstruction, no probe
    assert choice.runs == 3 == len(counted)


def test_the_estimate_says_how_many_reconstructions_it_made(scene, counted):
    _, frames, noise = scene
    alone = estimate_accuracy(frames, CODE, "diffusion", noise=noise)
    assert alone.runs == 2 == len(counted)  # the reconstruction and the probe
    given = estimate_accuracy(frames, CODE, "diffusion", noise=noise,
                              reconstruction=methods_pkg.run(frames, CODE, Method("diffusion")).video)
    assert given.runs == 1 and len(counted) == 4  # the probe alone (the given one was run here, not by it)
    with pytest.raises(NotEstimable, match="copies") as refused:
        estimate_accuracy(frames, CODE, Method("diffusion", time=0.25), noise=noise)
    assert refused.value.runs == 2


def test_a_candidate_given_twice_is_refused_before_any_run():
    """``candidates=[2, 2.0]`` ran the same reconstruction twice and listed it twice."""
    import flexvox_core as fv

    code = fv.design_code((2, 2)).code
    frames = fv.capture(fv.render_scene("balls", 8, 8, 8, seed=0), code)
    with pytest.raises(ValueError, match=r"`candidates` holds 2 and 2.0, the same time: give each value once"):
        fv.choose(frames, code, "diffusion", "time", [2, 4, 2.0])
