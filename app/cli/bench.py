"""``flexvox bench``: what accuracy costs in time, on the built-in scenes (and SCI data if present)."""

from __future__ import annotations

import time
from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, defer
from flexvox_app.cli.method_options import add_device_option, resolved_device


def register(sub) -> None:
    """Add the ``bench`` subcommand."""
    p = sub.add_parser(
        "bench",
        help="accuracy against time for every reconstruction and knob",
        description=(
            "Run every reconstruction and knob setting (re-binning at each division, diffusion-time "
            "and tensor sweeps, the nc/explicit/steady solvers, GAP-TV iterations) on the built-in "
            "scenes at K=8 and K=16, and on the SCI benchmark's Runner and Drop when "
            "$FLEXVOX_DATA or ../shared/data holds them. Prints a table (PSNR, SSIM, seconds) and "
            "writes results.csv, results.json and pareto.png. With REC, on that recording instead: "
            "re-binning at each division, a diffusion-time sweep, GAP-TV and motion-aware, each scored "
            "by the PSNR estimated from the recording alone (with its interval; the true PSNR beside it "
            "when the recording holds a ground truth); a method the estimate cannot serve says why."
        ),
    )
    p.add_argument("recording", type=Path, nargs="?", metavar="REC",
                   help="a recording (.zarr) to bench on, scored without ground truth")
    p.add_argument("--quick", action="store_true", help="fewer scenes, knobs and frames (under a minute)")
    p.add_argument("--no-sci", action="store_true", help="skip the SCI benchmark data even if present")
    p.add_argument("-o", "--out", type=Path, default=Path("bench/results"), metavar="DIR",
                   help="where results go (default bench/results)")
    p.add_argument("--overwrite", action="store_true", help="replace the results an earlier run left in DIR")
    defer(p, add_device_option)  # the device module: only when this command is used
    p.set_defaults(func=run)

OUTPUTS = ("results.csv", "results.json", "pareto.png")


def run(args) -> int:
    """Carry out ``flexvox bench``."""
    from tqdm import tqdm

    from flexvox_app.accuracy_bench import pareto, run_bench, summary
    from flexvox_app.cli.errors import CliError
    from flexvox_core.output_files import OutputError, check_writable, refuse_output_onto_input

    device = resolved_device(args)
    try:  # results written into the recording's own folder would be read as part of it
        for name in OUTPUTS:
            refuse_output_onto_input(args.out / name, [args.recording])
    except OutputError as exc:
        raise CliError(str(exc)) from None
    if args.recording is not None:  # opened before -o is made: a wrong path leaves no empty results folder
        from flexvox_core.recording import RecordingError, open_recording

        try:
            open_recording(args.recording)
        except RecordingError as exc:
            raise CliError(str(exc)) from None
    if args.out.exists() and not args.out.is_dir():
        raise CliError(f"-o {args.out} is a file; -o takes a folder, where results.csv, results.json and pareto.png "
                       "go")
    old = [name for name in OUTPUTS if (args.out / name).exists()]
    if old and not args.overwrite:
        raise CliError(f"{args.out} already holds {', '.join(old)} from an earlier run; use --overwrite to replace "
                       "them, or -o another folder")
    try:  # before the runs, which take minutes
        args.out.mkdir(parents=True, exist_ok=True)
        check_writable(args.out)
    except OSError as exc:
        raise CliError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    except OutputError as exc:
        raise CliError(str(exc)) from None
    t0 = time.perf_counter()
    if args.recording is not None:
        return _run_on_recording(args, device, t0)
    with tqdm(desc="captures", unit="capture", leave=False) as bar:
        def progress(done, total):
            bar.total = total
            bar.update(done - bar.n)
        rows = run_bench(args.out, quick=args.quick, sci=not args.no_sci, progress=progress, device=device)
    summ = summary(rows)
    front = {(r["family"], r["method"]) for r in pareto(summ)}
    print("| method | PSNR (dB) | SSIM | seconds | Pareto |")
    print("|---|---|---|---|---|")
    for r in summ:
        mark = "yes" if (r["family"], r["method"]) in front else ""
        print(f"| {r['method']} | {r['psnr']:.2f} | {r['ssim']:.3f} | {r['seconds']:.3f} | {mark} |")
    sci = [r for r in rows if "SCI" in r["case"]]
    if sci:
        print("\nSCI benchmark (2x4 code), best per family:")
        for case in sorted({r["case"] for r in sci}):
            for fam in sorted({r["family"] for r in sci}):
                best = max((r for r in sci if r["case"] == case and r["family"] == fam), key=lambda r: r["psnr"])
                print(f"  {case:<18} {fam:<26} {best['psnr']:.2f} dB  {best['seconds']:.3f} s  "
                      f"{best['method']}")
    on_gpu = sum(r["device"] == "cuda" for r in rows)
    print(f"\n{on_gpu} of {len(rows)} runs on the GPU" if device == "cuda" else "\nevery run on the CPU")
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s; "
          f"wrote {args.out}/results.csv, results.json, pareto.png")
    return EXIT_OK


def _run_on_recording(args, device: str, t0: float) -> int:
    """``flexvox bench REC``: the user's recording, scored by the estimate."""
    from tqdm import tqdm

    from flexvox_app.cli.bench_recording import print_table, run_recording_bench
    from flexvox_app.cli.errors import CliError
    from flexvox_core.recording import RecordingError

    with tqdm(desc="methods", unit="method", leave=False) as bar:
        def progress(done, total):
            bar.total = total
            bar.update(done - bar.n)
        try:
            rows = run_recording_bench(args.recording, args.out, quick=args.quick, device=device, progress=progress)
        except (ValueError, RecordingError) as exc:
            raise CliError(str(exc)) from None
    print_table(rows)
    print(f"{len(rows)} runs in {time.perf_counter() - t0:.0f} s; "
          f"wrote {args.out}/results.csv, results.json, pareto.png")
    return EXIT_OK
