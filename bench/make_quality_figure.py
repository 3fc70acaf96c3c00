"""The README's quality figure: one row per clip, ground truth beside four reconstructions.

Clips: the SCI benchmark's Runner and Drop (frames 0–7, flexvox's 2×4 identity code: one camera frame, K = 8;
skipped with a printed line when the data is absent — ``$FLEXVOX_DATA/sci_benchmark`` or
``../shared/data/sci_benchmark`` next to the checkout) and the built-in moving scenes ``balls`` and
``drummer`` (96×128, 6 camera frames through a 4×4 identity code, K = 16; no noise, as in ``flexvox bench``).
Columns: the ground truth, GAP-TV (``Method("gap-tv")``), constant-tensor ``nc`` (``Method("diffusion")``; isotropic
``tensor=(1, 1, 1), time=0.25`` on the SCI clips, its default tensor on the built-in scenes, as
docs/reconstruction.md advises per scene type), motion-aware's plain trajectory gather ("before":
``refine_time=0, local_choice=False, noise_aware=False`` and DIS with OpenCV's own 5 variational iterations: no
refinement, no local choice, no noise-aware smoothing) and motion-aware with its defaults. Each capture is reconstructed
whole (``chunk_frames=None``), timed with ``time.perf_counter`` (the best of ``--repeats`` runs, default 3) after a
warm-up of every method on a small capture (so the compiled kernels' first-call compilation is not counted), and
scored by ``flexvox_core.metrics.psnr`` (mean over the clip's sub-frames). Every panel shows the same sub-frame, the
middle one of the clip.

Draws the PNG (matplotlib, Agg; default ``docs/motion/quality.png``) and prints the table of PSNR and
seconds (clip × method) as Markdown. Figures only, never pass/fail.

Usage: ``python bench/make_quality_figure.py [-o PNG] [--overwrite] [--clips runner,drop,balls,drummer]
[--repeats N]`` (about half a minute on 2 cores).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_app.accuracy_bench import sci_data_dir
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method
from flexvox_core.metrics import psnr
from flexvox_core.output_errors import OutputError
from flexvox_core.output_files import atomic_output, check_output
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.video_api import reconstruct_video as reconstruct

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OUT = Path("docs/motion/quality.png")
"""The committed figure (relative to the repository root, where the script runs)."""
CLIPS = ("runner", "drop", "balls", "drummer")
SCI_CLIPS = ("runner", "drop")
H, W, FRAMES = 96, 128, 6  # built-in scenes: the size and length of `flexvox bench`


@dataclass
class Clip:
    """One capture: its title, ground truth, coded frames and code."""

    name: str
    title: str
    truth: np.ndarray
    frames: np.ndarray
    code: np.ndarray
    sci: bool


def columns(clip: Clip) -> list[tuple[str, Method]]:
    """(panel title, method) for the reconstructions of one clip, in column order."""
    if clip.sci:
        nc = ("nc (1,1,1), n = 0.25", Method("diffusion", tensor=(1.0, 1.0, 1.0), time=0.25))
    else:
        nc = ("nc (0.15,0.15,1), n = 1.5", Method("diffusion"))
    return [
        ("GAP-TV", Method("gap-tv")),
        nc,
        ("motion-aware, before", Method("motion-aware", refine_time=0.0, local_choice=False, noise_aware=False)),
        ("motion-aware, the default", Method("motion-aware")),
    ]


def load_clips(names) -> list[Clip]:
    """The requested clips; SCI clips without their data are skipped with a printed line."""
    out = []
    folder = sci_data_dir()
    for name in names:
        if name in SCI_CLIPS:
            if folder is None:
                print(f"SKIP {name}: no SCI benchmark data (set FLEXVOX_DATA, or put sci_benchmark/ in "
                      "../shared/data next to the checkout)")
                continue
            from flexvox_core.simulate.sources import load_video

            truth = load_video(folder / f"{name}40_cacti.mat")[:8]
            code = design_code((2, 4)).code
            title = f"{name.capitalize()} (SCI), K = 8"
            out.append(Clip(name, title, truth, capture(truth, code), code, sci=True))
        else:
            code = design_code((4, 4)).code
            truth = render_scene(name, FRAMES * 16, H, W, seed=0)
            title = f"{name} (built-in), K = 16"
            out.append(Clip(name, title, truth, capture(truth, code), code, sci=False))
    return out


def warm_up() -> None:
    """Run every method once on a small capture, so no timing below includes numba's compilation."""
    for tile in ((2, 4), (4, 4)):
        code = design_code(tile).code
        K = tile[0] * tile[1]
        truth = render_scene("balls", 2 * K, 32, 32, seed=0)
        frames = capture(truth, code)
        methods = [m for sci in (True, False) for _, m in columns(Clip("", "", truth, frames, code, sci=sci))]
        for method in methods:
            reconstruct(frames, code, method, chunk_frames=None)


@contextlib.contextmanager
def as_filed():
    """Motion-aware's flow with DIS's own variational refinement (OpenCV's 5 iterations) instead of
    ``flexvox_core.motion.gated_flow.DIS_PARAMS``."""
    import flexvox_core.motion.gated_flow as gating

    saved = gating.DIS_PARAMS
    gating.DIS_PARAMS = {}
    try:
        yield
    finally:
        gating.DIS_PARAMS = saved


