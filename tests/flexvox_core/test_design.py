import numpy as np
import pytest

from flexvox_core.codes import (
    code_from_order,
    neighbour_separation,
    order_from_code,
    sequential_order,
    verify,
)
from flexvox_core.design import STATUS_INFEASIBLE, STATUS_SUCCESS, design_code
from flexvox_core.divisions import Division, enumerate_divisions, parse_division

from .independent import supports_all_slow

ALL_TILES_TO_6 = [(m, n) for m in range(1, 7) for n in range(1, 7)]
INFEASIBLE_ALL_DIVISIONS = {(6, 6)}  # HiGHS proves it (about 9 s); see flexvox_core.design


@pytest.mark.parametrize("tile", ALL_TILES_TO_6, ids=lambda t: f"{t[0]}x{t[1]}")
def test_eq1_solutions_verify_for_every_tile_up_to_6x6(tile):
    result = design_code(tile, separation=0)
    if tile in INFEASIBLE_ALL_DIVISIONS:
        assert result.status == STATUS_INFEASIBLE and not result.success
        assert result.order is None and "infeasible" in result.message
        return
    assert result.status == STATUS_SUCCESS and result.success
    assert supports_all_slow(result.order)
    assert verify(result.code).supports_all
    assert result.supported == enumerate_divisions(tile)


@pytest.mark.parametrize(
    "tile, gap", [((2, 2), 1), ((2, 4), 2), ((3, 3), 2), ((4, 4), 4), ((3, 5), 3), ((4, 8), 8)]
)
def test_auto_separation_reaches_k_over_4(tile, gap):
    result = design_code(tile)
    assert result.success and supports_all_slow(result.order)
    assert result.separation == gap == neighbour_separation(result.order)


def test_separation_beyond_reach_is_an_infeasible_result_not_an_exception():
    result = design_code((4, 4), separation=5)
    assert result.status == STATUS_INFEASIBLE and not result.success
    assert result.code is None
    assert "gap >= 5" in result.message


def test_design_is_deterministic_and_canonical():
    a, b = design_code((4, 4)), design_code((4, 4))
    assert np.array_equal(a.order, b.order)
    assert a.order[0, 0] == 0  # the canonical form starts the first pixel at slot 0


def test_subset_of_divisions():
    divs = [parse_division("4x4x1", (4, 4)), parse_division("1x1x16", (4, 4))]
    result = design_code((4, 4), divisions=divs, separation=0)
    assert result.success
    assert set(divs) <= set(result.supported)


def test_sequential_firing_fails_2x2x4_as_the_seed_says():
    seq = code_from_order(sequential_order((4, 4)))
    r = verify(seq)
    assert Division(2, 2, 4) in r.unsupported
    assert not supports_all_slow(sequential_order((4, 4)))
    # ... while the designed code supports it.
    assert Division(2, 2, 4) in verify(design_code((4, 4)).code).supported


def test_verify_reports_multiplexed_codes_as_not_identity():
    code = np.ones((1, 3, 3), dtype=bool)
    r = verify(code)
    assert not r.identity and "not an identity code" in r.message


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"separation": -1}, r"`separation` must be 'auto' or a whole number >= 0; got -1"),
        ({"separation": "max"}, r"`separation` must be 'auto' or a whole number >= 0; got 'max'"),
        ({"node_limit": 0}, r"`node_limit` must be >= 1; got 0"),
        ({"divisions": [Division(3, 1, 4)]}, r"division 3x1x4 does not divide a 4x4 tile"),
        ({"divisions": []}, r"`divisions` must name at least one division"),
    ],
)
def test_design_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        design_code((4, 4), **kwargs)


def test_design_rejects_bad_tiles():
    with pytest.raises(ValueError, match=r"side n must be between 1 and 8; got 9"):
        design_code((2, 9))


def test_order_code_round_trip_and_errors():
    order = design_code((2, 4)).order
    assert np.array_equal(order_from_code(code_from_order(order)), order)
    with pytest.raises(ValueError, match=r"each slot 0..3 exactly once"):
        code_from_order([[0, 0], [1, 2]])
    with pytest.raises(ValueError, match=r"not an identity code"):
        order_from_code(np.ones((2, 2, 4), dtype=bool))
    with pytest.raises(ValueError, match=r"must have K = 4 slots; got 3"):
        verify(np.zeros((2, 2, 3), dtype=bool))
    with pytest.raises(ValueError, match=r"values must be 0/1"):
        verify(np.full((1, 1, 1), 2))


