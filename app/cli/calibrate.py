"""``flexvox calibrate``: co-location check, homography, shutter verification and sync, in order."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from flexvox_app.cli.app import add_screen_options, list_screens, with_projector_screen
from flexvox_app.cli.errors import EXIT_FAILED, EXIT_OK, CliError, arg_type
from flexvox_core.json_file import finite_or_null

HELP = "calibrate the rig: co-location, projector-camera homography, shutter masks, synchronisation"

def _tile(text: str):
    from flexvox_calibration.pipeline import calibration_tile
    from flexvox_core.tiles import parse_tile

    return calibration_tile(parse_tile(text))


def _baseline(text: str):
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--mock-baseline must be three numbers BX,BY,BZ; got {text!r}") from None
    if len(vals) != 3:
        raise ValueError(f"--mock-baseline must be three numbers BX,BY,BZ; got {text!r}")
    return vals


def _seed(text: str) -> int:
    if not text.isdigit():
        raise ValueError(f"--seed must be a whole number >= 0; got {text!r}")
    return int(text)


def register(sub) -> None:
    """Add the ``calibrate`` subcommand."""
    p = sub.add_parser(
        "calibrate",
        help=HELP,
        description=(
            "Run the rig's calibration in order: the co-location check (alignment numbers and, on the "
            "simulated rig, the parallax test across two target depths), the projector-camera homography "
            "(Gray code + phase shifting, RANSAC), the shutter masks of a code (each slot shown alone and "
            "decoded) and the synchronisation (phase and sub-slot delay, dropped frames, drift). Exit 0 when "
            "every step succeeds, 1 when one fails (its message says what to do). With --rig mock the "
            "simulated rig hides a homography, phase and delay drawn from --seed, and --json compares them."
        ),
    )
    p.add_argument("--rig", default="mock", metavar="mock|RIG.toml",
                   help="the simulated rig (default) or a rig profile (rig_drivers/PROFILES.md)")
    p.add_argument("--seed", type=arg_type(_seed), default=0, metavar="S",
                   help="simulated rig: seed of its hidden homography, timing and noise (default 0)")
    p.add_argument("--tile", type=arg_type(_tile), default=(4, 4), metavar="MxN",
                   help="tile of the shutter code to verify (K = M*N slots, at least 2; default 4x4)")
    p.add_argument("--mock-baseline", type=arg_type(_baseline), default=(0.0, 0.0, 0.0), metavar="BX,BY,BZ",
                   help="simulated rig: the projector's offset from the camera's centre, in units of the "
                        "target distance (default 0,0,0: co-located)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object instead of text (strict JSON: a number that is not finite, such as "
                        "a value a step did not measure, is null)")
    p.add_argument("-o", "--output", type=Path, metavar="CAL.json",
                   help="write the calibration (homography + sync) when every step succeeds")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing CAL.json (the old file stays until the new one is complete)")
    add_screen_options(p)
    p.set_defaults(func=run)


class _Progress:
    """tqdm bars on stderr, one per step."""

    def __init__(self, quiet: bool, interrupted=None):
        self.quiet = quiet
        self.interrupted = interrupted

    def check(self) -> None:
        """Stop (as a CLI error) once Ctrl-C was pressed while Qt's event loop runs."""
        if self.interrupted is not None and self.interrupted.is_set():
            raise CliError("interrupted: the devices were stopped and nothing was written")

    def __call__(self, desc: str):
        from tqdm import tqdm

        self.check()
        bar = tqdm(desc=desc, unit="pattern", file=sys.stderr, leave=False, disable=self.quiet or None)

        def update(done: int, total: int) -> None:
            self.check()
            if bar.total != total:
                bar.reset(total=total)
            bar.n = done
            bar.refresh()

        update.bar = bar
        return update


