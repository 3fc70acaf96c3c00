"""``flexvox demo``: the end-to-end story on the simulated rig, as an HTML report."""

from __future__ import annotations

from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, CliError

HELP = "run the end-to-end demo on the simulated rig and write an HTML report"
STEPS = ("design", "calibrate", "shutter check", "capture", "reconstruct", "figures", "videos", "accuracy vs time",
         "report")


def register(sub) -> None:
    """Add the ``demo`` subcommand."""
    p = sub.add_parser(
        "demo",
        help=HELP,
        description=(
            "Design a 4x4 code, calibrate the simulated rig (a projector finer than the camera behind a hidden "
            "homography, a hidden trigger offset), check the shutter with a strobe (slot accuracy with the "
            "calibration, with the raw phase, uncalibrated), capture a built-in scene with moving and still parts "
            "through the calibration (the drummer-like scene by default), read it back and reconstruct it "
            "(re-binning, high-SR and high-TR diffusion, "
            "GAP-TV, motion-aware) and write DIR/index.html with figures in the spirit of the paper's Figs. 1, "
            "3, 4, 5, 7-8, MP4s and the accuracy-vs-time table and plot."
        ),
    )
    p.add_argument("--out", type=Path, default=Path("flexvox-demo"), metavar="DIR",
                   help="where the report goes (default: flexvox-demo/)")
    p.add_argument("--quick", action="store_true", help="a smaller capture and fewer GAP-TV iterations")
    p.add_argument("--scene", default="drummer", help="built-in scene (default drummer)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the report an earlier run left in DIR (`make demo` passes it); a folder holding "
                        "anything else is never replaced")
    p.set_defaults(func=run)


def run(args) -> int:
    """Carry out ``flexvox demo``."""
    from tqdm import tqdm

    from flexvox_app.demo.run import DemoConfig, run_demo
    from flexvox_core.simulate.scenes import SCENES

    if args.scene not in SCENES:
        raise CliError(f"unknown scene {args.scene!r}; built-in scenes: {', '.join(SCENES)}")
    from flexvox_app.demo.run import check_report_folder
    from flexvox_core.output_files import OutputError

    try:  # before any work; the report is built beside it and moved into place when complete
        check_report_folder(args.out, args.overwrite)
    except OutputError as exc:
        raise CliError(str(exc)) from None
    cfg = DemoConfig(out=args.out, quick=args.quick, scene=args.scene, overwrite=args.overwrite)
    with tqdm(total=len(STEPS), unit="step", leave=False) as bar:
        def step(name):
            if bar.n < len(STEPS) and bar.desc:
                bar.update(1)
            bar.set_description(name)
        try:
            res = run_demo(cfg, step=step)
        except OutputError as exc:
            raise CliError(str(exc)) from None
        except OSError as exc:
            raise CliError(f"cannot write the report in {args.out}: {exc.strerror}") from None
        bar.update(len(STEPS) - bar.n)
    for note in res.notes:
        print(f"- {note}")
    width = max(len(r["method"]) for r in res.rows)
    print(f"\n{'method':<{width}}  PSNR (dB)  seconds")
    for r in sorted(res.rows, key=lambda r: -r["psnr"]):
        print(f"{r['method']:<{width}}  {r['psnr']:9.2f}  {r['seconds']:7.2f}")
    print(f"\ndone in {res.seconds:.0f} s; report: {args.out / 'index.html'}")
    return EXIT_OK
