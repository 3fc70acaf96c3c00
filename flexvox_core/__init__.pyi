from . import codes, design, divisions, forward, multiplex, tiles
from ._version import __version__
from .codes import (
    code_from_order,
    is_identity_code,
    neighbour_separation,
    order_from_code,
    sequential_order,
    validate_code,
    verify,
)
from .design import DesignResult, design_code
from .divisions import Division, enumerate_divisions, parse_division
from .forward import capture, sample_mask, sparse_volume, tiled_code
from .multiplex import MultiplexedCode, multiplexed_code, s_matrix
from .tiles import MAX_TILE_SIDE, parse_tile, validate_tile