def test_a_code_in_another_axis_order_or_still_in_its_result_is_refused_with_the_fix():
    from flexvox_core.codes import validate_code
    from flexvox_core.forward import tiled_code
    from flexvox_core.multiplex import multiplexed_code

    design = design_code((2, 4))
    with pytest.raises(ValueError, match=r"`code` of a 8x2 tile must have K = 16 slots; got 4: a code is \(m, n, K\) "
                                         r"and this one looks like \(K, m, n\) = \(8, 2, 4\): "
                                         r"np.moveaxis\(code, 0, -1\)"):
        validate_code(np.moveaxis(design.code, -1, 0))
    with pytest.raises(ValueError, match=r"`code` must be the code's \(m, n, K\) array; got a DesignResult: give "
                                         r"its `.code`"):
        validate_code(design)
    with pytest.raises(ValueError, match=r"got a MultiplexedCode: give its `.code`"):
        validate_code(multiplexed_code((1, 3)))
    with pytest.raises(ValueError, match=r"a code is \(m, n, K\) and this one looks like \(K, H, W\) = "
                                         r"\(8, 6, 9\), a code tiled over a sensor \(fv.tiled_code\): give the "
                                         r"tile's code"):
        validate_code(tiled_code(design.code, 6, 9))


def test_a_method_or_a_tile_in_the_code_s_place_is_refused_with_the_order_of_the_arguments():
    # reconstruct_video(frames, "diffusion") had said "`code` must have shape (m, n, K); got 0 dimensions ()"
    import flexvox_core as fv

    frames = np.zeros((2, 8, 8), np.float32)
    for given, got in (("diffusion", r"the text 'diffusion'"), ("4x4", r"the text '4x4'"),
                       (fv.Method("diffusion"), r"a Method")):
        with pytest.raises(ValueError, match=r"`code` must be the code's \(m, n, K\) array \(a tile's: "
                                             rf"fv.design_code\(tile\).code\); got {got}: a method goes after the "
                                             r"code, \(frames, code, method\)"):
            fv.reconstruct_video(frames, given)
    with pytest.raises(ValueError, match=r"got the text 'gap-tv': a method goes after the code"):
        fv.run(frames, "gap-tv")


def test_require_names_the_tile_and_the_reason():
    assert design_code((2, 2)).require().shape == (2, 2, 4)
    with pytest.raises(ValueError, match=r"no code for a 2x2 tile: no 2x2 code has a 4-neighbour gap >= 2"):
        design_code((2, 2), separation=2).require()
    with pytest.raises(ValueError, match=r"`separation` 5 is more than any 2x2 code can have: .* at most 2 apart"):
        design_code((2, 2), separation=5)


def test_a_tile_is_written_mxn_too():
    np.testing.assert_array_equal(design_code("4x4").code, design_code((4, 4)).code)
    assert design_code("2x4").tile == (2, 4)
    with pytest.raises(ValueError, match=r"tile must be written MxN with two whole numbers, e.g. 4x4; got '4 by 4'"):
        design_code("4 by 4")


def test_a_tile_with_no_code_at_any_gap_is_not_blamed_on_the_gap(monkeypatch):
    # 6x6 with every division is infeasible by Eq. 1 alone (gap 1): the message had said "with a neighbour gap >= 9"
    # and sent the user to a smaller gap, which fails the same way. The solver is stood in for (HiGHS takes ~9 s).
    from flexvox_core import design

    monkeypatch.setattr(design, "_solve", lambda m, n, A, gap, limit: (STATUS_INFEASIBLE, None))
    result = design.design_code((4, 4))
    assert result.status == STATUS_INFEASIBLE and "gap" not in result.message
    assert result.message.startswith("no 4x4 code supports ")
    assert "infeasible; ask for fewer divisions" in result.message
    demanded = design.design_code((4, 4), separation=3)
    assert "gap" not in demanded.message and "infeasible; ask for fewer divisions" in demanded.message
