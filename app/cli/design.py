"""``flexvox design``: solve the paper's integer program for a tile, or verify a code file."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from flexvox_app.cli.errors import EXIT_FAILED, EXIT_OK, CliError, arg_type
from flexvox_core.tiles import MAX_TILE_SIDE, parse_tile

if TYPE_CHECKING:  # the command's own imports are in the functions that run it: parsing needs none of them
    import numpy as np

HELP = "design a shutter code for an MxN tile (the paper's Eq. 1), or verify a code file"


def _separation(text: str):
    if text == "auto":
        return "auto"
    if not text.isdigit():
        raise ValueError(f"--separation must be 'auto' or a whole number >= 0; got {text!r}")
    return int(text)


def register(sub) -> None:
    """Add the ``design`` subcommand."""
    p = sub.add_parser(
        "design",
        help=HELP,
        description=(
            "Design an identity code whose samples support every division of the tile "
            "(every a x b x c block holds exactly one sample), choosing among the solutions "
            "the one whose 4-neighbours fire furthest apart in time. Prints the firing order "
            "as a grid and every supported [TR, SR]. With --verify, reports which divisions "
            "a saved code supports and whether `capture --code` can shutter with it (exit 1 if "
            "it misses any, or if capture cannot use it)."
        ),
    )
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--tile", type=arg_type(parse_tile), metavar="MxN",
                      help=f"tile rows x columns, each 1..{MAX_TILE_SIDE} (e.g. 4x4; K = M*N slots)")
    what.add_argument("--verify", type=Path, metavar="CODE.json",
                      help="check a code file written by `flexvox design -o` (or any JSON "
                           "with `order` or `code`)")
    p.add_argument("--divisions", metavar="AxBxC[,AxBxC...]",
                   help="support only these divisions (rows x columns x slots); default: all")
    p.add_argument("--separation", type=arg_type(_separation), default="auto", metavar="auto|N",
                   help="4-neighbour firing-time gap: 'auto' maximises it (tiles up to K=40), "
                        "N demands at least N slots, 0 solves Eq. 1 alone (default: auto)")
    p.add_argument("--multiplexed", action="store_true",
                   help="an S-matrix multiplexed code instead (K must be 3 mod 4: 1x3, 1x7, 3x5, 5x7)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("-o", "--output", type=Path, metavar="CODE.json", help="also write the code as JSON")
    p.add_argument("--overwrite", action="store_true", help="replace an existing CODE.json")
    p.set_defaults(func=run)


def _grid(order: np.ndarray) -> str:
    width = len(str(order.max()))
    return "\n".join("  " + " ".join(f"{v:>{width}d}" for v in row) for row in order)


def _resolution_table(divisions) -> str:
    lines = ["  block      TR   SR"]
    lines += [f"  {d.label:<9} {d.tr:>3}   {d.sr}" for d in divisions]
    return "\n".join(lines)


def _write(path: Path | None, payload: dict, overwrite: bool) -> None:
    if path is None:
        return
    from flexvox_core.output_files import OutputError, write_text_atomic

    try:
        write_text_atomic(path, json.dumps(payload, indent=1) + "\n", overwrite=overwrite)
    except OutputError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"cannot write {path}: {exc.strerror or exc}") from None


def _load_code(path: Path) -> np.ndarray:
    from flexvox_core.code_file import CodeFileError, read_code

    try:
        return read_code(path)
    except CodeFileError as exc:
        raise CliError(str(exc)) from None


def _verify(args) -> int:
    """``flexvox design --verify``: the divisions a code file supports, and whether a capture can shutter with it
    (the same rules as ``capture --code``: an identity code whose order, code and tile agree, or the S-matrix code
    of ``design --multiplexed``, whose demultiplexed slots are then the ones verified)."""
    from flexvox_core.code_file import CodeFileError, load_shutter_code
    from flexvox_core.codes import code_from_order, verify
    from flexvox_core.multiplex import MultiplexedCode

    code = _load_code(args.verify)
    try:
        usable, problem = load_shutter_code(args.verify), None
    except CodeFileError as exc:
        usable, problem = None, str(exc)
    multiplexed = isinstance(usable, MultiplexedCode)
    try:
        result = verify(code_from_order(usable.placement) if multiplexed else code)
    except ValueError as exc:
        raise CliError(f"{args.verify}: {exc}") from None
    ok = problem is None and result.supports_all and (result.identity or multiplexed)
    if args.json:
        print(json.dumps({**result.as_dict(), "multiplexed": multiplexed, "capture_ready": problem is None,
                          "problem": problem}))
        return EXIT_OK if ok else EXIT_FAILED
    m, n = result.tile
    if multiplexed:
        print(f"{args.verify}: {m}x{n} tile, K = {m * n}; an S-matrix multiplexed code (each pixel open in "
              f"{(m * n + 1) // 2} of {m * n} slots); its demultiplexed slots: {result.message}")
    else:
        print(f"{args.verify}: {m}x{n} tile, K = {m * n}; {result.message}")
    if result.supported:
        print("supported:\n" + _resolution_table(result.supported))
    if result.unsupported:
        print("NOT supported (blocks without exactly one sample):")
        for d in result.unsupported:
            print(f"  {d.label:<9} TR {d.tr:>3}  SR {d.sr}  ({result.failing_blocks[d.label]} bad blocks)")
    if problem is not None:
        print(f"capture cannot use it: {problem}")
    return EXIT_OK if ok else EXIT_FAILED


def run(args) -> int:
    """Carry out ``flexvox design``."""
    from flexvox_core.codes import code_from_order, verify
    from flexvox_core.divisions import enumerate_divisions, parse_division
    from flexvox_core.multiplex import multiplexed_code

    if args.output is not None:
        from flexvox_core.output_files import CLI_OVERWRITE_HINT, OutputError, check_output

        try:  # before the solve, which can take seconds
            check_output(args.output, overwrite=args.overwrite, inputs=[args.verify], hint=CLI_OVERWRITE_HINT)
        except OutputError as exc:
            raise CliError(str(exc)) from None
    if args.verify is not None:
        return _verify(args)

    m, n = args.tile
    if args.multiplexed:
        try:
            mc = multiplexed_code((m, n))
        except ValueError as exc:
            raise CliError(str(exc)) from None
        payload = mc.as_dict()
        payload["resolutions"] = [d.as_dict() for d in verify(code_from_order(mc.placement)).supported]
        _write(args.output, payload, args.overwrite)
        if args.json:
            print(json.dumps(payload))
            return EXIT_OK
        print(f"{m}x{n} tile, K = {mc.K}: S-matrix multiplexed code, each pixel open in "
              f"{(mc.K + 1) // 2} of {mc.K} slots")
        for r in range(mc.K):
            print(f"  pixel ({r // n},{r % n}): " + "".join("#" if v else "." for v in mc.S[r]))
        print(f"light throughput {mc.throughput:.1%} of the exposure (identity code: {1 / mc.K:.1%})")
        print(f"SNR after demultiplexing: x{mc.snr_gain_read:.2f} when read noise dominates, "
              f"x{mc.snr_gain_photon:.2f} when photon noise dominates")
        print("demultiplexed slots are placed by the identity order:\n" + _grid(mc.placement))
        return EXIT_OK

    divisions = None
    if args.divisions:
        try:
            divisions = [parse_division(t, (m, n)) for t in args.divisions.split(",") if t.strip()]
        except ValueError as exc:
            raise CliError(str(exc)) from None
        if not divisions:
            raise CliError(f"--divisions must name at least one division AxBxC (e.g. 2x2x4); got {args.divisions!r}")
    from flexvox_core.design import design_code  # the solver's scipy.optimize: imported by this command alone

    try:
        result = design_code((m, n), divisions=divisions, separation=args.separation)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    payload = result.as_dict()
    if result.success:
        _write(args.output, payload, args.overwrite)
    if args.json:
        print(json.dumps(payload))
        return EXIT_OK if result.success else EXIT_FAILED
    if not result.success:
        flags = "--divisions AxBxC,... for the divisions"
        if "neighbour gap" in result.message:  # not where no code exists at any gap
            flags = "--separation N for the gap, " + flags
        print(f"{m}x{n} tile: {result.message} ({flags})", file=sys.stderr)
        return EXIT_FAILED
    print(f"{m}x{n} tile, K = {m * n}: {result.message}")
    print("firing order (slot of each tile pixel):\n" + _grid(result.order))
    all_divs = enumerate_divisions((m, n))
    print(f"supported resolutions ({len(result.supported)} of {len(all_divs)} divisions):")
    print(_resolution_table(result.supported))
    print(f"solved in {result.solve_time_s:.2f} s")
    if args.output:
        print(f"wrote {args.output}")
    return EXIT_OK
