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

# The package's names, imported when first asked for (PEP 562): `import flexvox_core` (which every
# command line run does) then costs no scipy.optimize (the code design's solver, 0.26 s to import).
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


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'flexvox_core' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # once found, an ordinary attribute
    return value


def __dir__():
    return sorted([*globals(), *_WHERE])


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
