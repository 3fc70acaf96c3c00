"""Re-binning as a method: one division for the whole video (:mod:`flexvox_core.reconstruct.rebin`).

The paper's §2: each block of a division holds one sample, which fills the block.
"""

from __future__ import annotations

import math

import numpy as np

from flexvox_core.divisions import Division
from flexvox_core.methods.option_kinds import DIVISION
from flexvox_core.methods.options import Option, flag
from flexvox_core.methods.spec import MethodOutput, MethodSpec
from flexvox_core.reconstruct.rebin import default_block, rebin


class Rebin(MethodSpec):
    """Re-binning at one division, with or without interpolation between block centres."""

    name = "rebin"
    title = "re-binning at one division (TR x SR fixed for the whole video)"
    trade = "one division a x b x c for the whole video: TR = K / c, SR = 1 / (a b)"
    option_specs = (
        Option("block", None,
               "a Division, written 2x2x4 or 2,2,4 or given as (2, 2, 4), or None (the default division)",
               lambda v: isinstance(v, Division), kind=DIVISION, label="division",
               help="rows,columns,slots of the division (default: the one with TR closest to sqrt(K))"),
        flag("interpolate", True, label="interpolation between block centres",
             help="trilinear interpolation between block centres (off: each block's one sample fills it)"),
    )

    def overlap(self, options, K: int) -> int:
        return 1 if options.interpolate else 0

    def run(self, frames, code, options, *, sample_range=None, extras=False, missing=None,
            device="cpu") -> MethodOutput:
        block = options.block or default_block(code)
        return MethodOutput(rebin(frames, code, block, interpolate=options.interpolate))

    def label(self, values: dict) -> str:
        b = "default" if values["block"] is None else values["block"].label
        return f"rebin {b}{' interp' if values['interpolate'] else ''}"

    def as_dict(self, values: dict) -> dict:
        return {"name": self.name, **values, "block": None if values["block"] is None else values["block"].label}

    def bench_rank(self, row: dict, values: dict, code) -> tuple[tuple, bool]:
        # The block's slot count c (TR = K / c) first, so a K=12 recording borrows the nearest K=16 division.
        block = values["block"] or default_block(np.asarray(code, dtype=bool))
        c = int(row["block"].split("x")[2])
        other_interp = row["interpolate"] != values["interpolate"]
        other_block = row["block"] != block.label
        return (other_interp, abs(math.log(block.c / c)), other_block), not (other_interp or other_block)


REBIN = Rebin()
