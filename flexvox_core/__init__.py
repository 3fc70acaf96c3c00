"""flexvox_core — the numerics of flexible-voxel videography.

Codes (the paper's integer program), the forward model, simulation, reconstruction,
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

from typing import TYPE_CHECKING

from flexvox_core._version import __version__

# The package's names, imported when first asked for (PEP 562): `import flexvox_core` (which every command line
# run does) then costs no scipy.optimize (the code design's solver, 0.26 s to import). `from flexvox_core import
# design_code` still imports it at once: a module that wants it only sometimes imports it where it is used.
_EXPORTS = {
    "flexvox_core.codes": ("code_from_order", "is_identity_code", "neighbour_separation", "order_from_code",
                           "sequential_order", "validate_code", "verify"),
    "flexvox_core.design": ("DesignResult", "design_code"),
    "flexvox_core.divisions": ("Division", "enumerate_divisions", "parse_division"),
    "flexvox_core.forward": ("capture", "sample_mask", "sparse_volume", "tiled_code"),
    "flexvox_core.multiplex": ("MultiplexedCode", "multiplexed_code", "s_matrix"),
    "flexvox_core.tiles": ("MAX_TILE_SIDE", "parse_tile", "validate_tile"),
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}
_SUBMODULES = {module.rsplit(".", 1)[1] for module in _EXPORTS}
"""The submodules `import flexvox_core` used to load: still attributes of the package (``flexvox_core.forward``)."""

if TYPE_CHECKING:  # what type checkers and editors see: the same names, imported as before
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


def __getattr__(name: str):
    import importlib

    if name in _SUBMODULES:
        return importlib.import_module(f"flexvox_core.{name}")  # which makes it an attribute of the package
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'flexvox_core' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once found, an ordinary attribute
    return value


def __dir__():
    return sorted({*globals(), *_WHERE, *_SUBMODULES})


__all__ = [  # a literal list, as linters and documentation tools read it; a test keeps it equal to _EXPORTS
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
