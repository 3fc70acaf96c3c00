"""GAP-TV as a method, one measurement at a time (:mod:`flexvox_core.reconstruct.gaptv`)."""

from __future__ import annotations

import numpy as np

from flexvox_core.methods.options import integer, number
from flexvox_core.methods.spec import MethodOutput, MethodSpec, keywords
from flexvox_core.reconstruct.gaptv import gap_tv


class GapTv(MethodSpec):
    """GAP-TV (Yuan 2016), the classical compressive-video reconstruction, our baseline."""

    name = "gap-tv"
    title = "GAP-TV, the classical compressive-video reconstruction (the peer)"
    trade = "GAP-TV has no space-time knob"
    option_specs = (
        integer("iterations", 40, label="iterations", help="GAP-TV iterations", span=(1, 500, 1)),
        number("tv_weight", 0.3, strict=True, label="TV weight", help="GAP-TV's total-variation weight",
               span=(0.01, 5.0, 0.05)),
        integer("tv_iterations", 4, label="TV iterations", help="GAP-TV's denoising iterations per step",
                span=(1, 50, 1)),
    )
    bench_axis = "iterations"

    def takes_multiplexed(self, options) -> bool:
        return True  # GAP-TV takes any 0/1 code

    def overlap(self, options, K: int) -> int:
        return 0  # each measurement is reconstructed on its own

    def run(self, frames, code, options, *, sample_range=None, extras=False, missing=None,
            device="cpu") -> MethodOutput:
        # One measurement at a time, as the SCI literature (and its reference figures) does; the options are
        # gap_tv's keywords.
        kw = keywords(options)
        return MethodOutput(np.concatenate([gap_tv(frames[f: f + 1], code, **kw) for f in range(frames.shape[0])]))

    def label(self, values: dict) -> str:
        return f"gap-tv {values['iterations']} it"


GAP_TV = GapTv()
