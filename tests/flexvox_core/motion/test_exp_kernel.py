"""exp_kernel.exp32, the gathers' vectorizable float32 exp, against numpy's float64 exp."""

import numba
import numpy as np

from flexvox_core.motion.exp_kernel import exp32


@numba.njit
def each(x):
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = exp32(x[i])
    return out


def test_exp32_is_within_one_ulp_of_exp_from_minus_87_to_0():
    rng = np.random.default_rng(5)
    x = np.concatenate([-np.linspace(0, 87, 2_000_001, dtype=np.float32),
                        -np.abs(rng.standard_normal(1_000_000)).astype(np.float32) * 3,
                        np.array([0, -0.0, -1e-30, -1e-7, -86.99999, -87], np.float32)])
    got = each(x)
    assert got.dtype == np.float32 and got[0] == 1
    want = np.exp(x.astype(np.float64))
    ulp = np.spacing(want.astype(np.float32)).astype(np.float64)
    err = np.abs(got.astype(np.float64) - want)
    assert err.max(initial=0) > 0  # not np.exp itself
    assert (err <= ulp).all()


def test_exp32_is_0_below_minus_87_and_nan_stays_nan():
    np.testing.assert_array_equal(each(np.array([-87.5, -100, -1e30, -np.inf], np.float32)), 0)  # e**x < 1.7e-38
    assert np.isnan(each(np.array([np.nan], np.float32))[0])
