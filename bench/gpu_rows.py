"""PSNR on the GPU against the CPU on every motion-aware row of ``flexvox bench``, and the same bits on a rerun.

The captures are ``flexvox bench``'s (``flexvox_app.accuracy_bench.cases``: the built-in scenes at K = 8 and 16,
and the SCI clips Runner and Drop when ``$FLEXVOX_DATA/sci_benchmark`` or ``../shared/data`` holds them); each
motion-aware row runs on the CPU and twice on the GPU (``flexvox_core.methods.run``, one chunk). Printed per row:
both PSNRs, their difference, where the GPU run ran (a row the GPU does not take runs on the CPU and says so), and
whether the GPU's two runs gave the same bits; then the largest difference against the 0.1-dB target.

``--crop``, ``--frames``, ``--cases``, ``--sci`` and ``--rows`` shrink the work for a dry run under numba-cuda's
simulator (``bench/gpu_check.sh`` with ``GPU_CHECK_SMALL=1``). Figures only, never pass/fail. Usage:
``python bench/gpu_rows.py [--crop WxH] [--frames N] [--cases N] [--sci N] [--rows N]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

TARGET_DB = 0.1
"""The GPU's PSNR within this of the CPU's on every row."""


def shrink(case, crop: tuple[int, int] | None, frames: int | None):
    """``case`` cut to its first ``frames`` camera frames and its top-left ``crop`` (W, H) pixels, tile-aligned."""
    from flexvox_core.forward import capture

    K = case.code.shape[2]
    truth = case.truth
    if frames is not None:
        truth = truth[: frames * K]
    if crop is not None:
        w, h = crop
        truth = truth[:, :h, :w]
    truth = np.ascontiguousarray(truth)
    return type(case)(case.name, case.K, truth, capture(truth, case.code), case.code)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--crop", metavar="WxH", help="each capture's top-left WxH pixels only")
    ap.add_argument("--frames", type=int, help="each capture's first N camera frames only")
    ap.add_argument("--cases", type=int, help="the first N built-in captures only")
    ap.add_argument("--sci", type=int, help="the first N SCI clips only")
    ap.add_argument("--rows", type=int, help="the first N motion-aware rows of each capture only")
    args = ap.parse_args()
    from flexvox_app.accuracy_bench import cases, methods_for, sci_data_dir
    from flexvox_core.methods import run
    from flexvox_core.metrics import psnr

    crop = tuple(int(v) for v in args.crop.lower().split("x")) if args.crop else None
    every = cases(quick=False)
    built_in = [c for c in every if "(SCI)" not in c.name]
    sci = [c for c in every if "(SCI)" in c.name]
    chosen = built_in[: args.cases] if args.cases is not None else built_in
    sci = sci[: args.sci] if args.sci is not None else sci
    if not chosen and not sci:
        chosen = built_in[:1]  # no SCI clips here: one built-in capture rather than none
    folder = sci_data_dir()
    print(f"SCI clips: {folder if folder else 'not found (copy ../shared/data/sci_benchmark into $FLEXVOX_DATA)'}")
    print("\n| capture | method | CPU dB | GPU dB | GPU − CPU | GPU ran on | same bits on a rerun | CPU s | GPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    worst, rows, differ, elsewhere = 0.0, 0, 0, 0
    for case in (*chosen, *sci):
        case = shrink(case, crop, args.frames)
        rows_here = [m for family, m in methods_for(case, quick=False) if family == "motion-aware"]
        for method in rows_here[: args.rows] if args.rows is not None else rows_here:
            t0 = time.perf_counter()
            c = run(case.frames, case.code, method, chunk_frames=None, device="cpu").video
            tc = time.perf_counter() - t0
            t0 = time.perf_counter()
            g = run(case.frames, case.code, method, chunk_frames=None, device="cuda")
            tg = time.perf_counter() - t0
            again = run(case.frames, case.code, method, chunk_frames=None, device="cuda").video
            pc, pg = psnr(case.truth, c), psnr(case.truth, g.video)
            same = np.array_equal(g.video, again)
            rows += 1
            differ += not same
            if g.device == "cuda":
                worst = max(worst, abs(pg - pc))
            else:
                elsewhere += 1
            where = g.device if g.device == "cuda" else f"{g.device} ({g.device_note})"
            print(f"| {case.name} | {method.label()} | {pc:.2f} | {pg:.2f} | {pg - pc:+.3f} | {where} | "
                  f"{'yes' if same else 'NO'} | {tc:.2f} | {tg:.2f} |", flush=True)
    print(f"\n{rows} rows; largest |GPU − CPU| on the GPU's rows: {worst:.3f} dB "
          f"({'within' if worst <= TARGET_DB else 'OVER'} the {TARGET_DB} dB target); "
          f"reruns with different bits: {differ}; rows that ran on the CPU: {elsewhere}")


if __name__ == "__main__":
    main()
