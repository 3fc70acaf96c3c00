"""What accuracy costs in time: every reconstruction and knob on the same captures.

Runs re-binning (every supported division), constant-tensor diffusion (a diffusion-time
sweep for several tensors, and each solver), GAP-TV (an iteration sweep) and the
motion-aware reconstruction (diffusion time, refinement, a second pass) on the
built-in scenes at K = 8 (2×4) and K = 16 (4×4), and on the SCI benchmark's Runner and
Drop (2×4 code) when that data is present. Writes ``results.csv``, ``results.json`` and a
Pareto plot ``pareto.png`` (mean PSNR against log time), and returns the rows. Each method runs once on a small
capture of each code before any is timed (:func:`~flexvox_core.warm_up.warm_up`): no row pays numba's
one-time compile or cache load.

Each row carries its method's options (``options``: :meth:`Method.as_dict()
<flexvox_core.methods.Method.as_dict>`, the name and every option's value; JSON text in the CSV), which is
what rows are grouped and matched by; ``method`` is its label, for reading.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method
from flexvox_core.metrics import psnr, ssim
from flexvox_core.motion.pipeline import DEFAULT_TIME as MA_TIME
from flexvox_core.output_files import write_text_atomic
from flexvox_core.reconstruct.rebin import supported_divisions
from flexvox_core.simulate.scenes import render_scene

_logger = logging.getLogger(__name__)

TILES = ((2, 4), (4, 4))
"""The codes' tiles: K = 8 and K = 16."""
SCENES_FULL = ("fan", "balls", "drummer", "pan", "static")
SCENES_QUICK = ("balls", "static")
TENSORS = {
    "default (0.15,0.15,1)": (0.15, 0.15, 1.0),
    "isotropic (1,1,1)": (1.0, 1.0, 1.0),
    "high SR (0.05,0.05,1)": (0.05, 0.05, 1.0),
    "high TR (1,1,0.05)": (1.0, 1.0, 0.05),
    "between (0.3,0.3,1)": (0.3, 0.3, 1.0),
}
TIMES_FULL = (0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 4.0, 8.0)
TIMES_QUICK = (0.25, 1.0, 4.0)


@dataclass
class Case:
    """One capture to reconstruct: its ground truth, frames and code."""

    name: str
    K: int
    truth: np.ndarray
    frames: np.ndarray
    code: np.ndarray


def sci_data_dir() -> Path | None:
    """``$FLEXVOX_DATA/sci_benchmark`` or ``../shared/data/sci_benchmark`` next to the checkout."""
    env = os.environ.get("FLEXVOX_DATA")
    candidates = [Path(env) / "sci_benchmark"] if env else []
    candidates.append(Path(__file__).resolve().parents[2] / "shared" / "data" / "sci_benchmark")
    return next((c for c in candidates if (c / "runner40_cacti.mat").exists()), None)


def cases(*, quick: bool, sci: bool = True) -> list[Case]:
    """The captures of the benchmark (seeded, deterministic)."""
    H, W, F = (48, 64, 4) if quick else (96, 128, 6)
    out = []
    for tile in TILES:
        code = design_code(tile).code
        K = tile[0] * tile[1]
        for scene in SCENES_QUICK if quick else SCENES_FULL:
            truth = render_scene(scene, F * K, H, W, seed=0)
            out.append(Case(f"{scene} K={K}", K, truth, capture(truth, code), code))
    folder = sci_data_dir() if sci else None
    if folder is not None:
        from flexvox_core.simulate.sources import load_video

        code = design_code((2, 4)).code
        for name in ("runner", "drop") if not quick else ("runner",):
            truth = load_video(folder / f"{name}40_cacti.mat")[:8]
            out.append(Case(f"{name} (SCI) K=8", 8, truth, capture(truth, code), code))
    return out


def methods_for(case: Case, *, quick: bool) -> list[tuple[str, Method]]:
    """(family, method) rows for one capture."""
    rows = []
    for d in supported_divisions(case.code):
        rows.append(("rebin", Method("rebin", block=d, interpolate=True)))
        if not quick:
            rows.append(("rebin (blocks)", Method("rebin", block=d, interpolate=False)))
    for family, tensor in TENSORS.items():
        for n in TIMES_QUICK if quick else TIMES_FULL:
            rows.append((f"nc {family}", Method("diffusion", tensor=tensor, time=n)))
    if not quick:
        for n in (0.25, 1.0):
            rows.append(("explicit isotropic", Method("diffusion", tensor=(1, 1, 1), time=n, solver="explicit")))
        rows.append(("steady isotropic", Method("diffusion", tensor=(1, 1, 1), time=1.0, solver="steady")))
    for it in (5, 20) if quick else (5, 10, 20, 40):
        rows.append(("gap-tv", Method("gap-tv", iterations=it)))
    for n in (MA_TIME,) if quick else (2.0, 4.0, MA_TIME):
        rows.append(("motion-aware", Method("motion-aware", time=n)))
    if not quick:
        rows.append(("motion-aware", Method("motion-aware", time=MA_TIME, refine_time=0.0)))  # no refinement
        rows.append(("motion-aware", Method("motion-aware", time=MA_TIME, passes=2)))
        rows.append(("motion-aware", Method("motion-aware", time=MA_TIME, local_choice=False)))  # gather alone
    return rows


