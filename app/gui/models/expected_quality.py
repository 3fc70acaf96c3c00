"""Expected time and quality of a reconstruction, from the accuracy-vs-time benchmark.

``flexvox bench`` writes ``docs/bench/results.csv`` (one row per scene × method × knob, each carrying its
method's options: :meth:`Method.as_dict() <flexvox_core.methods.Method.as_dict>`).
:func:`build_table` condenses it into the small table shipped with the application,
``app/gui/expected_quality.json`` (regenerate with ``python -m flexvox_app.gui.models.expected_quality``):
per K and method (its options), the PSNR of the mean squared error over the built-in scenes (as the
bench's summary does), mean SSIM, mean seconds and the throughput in voxels per second, plus the mean
PSNR on the SCI clips (Runner, Drop) where the bench had them. A results.csv without an ``options``
column is read by its labels, against the methods the bench runs (:func:`flexvox_app.accuracy_bench.known_options`).

:func:`expected` finds the bench figures nearest to a :class:`~flexvox_core.methods.Method`
(interpolating along the method's bench axis, e.g. the diffusion time or iteration count, on a
log scale between measured values) and scales the time to the recording's size by the measured
throughput. It says which bench rows it used, and whether it had to extrapolate. The method
objects rank bench rows by the options they carry (``bench_rank``); this module knows no method by
name.
"""

from __future__ import annotations

import csv
import json
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_core.methods import Method
from flexvox_core.output_files import write_text_atomic

_logger = logging.getLogger(__name__)

TABLE_PATH = Path(__file__).with_name("expected_quality.json")
"""The table shipped with the application."""

BENCH_CSV = Path(__file__).resolve().parents[3] / "docs" / "bench" / "results.csv"
"""Where ``flexvox bench`` figures live in a checkout."""

def _row_options(rows: list[dict], csv_path: Path) -> list[dict]:
    """Each row's options: its ``options`` column, or (a results.csv without one) the options of the method
    the bench runs under its label."""
    if "options" in rows[0]:
        return [json.loads(r["options"]) for r in rows]
    from flexvox_app.accuracy_bench import known_options

    known = {K: known_options(K) for K in {int(r["K"]) for r in rows}}
    out = []
    for r in rows:
        options = known[int(r["K"])].get(r["method"])
        if options is None:
            raise ValueError(f"{csv_path}: row {r['method']!r} at K={r['K']} has no `options` column and flexvox "
                             "bench runs no method of that label; run flexvox bench again for its rows")
        out.append(options)
    return out


def build_table(csv_path=BENCH_CSV) -> dict:
    """Condense a bench ``results.csv`` into the shipped table (see the module docstring)."""
    from flexvox_app.accuracy_bench import options_key

    csv_path = Path(csv_path)
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise ValueError(f"{csv_path}: no rows")
    missing = {"case", "K", "method", "mse", "ssim", "seconds", "mvoxels_per_s", "psnr"} - set(rows[0])
    if missing:
        raise ValueError(f"{csv_path}: missing column(s) {', '.join(sorted(missing))}")
    groups: dict[tuple[int, str, str], dict] = {}
    for r, options in zip(rows, _row_options(rows, csv_path), strict=True):
        key = (int(r["K"]), r["method"], options_key(options))
        g = groups.setdefault(key, {"options": options, "builtin": [], "sci": []})
        g["sci" if "SCI" in r["case"] else "builtin"].append(r)
    entries = []
    for (K, label, _), g in sorted(groups.items()):
        b = g["builtin"]
        if not b:
            continue
        entry = {
            "K": K, "label": label, "options": g["options"],
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
    write_text_atomic(out, json.dumps(build_table(csv_path), indent=1) + "\n")
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
    nearest : str
        The bench setting the quality is quoted from when the bench never measured these settings (say another
        diffusion tensor); "" when it did.
    """

    psnr: float
    ssim: float
    seconds: float
    basis: str
    approximate: bool
    sci_psnr: float | None = None
    nearest: str = ""

    def text(self) -> str:
        """One line for the UI."""
        return (f"{'≈ ' if self.approximate else ''}{format_seconds(self.seconds)}, {self.quality_text()}")

    def quality_text(self) -> str:
        """The quality part of :meth:`text` (settings the bench never measured: the nearest it did, named)."""
        sci = f", SCI clips {self.sci_psnr:.1f} dB" if self.sci_psnr is not None else ""
        figures = f"{self.psnr:.1f} dB PSNR / SSIM {self.ssim:.2f} on the built-in scenes{sci}"
        if self.nearest:
            return f"quality not benched at these settings (the nearest benched, {self.nearest}: {figures})"
        return figures


def format_seconds(s: float) -> str:
    """Seconds in words: "107 ms", "4.2 s", "3.1 min"."""
    if s < 1:
        return f"{s * 1000:.0f} ms"
    if s < 120:
        return f"{s:.1f} s"
    return f"{s / 60:.1f} min"


def _interp(entries: list[dict], key: str, value: float) -> tuple[dict, bool, str]:
    """Interpolate psnr/ssim/mvoxels_per_s in log(``key``) between the bracketing entries."""
    pts = sorted(entries, key=lambda e: e["options"][key])
    xs = [math.log(e["options"][key]) for e in pts]
    x = math.log(value)
    if len(pts) == 1 or x <= xs[0] or x >= xs[-1]:
        e = pts[0] if x <= xs[0] else pts[-1]
        exact = math.isclose(e["options"][key], value, rel_tol=1e-6)
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


def expected(table: dict | None, method: Method, code, *, voxels: int) -> Expectation | None:
    """Expected figures for reconstructing ``voxels`` voxels with ``method`` and ``code``
    (m, n, K), or None when the table has nothing for the method."""
    if not table:
        return None
    K = int(np.asarray(code).shape[2])
    by_name = [e for e in table["entries"] if e["options"]["name"] == method.name]
    if not by_name:
        return None
    ks = sorted({e["K"] for e in by_name}, key=lambda k: (abs(math.log(k / K)), k))
    bench_k = ks[0]
    cands = [e for e in by_name if e["K"] == bench_k]
    approx = bench_k != K
    spec, values = method.spec, dict(method.values)
    defaults = Method(method.name).as_dict()  # an option a row does not name: it ran at the default
    ranked = [(spec.bench_rank({**defaults, **e["options"]}, values, code), e) for e in cands]
    best = min(rank for (rank, _), _ in ranked)
    fam = [e for (rank, _), e in ranked if rank == best]
    exact = next(ok for (rank, ok), _ in ranked if rank == best)
    if spec.bench_axis is None:
        fig, more, basis = fam[0], False, fam[0]["label"]
    else:
        fig, more, basis = _interp(fam, spec.bench_axis, values[spec.bench_axis])
    approx = approx or more or not exact
    seconds = voxels / max(fig["mvoxels_per_s"] * 1e6, 1e-9)
    nearest = "" if exact else basis
    basis = f"bench K={bench_k}: {basis}"
    return Expectation(psnr=float(fig["psnr"]), ssim=float(fig["ssim"]), seconds=float(seconds), basis=basis,
                       approximate=bool(approx), sci_psnr=fig.get("sci_psnr"), nearest=nearest)


if __name__ == "__main__":  # pragma: no cover - regenerates the shipped table
    logging.basicConfig(level=logging.INFO)
    _logger.info("wrote %s", write_table())
