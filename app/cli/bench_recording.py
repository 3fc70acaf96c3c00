"""``flexvox bench REC``: what accuracy costs in time on the user's own recording, from the estimate.

Every method and knob setting of :func:`methods_for` reconstructs the recording; each result is timed (after one
run of each and its estimate on a small capture, :func:`~flexvox_core.warm_up.warm_up`, and one read of the
recording: no row pays a one-time compile or load) and
scored by the estimate without ground truth (:func:`flexvox_core.accuracy.estimate_recording`), with the
true PSNR beside it when the recording holds a ground truth (read only after the estimate): ``truth`` is the
PSNR of the clip's mean squared error, the one the estimate estimates (:func:`flexvox_core.metrics.clip_psnr`),
``truth_frames_mean`` the mean of the sub-frames' PSNRs that ``flexvox bench``'s scenes report. A method the
estimate refuses keeps its row, with the reason and no estimate. Writes ``results.csv``, ``results.json``
and ``pareto.png`` (estimated PSNR against time, the interval as error bars, the truth as open marks).
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from pathlib import Path

TIMES_FULL = (0.25, 0.5, 1.0, 1.5, 2.0, 4.0)
TIMES_QUICK = (0.5, 1.5, 4.0)
OUTPUTS = ("results.csv", "results.json", "pareto.png")


def methods_for(code, *, quick: bool) -> list:
    """The methods and knob settings ``flexvox bench REC`` runs on a recording of identity code ``code``."""
    from flexvox_core.methods import Method
    from flexvox_core.reconstruct.rebin import supported_divisions

    rows = [Method("rebin", block=d, interpolate=True) for d in supported_divisions(code)]
    rows += [Method("diffusion", time=n) for n in (TIMES_QUICK if quick else TIMES_FULL)]
    rows += [Method("gap-tv", iterations=it) for it in ((20,) if quick else (10, 40))]
    rows.append(Method("motion-aware"))
    return rows


def run_recording_bench(path, out_dir, *, quick: bool = False, device: str = "cpu", progress=None,
                        chunk_frames: int | None = 16) -> list[dict]:
    """Run :func:`methods_for` on the recording at ``path``, write the results into ``out_dir`` and return the
    rows (``estimate``, ``low``, ``high``: dB or None with ``why``; ``truth``: dB or None)."""
    from flexvox_core.accuracy import NotEstimable, estimate_recording
    from flexvox_core.capture_reader import open_capture
    from flexvox_core.metrics import clip_psnr, psnr
    from flexvox_core.warm_up import warm_up

    reader = open_capture(path)
    rec = reader.recording
    methods = methods_for(reader.code, quick=quick)
    warm_up(reader.code, methods, device=device, estimates=True)  # no row pays a one-time compile or load
    reader.run(methods[0], chunk_frames=chunk_frames, device=device)  # nor the recording's first read
    rows = []
    for i, method in enumerate(methods):
        t0 = time.perf_counter()
        out = reader.run(method, chunk_frames=chunk_frames, device=device)
        seconds = time.perf_counter() - t0
        row = {"method": method.label, "family": method.name, "seconds": round(seconds, 5),
               "estimate": None, "low": None, "high": None, "estimate_seconds": None, "why": None,
               "truth": None, "device": out.device, "options": method.as_dict()}
        t0 = time.perf_counter()
        try:
            est = estimate_recording(rec, method, reconstruction=out.video if reader.multiplexed is None else None,
                                     chunk_frames=chunk_frames, device=device)
            row.update(estimate=round(est.psnr, 3), low=round(est.low, 3), high=round(est.high, 3),
                       samples=est.samples, estimate_seconds=round(time.perf_counter() - t0, 5))
        except NotEstimable as exc:
            row["why"] = str(exc)
        if rec.has_ground_truth:  # only now, after the estimate
            truth = rec.ground_truth[:]
            row["truth"] = round(float(clip_psnr(truth, out.video)), 3)  # what the estimate estimates
            row["truth_frames_mean"] = round(float(psnr(truth, out.video)), 3)
        rows.append(row)
        if progress:
            progress(i + 1, len(methods))
    write_results(Path(out_dir), rows, str(path))
    return rows


def write_results(out_dir: Path, rows: list[dict], source: str) -> None:
    """``results.csv``, ``results.json`` and ``pareto.png`` of :func:`run_recording_bench`'s rows."""
    from flexvox_core.output_files import write_text_atomic

    fields = ["method", "family", "seconds", "estimate", "low", "high", "estimate_seconds", "truth",
              "truth_frames_mean", "device", "why", "options"]
    table = io.StringIO(newline="")
    writer = csv.DictWriter(table, fieldnames=fields, extrasaction="ignore")
    writer.writeheader()
    writer.writerows({**r, "options": json.dumps(r["options"])} for r in rows)
    write_text_atomic(out_dir / "results.csv", table.getvalue())
    scored = [r for r in rows if r["estimate"] is not None]
    write_text_atomic(out_dir / "results.json", json.dumps(
        {"recording": source, "rows": rows, "pareto": pareto(scored)}, indent=1))
    plot(rows, out_dir / "pareto.png")


