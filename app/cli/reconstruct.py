"""``flexvox reconstruct``: a recording in, the full (S, H, W) video out."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from app.cli.errors import EXIT_OK, CliError, arg_type
from flexvox_core.divisions import parse_division
from flexvox_core.motion.pipeline import DEFAULT_TIME as MA_TIME
from flexvox_core.motion.pipeline import SLOW_REACH
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct import prepare
from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, SOLVERS
from flexvox_core.reconstruct.run import METHODS, Method, reconstruct
from flexvox_core.recording import RecordingError, open_recording
from flexvox_core.video_io import WRITABLE, write_video

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def parse_triple(text: str, what: str = "tensor"):
    """Three numbers written ``a,b,c`` (or ``axbxc``), for ``--tensor`` and the like."""
    parts = [p.strip() for p in re.split(r"[,xX]", text) if p.strip()]
    if len(parts) == 3 and all(_NUMBER.fullmatch(p) for p in parts):
        return tuple(float(p) for p in parts)
    raise ValueError(f"--{what} must be three numbers separated by commas; got {text!r}")


def register(sub) -> None:
    """Add the ``reconstruct`` subcommand."""
    p = sub.add_parser(
        "reconstruct",
        help="reconstruct the high-speed video of a recording",
        description=(
            "Reconstruct the full (S, H, W) float32 video in [0, 1] (S = F*K) of a recording and "
            f"write it to OUT ({', '.join(WRITABLE)}). Methods: rebin (re-binning at a division), "
            "diffusion (constant tensor; the default nc solver is the fast normalized convolution), "
            "gap-tv (the classical peer), motion-aware (the seed's Section 4: diffusion tensors oriented "
            "along optical flow). Multiplexed recordings are demultiplexed first."
        ),
    )
    p.add_argument("recording", type=Path, metavar="REC", help="a flexvox recording (.zarr)")
    p.add_argument("--method", choices=METHODS, default="diffusion", help="default: diffusion")
    p.add_argument("--block", metavar="a,b,c", help="rebin: rows,columns,slots of the division "
                   "(default: the one with TR closest to sqrt(K))")
    p.add_argument("--no-interpolate", action="store_true", help="rebin: blocks without interpolation")
    p.add_argument("--tensor", type=arg_type(parse_triple), default=DEFAULT_TENSOR,
                   metavar="cx,cy,ct", help=f"diffusion tensor (default {','.join(f'{c:g}' for c in DEFAULT_TENSOR)})")
    p.add_argument("--time", type=float, metavar="n",
                   help=f"diffusion time, the accuracy knob (default {DEFAULT_TIME:g}; motion-aware "
                        f"{MA_TIME:g})")
    p.add_argument("--solver", choices=SOLVERS, default="nc", help="diffusion solver (default nc)")
    p.add_argument("--iterations", type=int, default=40, help="gap-tv iterations (default 40)")
    p.add_argument("--flow", choices=("dis", "deepflow", "farneback", "tvl1"), default="dis",
                   help="motion-aware: optical-flow backend (default dis: DIS + variational refinement)")
    p.add_argument("--passes", type=int, default=1, metavar="N",
                   help="motion-aware: flow re-estimated from the previous pass N-1 times (default 1)")
    p.add_argument("--refine", type=float, default=0.0, metavar="n",
                   help="motion-aware: extra monotone variable-tensor diffusion time (default 0)")
    p.add_argument("--slow-reach", type=float, metavar="R",
                   help="motion-aware: how far the slowly moving voxels' gather reaches along their "
                        f"trajectory, in sampling periods each way (default {SLOW_REACH:g}; 0: no long "
                        "gather, faster where the whole picture drifts slowly)")
    p.add_argument("--figures", type=Path, metavar="DIR",
                   help="motion-aware: write flow (colour wheel, quiver), resolution map and a panel "
                        "like the seed's Figs. 7-8 as PNGs")
    p.add_argument("--fps", type=float, default=30.0, help="playback rate of an .mp4 output (default 30)")
    p.add_argument("--chunk", type=int, default=16, metavar="F", help="camera frames per chunk (default 16)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT", help="output file")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.set_defaults(func=run)


def load_capture(path: Path):
    """Normalised identity-code frames and their code from a recording (demultiplexed)."""
    rec = open_recording(path)
    dropped = rec.per_frame("dropped")
    if dropped.any():
        ids = np.flatnonzero(dropped)[:5].tolist()
        raise CliError(f"{path} has {int(dropped.sum())} dropped frame(s) (first at rows {ids}); "
                       "reconstructing across gaps is not supported yet")
    frames = rec.normalised_frames()
    if rec.attrs.get("multiplexed"):
        mc = multiplexed_code(tuple(rec.attrs["tile"]), placement=rec.attrs.get("placement_order"))
        frames, code = prepare(frames, mc)
    else:
        code = rec.code
    return rec, frames, code


def run(args) -> int:
    """Carry out ``flexvox reconstruct``."""
    try:
        if args.output.suffix.lower() not in WRITABLE:
            raise ValueError(f"-o {args.output}: the output must end in {', '.join(WRITABLE)}")
        if args.output.exists() and not args.overwrite:
            raise ValueError(f"{args.output} already exists (use --overwrite)")
        rec, frames, code = load_capture(args.recording)
        block = None
        if args.block:
            block = parse_division(args.block.replace(",", "x"), tuple(rec.attrs["tile"]))
        method = Method(args.method, block=block, interpolate=not args.no_interpolate, tensor=args.tensor,
                        time=args.time, solver=args.solver, iterations=args.iterations, flow=args.flow,
                        passes=args.passes, refine_time=args.refine, slow_reach=args.slow_reach)
        if args.slow_reach is not None and args.method != "motion-aware":
            raise ValueError("--slow-reach goes with --method motion-aware")
        if args.figures and args.method != "motion-aware":
            raise ValueError("--figures goes with --method motion-aware")
    except (ValueError, RecordingError) as exc:
        raise CliError(str(exc)) from None
    F, H, W = frames.shape
    t0 = time.perf_counter()
    with tqdm(total=F, unit="frame", desc=method.label(), disable=F <= args.chunk, leave=False) as bar:
        def progress(done, total):
            bar.update(done - bar.n)
        try:
            video = reconstruct(frames, code, method, chunk_frames=args.chunk, progress=progress)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    seconds = time.perf_counter() - t0
    attrs = {"source": str(args.recording), "method": method.as_dict(), "seconds": seconds}
    try:
        write_video(args.output, video, fps=args.fps, attrs=attrs, overwrite=args.overwrite)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    line = f"{method.label()}: {video.shape[0]} sub-frames of {H}x{W} in {seconds:.2f} s"
    line += f" ({video.size / max(seconds, 1e-9) / 1e6:.0f} M voxels/s)"
    if rec.has_ground_truth:
        from flexvox_core.metrics import psnr

        line += f"; PSNR vs ground truth {psnr(rec.ground_truth(), video).mean:.2f} dB"
    print(line)
    print(f"wrote {args.output}")
    if args.figures:
        from app.figures import write_figures

        written = write_figures(args.figures, frames, code, method)
        print(f"wrote {len(written)} figures to {args.figures}")
    return EXIT_OK
