"""Motion-aware's PSNR (its defaults) on `flexvox bench`'s captures, clean and with noise: a table to compare codes.

The captures are `flexvox bench`'s (`flexvox_app.accuracy_bench.cases`: the built-in scenes at 96×128, 6 frames,
K = 8 and 16; the SCI benchmark's Runner and Drop when the data is present, `$FLEXVOX_DATA/sci_benchmark`), each
clean and with Gaussian noise of σ = 0.01 (seeded). `--json OUT` writes the figures; `--compare BEFORE.json`
prints each beside the one in BEFORE and the largest difference. To compare two commits, run it from each
(the older one's packages first on `PYTHONPATH`, as docs/benchmarks.md says) with `FLEXVOX_DATA` set for both.

    python bench/motion_psnr_table.py --json after.json --compare before.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from flexvox_app.accuracy_bench import cases
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware

SIGMAS = (0.0, 0.01)


def table() -> dict[str, float]:
    """{case and σ: motion-aware's PSNR, dB}."""
    out = {}
    for case in cases(quick=False):
        for sigma in SIGMAS:
            frames = case.frames.astype(np.float32)
            if sigma:
                frames = frames + np.random.default_rng(0).normal(0, sigma, frames.shape).astype(np.float32)
            out[f"{case.name} σ={sigma}"] = float(psnr(case.truth, motion_aware(frames, case.code).video))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, help="write the figures here")
    parser.add_argument("--compare", type=Path, help="a --json of another code: each figure beside it")
    args = parser.parse_args()
    now = table()
    if args.json:
        args.json.write_text(json.dumps(now, indent=1))
    before = json.loads(args.compare.read_text()) if args.compare else {}
    worst = 0.0
    print("| capture | PSNR dB |" + (" before | difference |" if before else ""))
    print("|---|---|" + ("---|---|" if before else ""))
    for name, value in now.items():
        row = f"| {name} | {value:.3f} |"
        if name in before:
            diff = value - before[name]
            if math.isfinite(diff):
                worst = max(worst, abs(diff))
            row += f" {before[name]:.3f} | {diff:+.4f} |"
        print(row)
    if before:
        print(f"largest difference {worst:.4f} dB")


if __name__ == "__main__":
    main()