def pareto(rows: list[dict]) -> list[dict]:
    """The rows not beaten by a faster-or-equal row with a higher-or-equal estimate."""
    front, best = [], -math.inf
    for r in sorted(rows, key=lambda r: (r["seconds"], -r["estimate"])):
        if r["estimate"] > best:
            front.append(r)
            best = r["estimate"]
    return front


def plot(rows: list[dict], path: Path) -> None:
    """Estimated PSNR (interval as error bars) against seconds, one colour per method; the truth as open
    marks when known; the Pareto front of the estimates joined."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5), dpi=110)
    cmap = plt.get_cmap("tab10")
    for i, fam in enumerate(sorted({r["family"] for r in rows})):
        pts = [r for r in rows if r["family"] == fam and r["estimate"] is not None]
        if pts:
            ax.errorbar([r["seconds"] for r in pts], [r["estimate"] for r in pts],
                        yerr=[[r["estimate"] - r["low"] for r in pts], [r["high"] - r["estimate"] for r in pts]],
                        fmt="o", ms=4, capsize=2, color=cmap(i % 10), label=f"{fam} (estimate)")
        truth = [r for r in rows if r["family"] == fam and r["truth"] is not None]
        if truth:
            ax.scatter([r["seconds"] for r in truth], [r["truth"] for r in truth], s=30, facecolors="none",
                       edgecolors=cmap(i % 10), label=f"{fam} (truth)")
    front = pareto([r for r in rows if r["estimate"] is not None])
    if front:
        ax.plot([r["seconds"] for r in front], [r["estimate"] for r in front], "k--", lw=1, label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel("seconds per reconstruction")
    ax.set_ylabel("estimated PSNR, dB (no ground truth)")
    ax.set_title("What accuracy costs in time on this recording")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def print_table(rows: list[dict]) -> None:
    """The Markdown table of the rows."""
    print("| method | estimated PSNR (dB) | interval (dB) | true PSNR (dB) | seconds | estimate s |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        truth = f"{r['truth']:.2f}" if r["truth"] is not None else "-"
        if r["estimate"] is None:
            print(f"| {r['method']} | none | - | {truth} | {r['seconds']:.3f} | - |")
        else:
            print(f"| {r['method']} | {r['estimate']:.2f} | {r['low']:.2f}-{r['high']:.2f} | {truth} | "
                  f"{r['seconds']:.3f} | {r['estimate_seconds']:.3f} |")
    reasons = {r["family"]: r["why"] for r in rows if r["why"]}  # one line per method, its settings alike
    for why in reasons.values():
        print(f"no estimate: {why}")