def _open(args, spec, display=None):
    from flexvox_calibration.session import RigSession
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    if spec.simulated:
        # The one simulated rig (as `flexvox capture --rig mock --seed S` opens it); the calibration puts
        # its target in view. What is in front of it otherwise does not matter here: a still scene.
        rig = open_rig("mock", scene="static", subframes=16, seed=args.seed, baseline=args.mock_baseline,
                       clock=VirtualClock())
        return rig, RigSession.from_rig(rig)
    rig = open_rig(spec, projector_display=display)
    return rig, RigSession.from_rig(rig)


def run(args) -> int:
    """Carry out ``flexvox calibrate``."""
    from rig_drivers.profile import resolve_rig

    if args.list_screens:
        return list_screens()
    if args.output is not None:
        from flexvox_core.output_files import CLI_OVERWRITE_HINT, OutputError, check_output

        rig_file = None if args.rig == "mock" else Path(args.rig)
        try:  # checked before calibrating, so the run is not lost
            check_output(args.output, overwrite=args.overwrite, inputs=[rig_file], hint=CLI_OVERWRITE_HINT)
        except OutputError as exc:
            raise CliError(f"{exc} (checked before calibrating, so no run is lost)") from None
    try:
        spec = resolve_rig(args.rig)
    except ValueError as exc:
        raise CliError(str(exc).splitlines()[0]) from None
    return with_projector_screen(args, spec, lambda display, interrupted: _calibrate(args, spec, display, interrupted))


def _calibrate(args, spec, display=None, interrupted=None) -> int:
    from flexvox_calibration.errors import CalibrationError
    from flexvox_calibration.files import save_calibration
    from flexvox_calibration.pipeline import run_calibration, truth_comparison
    from rig_drivers.errors import DeviceError

    t0 = time.perf_counter()
    progress = _Progress(quiet=False, interrupted=interrupted)
    try:
        rig, session = _open(args, spec, display)
        try:
            outcome = run_calibration(rig, session, tile=tuple(args.tile), progress=progress)
            report, ok, keep = outcome.report, outcome.success, outcome.keep
        finally:
            rig.close()
        if ok and args.output is not None:
            save_calibration(args.output, keep["homography"], session.identity, sync=keep.get("sync"),
                             overwrite=args.overwrite)
    except (CalibrationError, DeviceError, ValueError) as exc:
        raise CliError(str(exc).splitlines()[0]) from None
    elapsed = time.perf_counter() - t0
    flat = {
        "success": ok,
        "rms_px": report.get("homography", {}).get("rms_px"),
        "coverage": report.get("homography", {}).get("coverage"),
        "shutter_slot_accuracy": report.get("shutter", {}).get("accuracy"),
        "phase_found": report.get("sync", {}).get("phase_slots"),
        "delay_found_us": report.get("sync", {}).get("delay_us"),
        "seconds": elapsed,
    }
    if rig.simulated is not None:
        flat.update(truth_comparison(rig, outcome, session.camera_size))
    if ok and args.output is not None:
        flat["output"] = str(args.output)
    if args.json:
        print(json.dumps(finite_or_null(flat | {"steps": report}), default=float, allow_nan=False))
        return EXIT_OK if ok else EXIT_FAILED
    for name in ("colocation", "homography", "shutter", "sync", "frames"):
        step = report.get(name)
        if step is None:
            continue
        if name == "colocation":
            print(f"co-location: {step['alignment']['message']}")
            print(f"parallax:    {step['parallax']['message']}")
            continue
        print(f"{name + ':':<12} {step['message']}")
        for w in step.get("warnings", []):
            print(f"  warning: {w}")
    if rig.simulated is not None and "homography_error_px" in flat:
        print(f"against the simulated rig's truth: homography error {flat['homography_error_px']:.3f} px, "
              f"phase {flat['phase_found']} (true {flat['phase_true']}), delay "
              f"{flat['delay_found_us'] if flat['delay_found_us'] is None else round(flat['delay_found_us'])} µs "
              f"(true {flat['delay_true_us']})")
    if ok and args.output is not None:
        print(f"wrote {args.output}")
    if not ok:
        print(f"calibration stopped: the {report.get('failed', 'last')} step failed", file=sys.stderr)
    print(f"done in {elapsed:.1f} s")
    return EXIT_OK if ok else EXIT_FAILED
