"""Option kinds: how a value of each kind is typed, read back and offered, the same for every front end."""

import pytest

from flexvox_core.divisions import Division
from flexvox_core.methods import Method, Option, get, specs
from flexvox_core.methods.option_kinds import DIVISION, FIELDS, FLAG, KINDS, TRIPLE


def test_every_option_has_a_kind_with_a_field_and_text_that_reads_back():
    for spec in specs():
        for o in spec.option_specs:
            assert o.kind in KINDS.values() and o.kind.field in FIELDS, (spec.name, o.name)
            value = Method(spec.name).values[o.name]
            if value is not None and not o.kind.needs_tile:
                assert o.kind.parse(o, o.kind.format(value)) == value, (spec.name, o.name)
    block = get("rebin").option("block")
    assert DIVISION.parse(block, DIVISION.format(Division(2, 1, 4)), tile=(2, 4)) == Division(2, 1, 4)


@pytest.mark.parametrize("method, name, text, value", [
    ("diffusion", "time", "2.5", 2.5),
    ("gap-tv", "iterations", " 7 ", 7),
    ("diffusion", "solver", "steady", "steady"),
    ("rebin", "interpolate", "off", False),
    ("diffusion", "tensor", "0.2, 0.3, 1", (0.2, 0.3, 1.0)),
    ("diffusion", "tensor", "1x1x0.05", (1.0, 1.0, 0.05)),
    ("rebin", "block", "2x2x1", Division(2, 2, 1)),
])
def test_text_is_read_by_the_kind(method, name, text, value):
    o = get(method).option(name)
    assert o.kind.parse(o, text, tile=(2, 2)) == value


@pytest.mark.parametrize("method, name, text, match", [
    ("diffusion", "time", "fast", r"`time` must be a number; got 'fast'"),
    ("gap-tv", "iterations", "1.5", r"`iterations` must be a whole number; got '1.5'"),
    ("diffusion", "solver", "cg", r"`solver` must be one of nc, explicit, steady; got 'cg'"),
    ("rebin", "interpolate", "maybe", r"`interpolate` must be true or false; got 'maybe'"),
    ("diffusion", "tensor", "1,2", r"`tensor` must be three numbers separated by commas; got '1,2'"),
    ("rebin", "block", "2,2", r"`block` must be three whole numbers a,b,c \(rows, columns, slots of the division\), "
                              r"e.g. 2,2,4; got '2,2'"),
    ("rebin", "block", "3,1,1", r"division 3x1x1 does not divide a 2x2 tile"),
])
def test_text_that_is_not_of_the_kind_is_refused_naming_the_option_and_the_syntax(method, name, text, match):
    o = get(method).option(name)
    with pytest.raises(ValueError, match=match):
        o.kind.parse(o, text, tile=(2, 2))


def test_a_front_end_names_the_option_its_own_way():
    o = get("diffusion").option("tensor")
    with pytest.raises(ValueError, match=r"^--tensor must be three numbers separated by commas; got '1,1'$"):
        o.kind.parse(o, "1,1", name="--tensor")


def test_the_command_line_asks_the_kind():
    interpolate, block = get("rebin").option("interpolate"), get("rebin").option("block")
    assert FLAG.flag(interpolate) == "--no-interpolate" and FLAG.help_words(interpolate).startswith("no ")
    assert FLAG.arguments(interpolate, "--no-interpolate") == {"action": "store_const", "const": False}
    assert DIVISION.arguments(block, "--block") == {"metavar": "a,b,c"}  # read later, with the tile
    tensor = get("diffusion").option("tensor")
    kw = TRIPLE.arguments(tensor, "--tensor")
    assert kw["metavar"] == "a,b,c" and kw["type"]("1,1,0.5") == (1.0, 1.0, 0.5)
    refine = get("motion-aware").option("refine_time")
    assert refine.kind.default_text(refine) == "(K/16)²"  # words for a default that depends on the capture
    reach = get("motion-aware").option("slow_reach")
    assert reach.kind.default_text(reach) == "0.75"


def test_an_option_takes_its_kind_by_name_or_as_the_kind():
    by_name = Option("t", None, "three numbers", lambda v: True, kind="triple")
    assert by_name.kind is TRIPLE and Option("t", None, "", lambda v: True, kind=TRIPLE).kind is TRIPLE
    with pytest.raises(ValueError, match=r"`kind` of option 't' must be one of number, integer, choice, flag, "
                                         r"triple, division; got 'vector'"):
        Option("t", None, "", lambda v: True, kind="vector")
