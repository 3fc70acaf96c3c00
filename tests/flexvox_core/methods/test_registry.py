"""Methods as objects: the registry, their options and capabilities, and adding one."""

import re

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
    ("rebin", {"block": "2x2"}, r"`block` must be three whole numbers a,b,c \(rows, columns, slots of the division\), "
                                r"e.g. 2,2,4; got '2x2'"),
    ("rebin", {"block": (2, 2)}, r"`block` must be a Division, written 2x2x4 or 2,2,4 or given as \(2, 2, 4\), or None "
                                 r"\(the default division\); got \(2, 2\)"),
    ("motion-aware", {"time": 0}, r"`time` must be a finite number > 0; got 0"),
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


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"refine_time": -1}, r"^`refine_time` must be a number from 0 to 10526 or None \(\(K/16\)²\); got -1$"),
    ({"time": 0}, r"^`time` must be a finite number > 0; got 0$"),
    ({"slow_reach": -1}, r"^`slow_reach` must be a number from 0 to 1000 \(sampling periods\) or None; got -1$"),
    ({"flow": "lucas"}, r"^`flow` must be one of dis, deepflow, farneback, tvl1; got 'lucas'$"),
])
def test_one_rule_one_message_through_method_and_motion_options(kwargs, match):
    """Motion-aware's options are MotionOptions' fields, declared once (their metadata): the same words whichever
    door a value comes in by."""
    from flexvox_core.motion.options import MotionOptions
    from flexvox_core.motion.streaming import StreamingMotionAware
    from tests.flexvox_core.gpu.tiny import CODE

    with pytest.raises(ValueError, match=match):
        Method("motion-aware", **kwargs)
    with pytest.raises(ValueError, match=match):
        MotionOptions(**kwargs)
    with pytest.raises(ValueError, match=match):
        StreamingMotionAware(CODE, **kwargs)


def test_motion_aware_options_are_motion_options_fields():
    """The method offers the fields that declare a kind, with their defaults and rules; its label and bench rank
    read the fields."""
    import dataclasses

    from flexvox_core.motion.options import MotionOptions

    spec = Method("motion-aware").spec
    declared = {f.name: f for f in dataclasses.fields(MotionOptions) if f.metadata["kind"]}
    assert [o.name for o in spec.option_specs] == list(declared)
    assert [o.name for o in spec.option_specs] == ["flow", "time", "passes", "refine_time", "slow_reach",
                                                   "local_choice", "noise_aware"]
    for o in spec.option_specs:
        assert (o.default, o.rule, o.kind.name) == (declared[o.name].default, declared[o.name].metadata["rule"],
                                                    declared[o.name].metadata["kind"])
    m = Method("motion-aware", passes=2, refine_time=0.5, local_choice=False, noise_aware=False, slow_reach=1)
    assert m.label == "motion-aware dis n=5 x2 +refine 0.5 slow-reach 1 gather-only noise-blind"
    row = Method("motion-aware", time=2.0).as_dict()
    assert spec.bench_rank(row, dict(Method("motion-aware", refine_time=0.3).values), None) == ((0,), True)
    assert spec.bench_rank(row, dict(m.values), None) == ((4,), False)  # passes, slow reach, two flags


def test_motion_aware_function_shows_every_option_in_its_signature():
    import dataclasses
    import inspect

    from flexvox_core.motion.options import MotionOptions
    from flexvox_core.motion.pipeline import motion_aware

    params = inspect.signature(motion_aware).parameters
    assert list(params) == ["frames", "code", *(f.name for f in dataclasses.fields(MotionOptions)), "sample_range",
                            "missing", "device"]
    assert params["slow_speed"].default == MotionOptions.__dataclass_fields__["slow_speed"].default
    with pytest.raises(TypeError, match="slow_sped"):
        motion_aware(np.zeros((1, 4, 4), np.float32), np.eye(4, dtype=bool).reshape(2, 2, 4), slow_sped=1)


@pytest.mark.parametrize("block", [(2, 2, 4), [2, 2, 4], "2x2x4", "2,2,4", " 2, 2, 4 "])
def test_a_division_option_takes_its_spellings(block):
    from flexvox_core.divisions import Division

    m = Method("rebin", block=block)
    assert m.block == Division(2, 2, 4) and m == Method("rebin", block=Division(2, 2, 4))


def test_label_is_a_property_and_calling_it_still_works():
    m = Method("motion-aware", passes=2)
    assert isinstance(m.label, str) and m.label == "motion-aware dis n=5 x2"
    assert m.label() == m.label and type(m.label()) is str


@pytest.mark.parametrize("name", ["diffusion", "rebin", "gap-tv", "motion-aware"])
def test_every_method_takes_a_frozen_options_object(name):
    """A method's options object has an attribute per option and cannot be changed (diffusion's as motion-aware's)."""
    import dataclasses

    m = Method(name)
    options = m.options
    assert dataclasses.is_dataclass(options)
    assert {f.name for f in dataclasses.fields(options)} >= {o.name for o in m.spec.option_specs}
    for o in m.spec.option_specs:
        assert getattr(options, o.name) == getattr(m, o.name) or o.name == "slow_reach"  # None: SLOW_REACH
    with pytest.raises(dataclasses.FrozenInstanceError):
        object.__getattribute__(options, "__setattr__")(m.spec.option_specs[0].name, 1)


def test_the_command_line_s_auto_in_python_says_where_python_chooses_a_knob():
    with pytest.raises(ValueError, match=r"`time` must be a positive finite number; got 'auto' \(`time=\"auto\"` "
                                         r"is the command line's: in Python fv.choose\(frames, code, 'diffusion', "
                                         r"'time'\) chooses it by the estimated accuracy, fv.choose_recording from a "
                                         r"recording\)"):
        Method("diffusion", time="auto")
    with pytest.raises(ValueError, match=r"got 'auto' \(`block=\"auto\"` is the command line's: in Python "
                                         r"fv.choose\(frames, code, 'rebin', 'block'\)"):
        Method("rebin", block="auto")
    with pytest.raises(ValueError, match=r"`iterations` must be a whole number >= 1; got 'two'$"):
        Method("gap-tv", iterations="two")


@pytest.mark.parametrize(("name", "hint"), [
    ("motion_aware", r": write it 'motion-aware'$"),
    ("Motion-Aware", r": write it 'motion-aware'$"),
    ("rebin ", r": write it 'rebin'$"),
    ("GAP TV", r": write it 'gap-tv'$"),
    ("gaptv", r": did you mean 'gap-tv'\?$"),
    ("nc", r": 'nc' is a solver of the diffusion method: \('diffusion', solver='nc'\) \(its default\)$"),
    ("explicit", r": 'explicit' is a solver of the diffusion method: \('diffusion', solver='explicit'\)$"),
    ("magic", r"$"),
])
def test_a_near_miss_name_is_refused_with_the_name_meant(name, hint):
    # never converted silently: the refusal says what to write
    with pytest.raises(ValueError, match=r"`method` must be one of rebin, diffusion, gap-tv, motion-aware; got "
                                         + re.escape(repr(name)) + hint):
        Method(name)
