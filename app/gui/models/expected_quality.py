"""Expected time and quality of a reconstruction, from the accuracy-vs-time benchmark.

``flexvox bench`` writes ``docs/bench/results.csv`` (one row per scene × method × knob).
:func:`build_table` condenses it into the small table shipped with the application,
``app/gui/expected_quality.json`` (regenerate with ``python -m app.gui.models.expected_quality``):
per K and method, the PSNR of the mean squared error over the built-in scenes (as the bench's
summary does), mean SSIM, mean seconds and the throughput in voxels per second, plus the mean
PSNR on the SCI clips (Runner, Drop) where the bench had them.

:func:`expected` finds the bench figures nearest to a :class:`~flexvox_core.reconstruct.run.Method`
(interpolating the diffusion time or iteration count on a log scale between measured values)
and scales the time to the recording's size by the measured throughput. It says which
bench rows it used, and whether it had to extrapolate.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_core.reconstruct.run import Method, default_block

_logger = logging.getLogger(__name__)

TABLE_PATH = Path(__file__).with_name("expected_quality.json")
"""The table shipped with the application."""

BENCH_CSV = Path(__file__).resolve().parents[3] / "docs" / "bench" / "results.csv"
"""Where ``flexvox bench`` figures live in a checkout."""

_LABEL = [
    ("rebin", re.compile(r"^rebin (?P<block>\d+x\d+x\d+)(?P<interp> interp)?$")),
    ("diffusion", re.compile(r"^diffusion (?P<solver>\w+) \((?P<tensor>[\d.,]+)\) n=(?P<time>[\d.]+)$")),
    ("gap-tv", re.compile(r"^gap-tv (?P<iterations>\d+) it$")),
    ("motion-aware", re.compile(
        r"^motion-aware (?P<flow>\w+) n=(?P<time>[\d.]+)(?: \+refine (?P<refine>[\d.]+))?(?: x(?P<passes>\d+))?$")),
]


def parse_label(label: str) -> dict:
    """Knobs of a bench method label (``Method.label()``), e.g. ``"gap-tv 40 it"`` → ``{"name": "gap-tv",
    "iterations": 40}``. Raises ValueError for a label it does not know."""
    for name, rx in _LABEL:
        m = rx.match(label.strip())
        if not m:
            continue
        g = m.groupdict()
        if name == "rebin":
            return {"name": name, "block": g["block"], "interpolate": g["interp"] is not None}
        if name == "diffusion":
            return {"name": name, "solver": g["solver"], "tensor": [float(c) for c in g["tensor"].split(",")],
                    "time": float(g["time"])}
        if name == "gap-tv":
            return {"name": name, "iterations": int(g["iterations"])}
        return {"name": name, "flow": g["flow"], "time": float(g["time"]),
                "refine_time": float(g["refine"] or 0), "passes": int(g["passes"] or 1)}
    raise ValueError(f"unknown bench method label {label!r}")


def build_table(csv_path=BENCH_CSV) -> dict:
    """Condense a bench ``results.csv`` into the shipped table (see the module docstring)."""
    csv_path = Path(csv_path)
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ValueError(f"{csv_path}: no rows")
    missing = {"case", "K", "method", "mse", "ssim", "seconds", "mvoxels_per_s", "psnr"} - set(rows[0])
    if missing:
        raise ValueError(f"{csv_path}: missing column(s) {', '.join(sorted(missing))}")
    groups: dict[tuple[int, str], dict[str, list]] = {}
    for r in rows:
        key = (int(r["K"]), r["method"])
        g = groups.setdefault(key, {"builtin": [], "sci": []})
        g["sci" if "SCI" in r["case"] else "builtin"].append(r)
    entries = []
    for (K, label), g in sorted(groups.items()):
        b = g["builtin"]
        if not b:
            continue
        entry = {
            "K": K, "label": label, "knobs": parse_label(label),
            "psnr": round(10 * math.log10(1 / max(float(np.mean([float(r["mse"]) for r in b])), 1e-20)), 2),
            "ssim": round(float(np.mean([float(r["ssim"]) for r in b])), 4),
            "seconds": round(float(np.mean([float(r["seconds"]) for r in b])), 5),
            "mvoxels_per_s": round(float(np.median([float(r["mvoxels_per_s"]) for r in b])), 2),
            "scenes": len(b),
        }
        if g["sci"]:
            entry["sci_psnr"] = round(float(np.mean([float(r["psnr"]) for r in g["sci"]])), 2)
        entries.append(entry)
    return {
        "source": "docs/bench/results.csv (flexvox bench: built-in scenes 96x128, 6 frames, K = 8 and 16; "
                  "SCI Runner/Drop at K = 8 when present)",
        "machine": "the 2-core development machine, with other work sharing the cores",
        "psnr": "PSNR of the mean squared error over the built-in scenes, dB (sci_psnr: mean over Runner, Drop)",
        "entries": entries,
    }


def write_table(csv_path=BENCH_CSV, out=TABLE_PATH) -> Path:
    """Write :func:`build_table` as JSON to ``out``."""
    out = Path(out)
    out.write_text(json.dumps(build_table(csv_path), indent=1) + "\n")
    return out


def load_table(path=TABLE_PATH) -> dict | None:
    """The shipped table, or None (logged) when it is missing or unreadable."""
    try:
        table = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        _logger.warning("no expected-quality table at %s: %s", path, exc)
        return None
    if not isinstance(table, dict) or not isinstance(table.get("entries"), list):
        _logger.warning("expected-quality table %s has no `entries` list", path)
        return None
    return table


@dataclass(frozen=True)
class Expectation:
    """Expected quality and time of a reconstruction.

    Attributes
    ----------
    psnr, ssim : float
        Bench figures on the built-in scenes (dB; 0-1).
    seconds : float
        Expected seconds for the recording's size, from the bench throughput.
    basis : str
        Which bench rows the figures come from, in words.
    approximate : bool
        True when no bench row matches the settings exactly (nearest or interpolated rows, another K).
    sci_psnr : float or None
        Mean PSNR on the SCI clips (Runner, Drop), when the bench had them.
    """

    psnr: float
    ssim: float
    seconds: float
    basis: str
    approximate: bool
    sci_psnr: float | None = None

    def text(self) -> str:
        """One line for the UI."""
        sci = f", SCI clips {self.sci_psnr:.1f} dB" if self.sci_psnr is not None else ""
        return (f"{'≈ ' if self.approximate else ''}{_fmt_seconds(self.seconds)}, "
                f"{self.psnr:.1f} dB PSNR / SSIM {self.ssim:.2f} on the built-in scenes{sci}")


def _fmt_seconds(s: float) -> str:
    if s < 1:
        return f"{s * 1000:.0f} ms"
    if s < 120:
        return f"{s:.1f} s"
    return f"{s / 60:.1f} min"


def _interp(entries: list[dict], key: str, value: float) -> tuple[dict, bool, str]:
    """Interpolate psnr/ssim/mvoxels_per_s in log(``key``) between the bracketing entries."""
    pts = sorted(entries, key=lambda e: e["knobs"][key])
    xs = [math.log(e["knobs"][key]) for e in pts]
    x = math.log(value)
    if len(pts) == 1 or x <= xs[0] or x >= xs[-1]:
        e = pts[0] if x <= xs[0] else pts[-1]
        exact = math.isclose(e["knobs"][key], value, rel_tol=1e-6)
        return e, not exact, e["label"] + ("" if exact else f" (nearest: {key} outside the bench's range)")
    i = int(np.searchsorted(xs, x))
    lo, hi = pts[i - 1], pts[i]
    if math.isclose(xs[i], x, rel_tol=1e-9, abs_tol=1e-12):
        return hi, False, hi["label"]
    t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
    mix = {k: (1 - t) * lo[k] + t * hi[k] for k in ("psnr", "ssim", "mvoxels_per_s")}
    if "sci_psnr" in lo and "sci_psnr" in hi:
        mix["sci_psnr"] = (1 - t) * lo["sci_psnr"] + t * hi["sci_psnr"]
    return mix, True, f"interpolated between {lo['label']} and {hi['label']}"


def _log_distance(a, b) -> float:
    return float(np.linalg.norm(np.log(np.asarray(a, float)) - np.log(np.asarray(b, float))))


def expected(table: dict | None, method: Method, code, *, voxels: int) -> Expectation | None:
    """Expected figures for reconstructing ``voxels`` voxels with ``method`` and ``code``
    (m, n, K), or None when the table has nothing for the method."""
    if not table:
        return None
    K = int(np.asarray(code).shape[2])
    by_name = [e for e in table["entries"] if e["knobs"]["name"] == method.name]
    if not by_name:
        return None
    ks = sorted({e["K"] for e in by_name}, key=lambda k: (abs(math.log(k / K)), k))
    bench_k = ks[0]
    cands = [e for e in by_name if e["K"] == bench_k]
    approx = bench_k != K
    if method.name == "rebin":
        block = method.block or default_block(np.asarray(code, dtype=bool))
        same = [e for e in cands if e["knobs"]["interpolate"] == method.interpolate] or cands
        # Match the block's slot count c (TR = K / c), so a K=12 recording borrows the nearest K=16 division.
        def tr_gap(e):
            c = int(e["knobs"]["block"].split("x")[2])
            return abs(math.log(block.c / c))
        best = min(same, key=lambda e: (tr_gap(e), e["knobs"]["block"] != block.label))
        fig, more, basis = best, best["knobs"]["block"] != block.label, best["label"]
        approx = approx or more or best["knobs"]["interpolate"] != method.interpolate
    elif method.name == "diffusion":
        same = [e for e in cands if e["knobs"]["solver"] == method.solver] or cands
        tensors = {tuple(e["knobs"]["tensor"]) for e in same}
        tensor = min(tensors, key=lambda t: _log_distance(t, method.tensor))
        fam = [e for e in same if tuple(e["knobs"]["tensor"]) == tensor]
        fig, more, basis = _interp(fam, "time", method.time)
        approx = approx or more or _log_distance(tensor, method.tensor) > 1e-6 or fam[0]["knobs"]["solver"] != \
            method.solver
    elif method.name == "gap-tv":
        fig, more, basis = _interp(cands, "iterations", method.iterations)
        approx = approx or more
    else:
        same = [e for e in cands if e["knobs"]["passes"] == method.passes
                and (e["knobs"]["refine_time"] > 0) == (method.refine_time > 0)] or cands
        fig, more, basis = _interp(same, "time", method.time)
        approx = approx or more or same[0]["knobs"]["flow"] != method.flow
    seconds = voxels / max(fig["mvoxels_per_s"] * 1e6, 1e-9)
    basis = f"bench K={bench_k}: {basis}"
    return Expectation(psnr=float(fig["psnr"]), ssim=float(fig["ssim"]), seconds=float(seconds), basis=basis,
                       approximate=bool(approx), sci_psnr=fig.get("sci_psnr"))


if __name__ == "__main__":  # pragma: no cover - regenerates the shipped table
    logging.basicConfig(level=logging.INFO)
    _logger.info("wrote %s", write_table())
