"""The checks of real-number parameters: named errors, no strings or bools taken for numbers."""

import numpy as np
import pytest

from flexvox_core.numbers import checked_number, number_pair, positive_number


def test_checked_number_takes_real_numbers_that_meet_the_rule():
    assert checked_number("time", 5, "a finite number > 0", lambda v: v > 0) == 5.0
    assert checked_number("time", np.float32(0.5), "a finite number > 0", lambda v: v > 0) == 0.5
    for bad in ("5", True, float("nan"), -1.0, None):
        with pytest.raises(ValueError, match=r"`time` must be a finite number > 0; got "):
            checked_number("time", bad, "a finite number > 0", lambda v: v > 0)


def test_number_pair_names_the_value_and_the_rule():
    assert number_pair("sample_range", (0, 1)) == (0.0, 1.0)
    with pytest.raises(ValueError, match=r"`sample_range` must be two numbers \(lo, hi\); got 3"):
        number_pair("sample_range", 3)
    with pytest.raises(ValueError, match=r"`sample_range` must be two numbers \(lo, hi\) or None; got \(1, 2, 3\)"):
        number_pair("sample_range", (1, 2, 3), "two numbers (lo, hi) or None")


def test_positive_number_still_converts_text():
    assert positive_number("`time`", "2") == 2.0  # its callers' behaviour, kept