def measure(clip: Clip, repeats: int) -> list[tuple[str, np.ndarray, float, float]]:
    """(title, video, PSNR dB, seconds: the best of ``repeats`` runs) per column of ``clip``."""
    rows = []
    for title, method in columns(clip):
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            with as_filed() if title == "motion-aware, before" else contextlib.nullcontext():
                video = reconstruct(clip.frames, clip.code, method, chunk_frames=None)
            times.append(time.perf_counter() - t0)
        rows.append((title, video, float(psnr(clip.truth, video)), min(times)))
    return rows


def seconds_text(sec: float) -> str:
    return f"{sec:.3f} s" if sec < 0.1 else f"{sec:.2f} s"


def cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def draw(clips: list[Clip], results: list[list], out: Path, *, overwrite: bool, repeats: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    ncol = 1 + len(results[0])
    heights = [c.truth.shape[1] / c.truth.shape[2] for c in clips]
    panel_w = 2.3
    fig, axes = plt.subplots(len(clips), ncol, squeeze=False,
                             figsize=(panel_w * ncol, sum(panel_w * h + 0.45 for h in heights) + 0.5),
                             gridspec_kw={"height_ratios": heights}, layout="constrained")
    subs = []
    for row, (clip, res) in enumerate(zip(clips, results, strict=True)):
        s = clip.truth.shape[0] // 2
        subs.append(f"{s} of {clip.truth.shape[0]}")
        size = f"{clip.truth.shape[1]}×{clip.truth.shape[2]}"
        panels = [(f"{clip.title}\ntruth, {size}, sub-frame {s}", clip.truth)]
        panels += [(f"{title}\n{p:.2f} dB · {seconds_text(sec)}", video) for title, video, p, sec in res]
        for col, (title, video) in enumerate(panels):
            ax = axes[row][col]
            ax.imshow(video[s], cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            ax.set_title(title, fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
    shown = ", ".join(f"{c.name} {t}" for c, t in zip(clips, subs, strict=True))
    fig.suptitle(f"PSNR over the whole clip; seconds per reconstruction, best of {repeats}, on {cores()} CPU cores.\n"
                 "\"before\": the trajectory gather alone (no refinement, local choice or noise-aware smoothing; "
                 "DIS's own 5 iterations).\n"
                 f"Shown: the middle sub-frame, counted from 0 ({shown})", fontsize=10)
    fig.canvas.draw()
    # Everything drawn is grey: an 8-bit grey PNG holds it exactly, at a third of RGBA's size.
    grey = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())).convert("L")
    plt.close(fig)
    with atomic_output(out, overwrite=overwrite) as tmp:
        grey.save(tmp, format="PNG", optimize=True)
    print(f"figure: {out}")


def table(clips: list[Clip], results: list[list]) -> str:
    """The Markdown table: one row per clip, PSNR (dB) and seconds per method."""
    heads = ["GAP-TV", "nc", "motion-aware before", "motion-aware, the default"]
    lines = ["| clip | " + " | ".join(heads) + " |", "|---" * (1 + len(heads)) + "|"]
    for clip, res in zip(clips, results, strict=True):
        cells = [f"{p:.2f} dB, {seconds_text(sec)}" for _, _, p, sec in res]
        name = f"{clip.name.capitalize()} (isotropic nc)" if clip.sci else f"{clip.name} (default nc)"
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT, help=f"the PNG to write (default {DEFAULT_OUT})")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing PNG")
    ap.add_argument("--repeats", type=int, default=3, help="runs per reconstruction; the best time counts (default 3)")
    ap.add_argument("--clips", default=",".join(CLIPS), help=f"comma-separated, of {', '.join(CLIPS)}")
    args = ap.parse_args(argv)
    names = [c.strip() for c in args.clips.split(",") if c.strip()]
    unknown = [c for c in names if c not in CLIPS]
    if args.repeats < 1:
        ap.error("--repeats must be at least 1")
    if unknown or not names:
        ap.error(f"unknown clip(s) {', '.join(unknown) or '(none given)'}; choose from {', '.join(CLIPS)}")
    absent = [n for n in names if n in SCI_CLIPS] if sci_data_dir() is None else []
    if absent and args.out.expanduser().resolve() == (ROOT / DEFAULT_OUT).resolve():
        print(f"error: no SCI benchmark data for {', '.join(absent)} (set FLEXVOX_DATA, or put sci_benchmark/ in "
              f"../shared/data next to the checkout); {DEFAULT_OUT} shows them, so it is not replaced with a partial "
              "figure: write another one with -o FILE.png, or leave them out with --clips", file=sys.stderr)
        return 2
    try:
        out = check_output(args.out, overwrite=args.overwrite)
    except OutputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    clips = load_clips(names)
    if not clips:
        print("nothing to draw")
        return 0
    warm_up()
    results = []
    for clip in clips:
        results.append(measure(clip, args.repeats))
        for title, _, p, sec in results[-1]:
            print(f"{clip.name:8s} {title:40s} {p:6.2f} dB  {seconds_text(sec)}", flush=True)
    try:
        draw(clips, results, out, overwrite=args.overwrite, repeats=args.repeats)
    except OutputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print()
    print(f"PSNR (mean over the clip's sub-frames) and seconds per reconstruction (best of {args.repeats}), "
          f"{cores()} cores:")
    print()
    print(table(clips, results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
