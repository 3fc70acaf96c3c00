from fractions import Fraction

import pytest
from hypothesis import given
from hypothesis import strategies as st

from flexvox_core.divisions import Division, check_division, enumerate_divisions, parse_division
from flexvox_core.tiles import parse_tile, validate_tile


@pytest.mark.parametrize("text, tile", [("4x4", (4, 4)), ("2X4", (2, 4)), (" 8x8 ", (8, 8)), ("1×3", (1, 3))])
def test_parse_tile(text, tile):
    assert parse_tile(text) == tile


@pytest.mark.parametrize(
    "text, match",
    [
        ("0x4", r"side m must be between 1 and 8; got 0"),
        ("4x0", r"side n must be between 1 and 8; got 0"),
        ("-2x2", r"side m must be between 1 and 8; got -2"),
        ("9x9", r"side m must be between 1 and 8; got 9"),
        ("4x16", r"side n must be between 1 and 8; got 16"),
        ("4", r"must be written MxN with two whole numbers"),
        ("ax4", r"must be written MxN with two whole numbers"),
        ("2.5x4", r"must be written MxN"),
        ("", r"must be written MxN"),
    ],
)
def test_parse_tile_rejects(text, match):
    with pytest.raises(ValueError, match=match):
        parse_tile(text)


def test_validate_tile_rejects_non_integers():
    with pytest.raises(ValueError, match=r"side m must be an integer; got 2.0"):
        validate_tile((2.0, 2))
    with pytest.raises(ValueError, match=r"must be two integers"):
        validate_tile(4)


def test_divisions_of_4x4_match_the_seed():
    divs = enumerate_divisions((4, 4))
    assert len(divs) == 9
    # The paper's five distinct resolutions for K = 16 (its footnote 1), with SR = 1/TR.
    assert sorted({d.tr for d in divs}) == [1, 2, 4, 8, 16]
    assert all(d.tr * d.sr == 1 for d in divs)
    assert Division(2, 2, 4) in divs and Division(2, 2, 4).sr == Fraction(1, 4)


@given(st.integers(1, 8), st.integers(1, 8))
def test_divisions_are_exactly_the_valid_block_shapes(m, n):
    K = m * n
    divs = set(enumerate_divisions((m, n)))
    brute = {
        Division(a, b, c)
        for a in range(1, m + 1)
        for b in range(1, n + 1)
        for c in range(1, K + 1)
        if m % a == 0 and n % b == 0 and K % c == 0 and a * b * c == K
    }
    assert divs == brute
    for d in divs:
        assert d.tr == K // d.c and d.sr == Fraction(1, d.a * d.b)


def test_parse_division():
    assert parse_division("2x2x4", (4, 4)) == Division(2, 2, 4)
    with pytest.raises(ValueError, match=r"division 3x1x4 does not divide a 4x4 tile"):
        parse_division("3x1x4", (4, 4))
    with pytest.raises(ValueError, match=r"must be written AxBxC"):
        parse_division("2x2")
    with pytest.raises(ValueError, match=r"does not divide a 2x2 tile"):
        check_division(Division(1, 1, 2), (2, 2))


def test_parse_division_takes_every_spelling():
    want = Division(2, 2, 4)
    for spelling in ("2x2x4", "2X2X4", "2×2×4", " 2 , 2 , 4 ", "2,2,4", (2, 2, 4), [2, 2, 4], want):
        assert parse_division(spelling, (4, 4)) == want
    with pytest.raises(ValueError, match=r"AxBxC or A,B,C .*got '2x2,4'"):
        parse_division("2x2,4")  # one separator throughout
    with pytest.raises(ValueError, match=r"three whole numbers .*got \(2, 2\.0, 4\)"):
        parse_division((2, 2.0, 4))
    with pytest.raises(ValueError, match=r"sizes must be >= 1; got 0x2x4"):
        parse_division((0, 2, 4))
    with pytest.raises(ValueError, match=r"does not divide a 4x4 tile"):
        parse_division((3, 1, 4), (4, 4))
