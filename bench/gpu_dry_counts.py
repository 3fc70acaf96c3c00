"""The kernel launches and bytes of each stage of a dry run of ``bench/gpu_check.sh`` (``make gpu-dry-run``).

Reads ``OUT/counts/*.json`` (written by ``bench/gpu_dry/sitecustomize.py`` in every process of the dry run) and
``OUT/stages.txt`` (each stage's exit status and wall seconds), and prints per stage: the simulator's launches,
their threads, the bytes of the arrays the launches were passed, the bytes copied host to device and back, and
what that would cost on a card at ``--bandwidth`` bytes/s and ``--launch`` s per launch at the dry run's sizes.
Usage: ``python bench/gpu_dry_counts.py [OUT] [--bandwidth 3e12] [--launch 1e-5]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

FIELDS = ("launches", "threads", "kernel_bytes", "h2d_bytes", "d2h_bytes")


def per_stage(out: Path) -> dict[str, dict[str, int]]:
    """The counts of ``out/counts/*.json`` summed per stage."""
    sums: dict[str, dict[str, int]] = {}
    for f in sorted((out / "counts").glob("*.json")):
        d = json.loads(f.read_text())
        s = sums.setdefault(d["stage"], dict.fromkeys(FIELDS, 0))
        for k in FIELDS:
            s[k] += d[k]
    return sums


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default="bench/results/gpu_dry")
    ap.add_argument("--bandwidth", type=float, default=3e12, help="the card's memory bandwidth, bytes/s")
    ap.add_argument("--launch", type=float, default=1e-5, help="seconds per kernel launch")
    args = ap.parse_args()
    out = Path(args.out)
    walls = {}
    if (out / "stages.txt").exists():
        for line in (out / "stages.txt").read_text().splitlines():
            name, rc, secs = line.split()
            walls[name] = (int(rc), int(secs))
    sums = per_stage(out)
    print(f"\nper stage of the dry run (tiny sizes, numba-cuda's simulator); card time at the dry run's sizes: "
          f"{args.launch * 1e6:.0f} µs per launch + kernel bytes at {args.bandwidth / 1e12:g} TB/s")
    print("| stage | exit | dry-run s | launches | threads | kernel MB | host→device MB | device→host MB "
          "| card ms at these sizes |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in dict.fromkeys([*walls, *sums]):
        if name not in walls:
            continue  # the script's own checks between stages
        s = sums.get(name, dict.fromkeys(FIELDS, 0))
        rc, secs = walls[name]
        card = s["launches"] * args.launch + s["kernel_bytes"] / args.bandwidth
        print(f"| {name} | {rc} | {secs} | {s['launches']} | {s['threads']} | {s['kernel_bytes'] / 1e6:.2f} | "
              f"{s['h2d_bytes'] / 1e6:.3f} | {s['d2h_bytes'] / 1e6:.3f} | {card * 1000:.1f} |")


if __name__ == "__main__":
    main()
