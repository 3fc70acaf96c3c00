"""Methods as objects: the registry, their options and capabilities, and adding one."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method, MethodSpec, get, names, register, run, unregister

from .tiny_method import FrameMean, frame_mean_registered

CODE = design_code((2, 2)).code


@pytest.fixture
def frame_mean():
    with frame_mean_registered():
        yield get("frame-mean")


def test_a_method_is_one_class_and_one_registration(frame_mean, rng):
    assert names()[-1] == "frame-mean" and Method("frame-mean").label() == "frame-mean r=1"
    truth = rng.random((10 * 4, 6, 8)).astype(np.float32)
    frames = capture(truth, CODE) * 3  # outside [0, 1]: the whole range rescales it
    m = Method("frame-mean", radius=2)
    whole = run(frames, CODE, m, chunk_frames=None, extras=True)
    chunked = run(frames, CODE, m, chunk_frames=3, extras=True)
    np.testing.assert_array_equal(chunked.video, whole.video)  # overlap and sample range from the object
    np.testing.assert_array_equal(whole.extras["frame"], np.repeat(np.arange(10), 4))
    # Extras are trimmed like the video: each chunk's frame numbers count from its own context.
    starts = [0, 3, 6, 9]
    expected = np.concatenate([np.repeat(np.arange(s, min(10, s + 3)) - max(0, s - 2), 4) for s in starts])
    np.testing.assert_array_equal(chunked.extras["frame"], expected)
    assert 0 <= whole.video.min() and whole.video.max() <= 1 and whole.video.dtype == np.float32


def test_registration_does_not_leak():
    with frame_mean_registered():
        assert "frame-mean" in names()
    assert "frame-mean" not in names()
    with pytest.raises(ValueError, match=r"`method` must be one of rebin, diffusion, gap-tv, motion-aware; "
                                         r"got 'frame-mean'"):
        Method("frame-mean")


def test_register_refusals(frame_mean):
    with pytest.raises(ValueError, match=r"a method needs a name of its own; 'frame-mean' is taken"):
        register(FrameMean())
    with pytest.raises(ValueError, match=r"`spec` must be a MethodSpec instance; got 'rebin'"):
        register("rebin")
    with pytest.raises(ValueError, match=r"'rebin' is a built-in method and cannot be removed"):
        unregister("rebin")
    with pytest.raises(ValueError, match=r"no method 'nothing' is registered"):
        unregister("nothing")


@pytest.mark.parametrize("name, kwargs, match", [
    ("frame-mean", {"radius": -1}, r"`radius` must be a whole number >= 0; got -1"),
    ("frame-mean", {"radius": 1.5}, r"`radius` must be a whole number >= 0; got 1.5"),
    ("frame-mean", {"tensor": (1, 1, 1)}, r"`tensor` is not an option of frame-mean \(its options: radius\)"),
    ("gap-tv", {"iterations": 0}, r"`iterations` must be a whole number >= 1; got 0"),
    ("gap-tv", {"tv_weight": 0}, r"`tv_weight` must be a finite number > 0; got 0"),
    ("rebin", {"interpolate": 1}, r"`interpolate` must be True or False; got 1"),
    ("rebin", {"block": "2x2x1"}, r"`block` must be a Division .* or None \(the default division\); got '2x2x1'"),
    ("motion-aware", {"flow": "lucas"}, r"`flow` must be one of dis, deepflow, farneback, tvl1; got 'lucas'"),
    ("motion-aware", {"passes": 0}, r"`passes` must be a whole number >= 1; got 0"),
    ("motion-aware", {"refine_time": -1.0},
     r"`refine_time` must be a number from 0 to 10526 or None \(\(K/16\)²\); got -1.0"),
    ("motion-aware", {"refine_time": 1e6},
     r"`refine_time` must be a number from 0 to 10526 or None \(\(K/16\)²\); got 1000000.0"),
    ("motion-aware", {"slow_reach": 1e308},
     r"`slow_reach` must be a number from 0 to 1000 \(sampling periods\) or None; got 1e\+308"),
    ("diffusion", {"time": 0}, r"`time` must be a positive finite number; got 0"),
])
def test_options_are_checked_naming_the_value_and_the_rule(frame_mean, name, kwargs, match):
    with pytest.raises(ValueError, match=match):
        Method(name, **kwargs)


def test_capabilities_not_names_say_what_a_method_needs():
    assert [s.needs_sample_range for s in map(get, names())] == [False, False, False, True]
    assert get("motion-aware").extras == ("flow", "tr") and get("diffusion").extras == ()
    assert Method("diffusion", solver="steady").overlap(8) is None  # a global solve
    assert Method("rebin", interpolate=False).overlap(8) == 0 and Method("gap-tv").overlap(8) == 0
    assert all(isinstance(get(n), MethodSpec) for n in names())


def test_method_values_read_like_a_frozen_record():
    m = Method("motion-aware", time=3.0)
    assert m == Method("motion-aware", time=3.0) and hash(m) == hash(Method("motion-aware", time=3.0))
    assert m != Method("motion-aware") and (m.name, m.time, m.passes, m.slow_reach) == ("motion-aware", 3.0, 1, None)
    assert m.as_dict() == {"name": "motion-aware", "flow": "dis", "time": 3.0, "passes": 1, "refine_time": None,
                           "slow_reach": None, "local_choice": True, "noise_aware": True}
    assert Method("diffusion").time == 1.5 and Method().time == 5.0  # each method's own default
    assert Method() == Method("motion-aware")  # the default method
    with pytest.raises(AttributeError, match=r"gap-tv has no option 'tensor' \(its options: iterations, tv_weight, "
                                             r"tv_iterations\)"):
        Method("gap-tv").tensor  # noqa: B018 - the attribute raises
    with pytest.raises(AttributeError, match=r"a Method is read-only"):
        m.time = 4.0
    import pickle

    assert pickle.loads(pickle.dumps(m)) == m


def test_a_bench_row_is_matched_by_the_options_it_carries():
    import json

    from flexvox_core.divisions import Division

    code = design_code((2, 4)).code
    methods = [
        Method("rebin", block=Division(2, 1, 4), interpolate=False),
        Method("diffusion", tensor=(0.05, 0.05, 1), time=8),
        Method("gap-tv"),
        Method("motion-aware", refine_time=1.0, passes=2),
        Method("motion-aware", slow_reach=2.0),
        Method("motion-aware", local_choice=False, noise_aware=False),
    ]
    for m in methods:
        row = json.loads(json.dumps(m.as_dict()))  # as results.csv and the shipped table hold it
        assert m.spec.bench_rank(row, dict(m.values), code)[1], m
    # One option apart: no longer the same row (the bench axis aside, which figures are interpolated along).
    apart = [
        (Method("rebin", block=Division(2, 1, 4)), {"interpolate": False}),
        (Method("diffusion"), {"solver": "explicit"}),
        (Method("gap-tv"), {"tv_weight": 1.0}),
        (Method("motion-aware"), {"slow_reach": 2.0}),
        (Method("motion-aware"), {"noise_aware": False}),
    ]
    for m, change in apart:
        row = {**json.loads(json.dumps(m.as_dict())), **change}
        assert not m.spec.bench_rank(row, dict(m.values), code)[1], (m, change)
    assert get("gap-tv").bench_rank({"name": "gap-tv", "iterations": 5, "tv_weight": 0.3, "tv_iterations": 4},
                                    dict(Method("gap-tv").values), code) == ((0,), True)  # iterations: the axis
