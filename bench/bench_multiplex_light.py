"""Multiplexed against identity codes across light levels: where does multiplexing pay for its light?

The built-in ``balls`` scene (96×128, 6 camera frames) is captured through a tile's identity code and,
where an S-matrix exists (K ≡ 3 mod 4: the 3×5 tile; none for 4×4, K = 16), its multiplexed code, with
photon noise and read noise (``flexvox_core.simulate``: effects ``photon_noise``, ``read_noise``), at
electrons per unit intensity from 5 to 5000 (log steps) and read noise 1, 3 and 10 e⁻. Each capture is
reconstructed by the runner with each method's defaults — ``diffusion`` (nc), ``motion-aware`` and
``gap-tv`` — which reconstruct a multiplexed capture from its own forward model
(``flexvox_core.reconstruct.multiplexed``); the per-tile demultiplexing (the old path, ``demux nc``) is
printed beside them for 3×5. Printed: one row per (tile, read noise, light) with the PSNR (dB, mean over
sub-frames) of each code and method, and the best identity against the best multiplexed figure. The
plot (matplotlib, Agg) goes to ``--out`` (default ``bench/results/multiplex_light.png``).

Figures only, never pass/fail. Usage: ``python bench/bench_multiplex_light.py [--quick] [--out PNG]
[--methods M,...] [--seed S]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.methods import Method, run
from flexvox_core.metrics import psnr
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct import as_identity_capture
from flexvox_core.simulate.effects import EFFECTS
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video

FRAMES, H, W = 6, 96, 128
LIGHTS = (5, 15, 50, 150, 500, 1500, 5000)
READ_NOISE = (1, 3, 10)
TILES = ((3, 5), (4, 4))


def _psnr(truth, video) -> float:
    return float(psnr(truth, np.clip(video, 0, 1)))


def _capture(truth, code, light, read_sigma, seed):
    effects = [EFFECTS["photon_noise"](), EFFECTS["read_noise"](sigma=read_sigma)]
    return simulate_video(truth, code, effects=effects, seed=seed, electrons_per_unit=light).frames


def _row(truth, tile, light, read_sigma, methods, seed) -> dict:
    ident = design_code(tile).code
    scores = {}
    frames = _capture(truth, ident, light, read_sigma, seed)
    for name in methods:
        scores[f"identity {name}"] = _psnr(truth, run(frames, ident, Method(name), chunk_frames=None).video)
    K = tile[0] * tile[1]
    if K % 4 == 3:
        mc = multiplexed_code(tile)
        frames = _capture(truth, mc.code, light, read_sigma, seed)
        for name in methods:
            scores[f"multiplexed {name}"] = _psnr(truth, run(frames, mc.code, Method(name), chunk_frames=None).video)
        identity = as_identity_capture(frames, mc)
        scores["demux nc"] = _psnr(truth, run(*identity, Method("diffusion"), chunk_frames=None).video)
    return scores


def _plot(rows, methods, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tiles = sorted({r["tile"] for r in rows})
    fig, axes = plt.subplots(len(tiles), len(READ_NOISE), figsize=(4.2 * len(READ_NOISE), 3.4 * len(tiles)),
                             squeeze=False, sharey=True)
    for i, tile in enumerate(tiles):
        for j, sigma in enumerate(READ_NOISE):
            ax = axes[i][j]
            sel = [r for r in rows if r["tile"] == tile and r["read"] == sigma]
            x = [r["light"] for r in sel]
            for k, name in enumerate(methods):
                for kind, style in (("identity", "--"), ("multiplexed", "-")):
                    key = f"{kind} {name}"
                    if key in sel[0]["scores"]:
                        ax.plot(x, [r["scores"][key] for r in sel], style, color=f"C{k}", marker="o", ms=3,
                                label=key)
            if "demux nc" in sel[0]["scores"]:
                ax.plot(x, [r["scores"]["demux nc"] for r in sel], ":", color="grey", label="demux nc (old)")
            ax.set_xscale("log")
            ax.set_title(f"{tile}, read noise {sigma} e⁻", fontsize=9)
            ax.set_xlabel("electrons per unit")
            if j == 0:
                ax.set_ylabel("PSNR (dB)")
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"plot: {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", default="diffusion,motion-aware,gap-tv")
    ap.add_argument("--quick", action="store_true", help="light 5, 50, 500, 5000 and read noise 3 only")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("bench/results/multiplex_light.png"))
    args = ap.parse_args()
    methods = args.methods.split(",")
    lights = LIGHTS[::2] if args.quick else LIGHTS
    reads = (3,) if args.quick else READ_NOISE
    print(f"balls {H}x{W}, {FRAMES} frames, photon + read noise, seed {args.seed}; PSNR dB "
          "(identity / multiplexed per method; 'best' = best identity vs best multiplexed)")
    print("| tile | read e⁻ | e⁻ per unit | " + " | ".join(f"{m} id / mx" for m in methods)
          + " | demux nc | best id / mx | mx − id |")
    print("|---" * (6 + len(methods)) + "|")
    rows = []
    for tile in TILES:
        truth = render_scene("balls", FRAMES * tile[0] * tile[1], H, W)
        for sigma in reads:
            for light in lights:
                s = _row(truth, tile, light, sigma, methods, args.seed)
                rows.append({"tile": f"{tile[0]}x{tile[1]}", "read": sigma, "light": light, "scores": s})
                cells = [f"{s[f'identity {m}']:.2f} / " + (f"{s[f'multiplexed {m}']:.2f}"
                                                           if f"multiplexed {m}" in s else "–") for m in methods]
                best_id = max(s[f"identity {m}"] for m in methods)
                mx = [s[f"multiplexed {m}"] for m in methods if f"multiplexed {m}" in s]
                best = f"{best_id:.2f} / {max(mx):.2f} | {max(mx) - best_id:+.2f}" if mx else f"{best_id:.2f} / – | –"
                demux = f"{s['demux nc']:.2f}" if "demux nc" in s else "–"
                print(f"| {tile[0]}x{tile[1]} | {sigma} | {light} | " + " | ".join(cells) + f" | {demux} | {best} |",
                      flush=True)
    if reads == READ_NOISE:
        _plot(rows, methods, args.out)


if __name__ == "__main__":
    main()
