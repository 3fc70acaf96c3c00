"""e**x in float32 without a call: a polynomial that LLVM vectorizes inside a loop (numba's ``math.exp`` is a call to
the C library, which keeps the loop scalar; numba has no vector math library here). The gathers' range and
trajectory weights use it (:mod:`~flexvox_core.motion.mcnc_kernel`, :mod:`~flexvox_core.motion.longreach_kernel`);
``tests/flexvox_core/motion/test_exp_kernel.py`` compares it with numpy's float64 exp.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numba import types
from numba.core.extending import intrinsic


@intrinsic
def _float32_bits(typingctx: Any, bits: Any) -> Any:
    """The float32 whose bit pattern is the low 32 bits of the integer ``bits`` (compiled code only)."""
    if not isinstance(bits, types.Integer):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        value = args[0]
        i32 = context.get_value_type(types.int32)
        if value.type.width > 32:
            value = builder.trunc(value, i32)
        elif value.type.width < 32:
            value = builder.sext(value, i32)
        return builder.bitcast(value, context.get_value_type(types.float32))

    return types.float32(bits), codegen


_float32_from_bits: Any = _float32_bits
""":func:`_float32_bits` as called (one argument: numba passes the typing context)."""


@numba.njit(inline="always", nogil=True, cache=True, error_model="numpy")
def exp32(x: Any) -> Any:
    """e**x in float32 for x <= 0 (float32), branch-free so that a loop calling it vectorizes (numba's math.exp is
    a call): Cephes' expf (x = n·ln 2 + r, |r| <= ln2/2, a polynomial of r, times 2**n built in the exponent bits).
    Within 1 ulp of e**x for -87 <= x <= 0 (a test checks 3 M points); 0 below -87 (where e**x < 1.7e-38); NaN
    gives NaN."""
    lo = np.float32(-87.0)
    z = max(x, lo)
    n = np.floor(z * np.float32(1.44269504088896341) + np.float32(0.5))
    r = z - n * np.float32(0.693359375) - n * np.float32(-2.12194440e-4)
    p = np.float32(1.9875691500e-4)
    p = p * r + np.float32(1.3981999507e-3)
    p = p * r + np.float32(8.3334519073e-3)
    p = p * r + np.float32(4.1665795894e-2)
    p = p * r + np.float32(1.6666665459e-1)
    p = p * r + np.float32(5.0000001201e-1)
    p = p * (r * r) + r + np.float32(1)
    scale = _float32_from_bits((np.int32(n) + np.int32(127)) << np.int32(23))
    e = p * scale
    return e if x >= lo else (np.float32(0) if x < lo else x)
