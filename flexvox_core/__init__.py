"""flexvox_core — the numerics of flexible-voxel videography.

Codes (the seed's integer program), the forward model, simulation, reconstruction,
optical flow, metrics and recording I/O. This package never imports Qt.

Reconstruction in three layers: the algorithms (:mod:`flexvox_core.reconstruct`,
:mod:`flexvox_core.motion`); the methods as objects, their registry and the one chunked runner
(:mod:`flexvox_core.methods`); and the one reader from a recording to reconstruction input
(:mod:`flexvox_core.capture_reader`), which :mod:`flexvox_core.batch`, the command line and the
application share.

Array conventions (shared by every part of flexvox):

=====================  =========================  =====================================
thing                  shape / type               notes
=====================  =========================  =====================================
high-speed video       ``(S, H, W)`` float32      S sub-frames, time first, in [0, 1]
coded capture          ``(F, H, W)``              S = F·K
code                   ``(m, n, K)`` bool         ``code[i, j, s]``: pixel open in slot s
firing order           ``(m, n)`` int             identity code as slot numbers 0..K-1
=====================  =========================  =====================================

Pixel ``(y, x)`` uses ``code[y % m, x % n]``.
"""

from flexvox_core._version import __version__
from flexvox_core.codes import (
    code_from_order,
    is_identity_code,
    neighbour_separation,
    order_from_code,
    sequential_order,
    validate_code,
    verify,
)
from flexvox_core.design import DesignResult, design_code
from flexvox_core.divisions import Division, enumerate_divisions, parse_division
from flexvox_core.forward import capture, sample_mask, sparse_volume, tiled_code
from flexvox_core.multiplex import MultiplexedCode, multiplexed_code, s_matrix
from flexvox_core.tiles import MAX_TILE_SIDE, parse_tile, validate_tile

__all__ = [
    "__version__",
    "MAX_TILE_SIDE",
    "DesignResult",
    "Division",
    "MultiplexedCode",
    "capture",
    "code_from_order",
    "design_code",
    "enumerate_divisions",
    "is_identity_code",
    "multiplexed_code",
    "neighbour_separation",
    "order_from_code",
    "parse_division",
    "parse_tile",
    "s_matrix",
    "sample_mask",
    "sequential_order",
    "sparse_volume",
    "tiled_code",
    "validate_code",
    "validate_tile",
    "verify",
]
