"""The reconstruction options that ``reconstruct``, ``export`` and ``batch`` share, and the
:class:`~flexvox_core.reconstruct.run.Method` they describe."""

from __future__ import annotations

import re

from app.cli.errors import arg_type

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
MOTION_ONLY = ("--passes", "--refine", "--slow-reach")


def parse_triple(text: str, what: str = "tensor"):
    """Three numbers written ``a,b,c`` (or ``axbxc``), for ``--tensor`` and the like."""
    parts = [p.strip() for p in re.split(r"[,xX]", text) if p.strip()]
    if len(parts) == 3 and all(_NUMBER.fullmatch(p) for p in parts):
        return tuple(float(p) for p in parts)
    raise ValueError(f"--{what} must be three numbers separated by commas; got {text!r}")


def add_method_options(p, *, chunk: int) -> None:
    """Add the method options and ``--chunk F`` (default ``chunk`` camera frames) to parser ``p``."""
    from flexvox_core.motion.pipeline import DEFAULT_TIME as MA_TIME
    from flexvox_core.motion.pipeline import SLOW_REACH
    from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, SOLVERS
    from flexvox_core.reconstruct.run import METHODS

    p.add_argument("--method", choices=METHODS, default="diffusion", help="default: diffusion")
    p.add_argument("--block", metavar="a,b,c", help="rebin: rows,columns,slots of the division "
                   "(default: the one with TR closest to sqrt(K))")
    p.add_argument("--no-interpolate", action="store_true", help="rebin: blocks without interpolation")
    p.add_argument("--tensor", type=arg_type(parse_triple), default=DEFAULT_TENSOR,
                   metavar="cx,cy,ct", help=f"diffusion tensor (default {','.join(f'{c:g}' for c in DEFAULT_TENSOR)})")
    p.add_argument("--time", type=float, metavar="n",
                   help=f"diffusion time, the accuracy knob (default {DEFAULT_TIME:g}; motion-aware {MA_TIME:g})")
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
    p.add_argument("--chunk", type=int, default=chunk, metavar="F", help=f"camera frames per chunk (default {chunk})")


def method_from_args(args, tile):
    """The :class:`~flexvox_core.reconstruct.run.Method` the options describe (``ValueError`` if they clash)."""
    from flexvox_core.divisions import parse_division
    from flexvox_core.reconstruct.run import Method

    given = [opt for opt, on in zip(MOTION_ONLY, (args.passes != 1, bool(args.refine), args.slow_reach is not None),
                                    strict=True) if on]
    if args.method != "motion-aware" and given:
        raise ValueError(f"{' and '.join(given)} {'goes' if len(given) == 1 else 'go'} with --method motion-aware, "
                         f"not {args.method} ({', '.join(MOTION_ONLY[:-1])} and {MOTION_ONLY[-1]} go with "
                         "--method motion-aware only)")
    block = parse_division(args.block.replace(",", "x"), tuple(tile)) if args.block else None
    return Method(args.method, block=block, interpolate=not args.no_interpolate, tensor=args.tensor,
                  time=args.time, solver=args.solver, iterations=args.iterations, flow=args.flow,
                  passes=args.passes, refine_time=args.refine, slow_reach=args.slow_reach)