def known_options(K: int) -> dict[str, dict]:
    """The options (``as_dict``) of every method the full bench runs at K (a tile of :data:`TILES`), by label:
    how a results.csv without an ``options`` column is read."""
    tile = next((t for t in TILES if t[0] * t[1] == K), None)
    if tile is None:
        return {}
    case = Case(f"K={K}", K, np.empty(0), np.empty(0), design_code(tile).code)
    return {method.label(): method.as_dict() for _, method in methods_for(case, quick=False)}


def run_bench(out_dir, *, quick: bool = False, sci: bool = True, progress=None, device: str = "cpu") -> list[dict]:
    """Run the benchmark, write CSV/JSON/PNG into ``out_dir`` and return the rows (``device``: where each
    reconstruction runs, :func:`~flexvox_core.methods.runner.device_for`; each row says where it ran)."""
    from flexvox_core.methods import run
    from flexvox_core.warm_up import warm_up
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    all_cases = cases(quick=quick, sci=sci)
    warmed: set[tuple] = set()
    for i, case in enumerate(all_cases):
        methods = methods_for(case, quick=quick)
        key = (case.code.shape, case.frames.dtype.str)
        if key not in warmed:  # no row pays a one-time compile or load
            warm_up(case.code, [method for _, method in methods], device=device, dtype=case.frames.dtype)
            warmed.add(key)
        for family, method in methods:
            t0 = time.perf_counter()
            out = run(case.frames, case.code, method, chunk_frames=None, device=device)
            seconds = time.perf_counter() - t0
            video = out.video
            mse = float(np.mean((case.truth.astype(np.float64) - video) ** 2))
            rows.append({
                "case": case.name, "K": case.K, "family": family, "method": method.label(),
                "psnr": round(float(psnr(case.truth, video)), 3), "mse": mse,
                "ssim": round(float(ssim(case.truth, video)), 4),
                "seconds": round(seconds, 5), "mvoxels_per_s": round(video.size / max(seconds, 1e-9) / 1e6, 2),
                "device": out.device, "options": method.as_dict(),
            })
        if progress:
            progress(i + 1, len(all_cases))
    _write(out_dir, rows)
    return rows


def options_key(options: dict) -> str:
    """A row's options as one comparable text (JSON, keys sorted)."""
    return json.dumps(options, sort_keys=True)


def summary(rows: list[dict]) -> list[dict]:
    """Per method (its options) over the built-in scenes: PSNR of the mean squared error (so an exact
    reconstruction of a still scene counts as error 0, not as an infinite PSNR), mean SSIM
    and mean seconds."""
    by: dict[tuple, list[dict]] = {}
    for r in rows:
        if "SCI" in r["case"]:
            continue
        by.setdefault((r["family"], options_key(r["options"])), []).append(r)
    out = []
    for (family, _), rs in by.items():
        out.append({"family": family, "method": rs[0]["method"], "options": rs[0]["options"],
                    "psnr": float(10 * np.log10(1 / max(np.mean([r["mse"] for r in rs]), 1e-20))),
                    "ssim": float(np.mean([r["ssim"] for r in rs])),
                    "seconds": float(np.mean([r["seconds"] for r in rs])),
                    "cases": len(rs)})
    return sorted(out, key=lambda r: -r["psnr"])


def pareto(points: list[dict]) -> list[dict]:
    """The rows not beaten by a faster-or-equal row with higher-or-equal PSNR."""
    front, best = [], -math.inf
    for r in sorted(points, key=lambda r: (r["seconds"], -r["psnr"])):
        if r["psnr"] > best:
            front.append(r)
            best = r["psnr"]
    return front


def _write(out_dir: Path, rows: list[dict]) -> None:
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows({**r, "options": json.dumps(r["options"])} for r in rows)
    write_text_atomic(out_dir / "results.csv", table.getvalue())
    summ = summary(rows)
    write_text_atomic(out_dir / "results.json", json.dumps({"rows": rows, "summary": summ, "pareto": pareto(summ)},
                                                           indent=1))
    plot_pareto(summ, out_dir / "pareto.png")


def plot_pareto(summ: list[dict], path: Path) -> None:
    """Mean PSNR against time (log), one colour per family, the Pareto front joined."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    families = sorted({r["family"] for r in summ})
    cmap = plt.get_cmap("tab10")
    for i, fam in enumerate(families):
        pts = [r for r in summ if r["family"] == fam]
        ax.scatter([r["seconds"] for r in pts], [r["psnr"] for r in pts], s=22, color=cmap(i % 10), label=fam)
    front = pareto(summ)
    ax.plot([r["seconds"] for r in front], [r["psnr"] for r in front], "k--", lw=1, label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel("seconds per capture (mean over scenes)")
    ax.set_ylabel("PSNR of the mean squared error over built-in scenes, dB")
    ax.set_title("What accuracy costs in time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
