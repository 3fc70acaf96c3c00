"""The trajectory gather's leave-one-out by brute force: the gather run again without each sample."""

import numpy as np

from flexvox_core.forward import tiled_order
from flexvox_core.motion import motion_compensated_nc


def gather_loo_errors(sparse, mask, flow, code, loo, **kw) -> list[float]:
    """|loo − the gather's value at each gathered sample's voxel without that sample| for every sample whose
    voxel is not in ``kw["still"]``; a voxel in it must have no estimate (NaN) in ``loo``."""
    F, H, W = loo.shape
    K = code.shape[2]
    still = kw["still"]
    order = tiled_order(code, H, W)
    errors = []
    for f in range(F):
        for y in range(H):
            for x in range(W):
                s = f * K + order[y, x]
                if still[s, y, x]:
                    assert np.isnan(loo[f, y, x])  # not gathered: nothing written
                    continue
                without, kept = sparse.copy(), mask.copy()
                without[s, y, x], kept[s, y, x] = 0, False
                ref = motion_compensated_nc(without, kept, flow, keep_samples=False,
                                            fallback=np.full_like(sparse, np.nan), **kw)[s, y, x]
                errors.append(abs(ref - loo[f, y, x]))
    return errors
