"""``flexvox app``: the Qt application (device panel; Calibrate, Capture and Review workspaces)."""

from __future__ import annotations

from pathlib import Path

from app.cli.errors import CliError

HELP = "start the Qt application (device panel; Calibrate, Capture, Review)"


def register(sub) -> None:
    """Add the ``app`` subcommand."""
    p = sub.add_parser(
        "app",
        help=HELP,
        description=(
            "Start the flexvox window: a device panel for the rig and three workspaces. Review opens a "
            "recording, plays it, reconstructs it (re-binning, diffusion, GAP-TV, motion-aware) with a "
            "slider from high spatial to high temporal resolution, compares and exports. Capture chooses the "
            "code and timing and shows a live view. Calibrate lists what the calibration wizards will do. "
            "The simulated rig is the default."
        ),
    )
    p.add_argument("recording", nargs="?", type=Path, metavar="REC",
                   help="a recording (.zarr) to open in the Review workspace")
    p.add_argument("--rig", default="mock", metavar="mock|RIG.toml",
                   help="the simulated rig (default) or a rig profile (rig_drivers/PROFILES.md)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Carry out ``flexvox app``."""
    from rig_drivers.errors import SettingError
    from rig_drivers.profile import open_rig

    if args.recording is not None and not args.recording.exists():
        raise CliError(f"{args.recording}: no such recording")
    try:
        rig = open_rig(args.rig)
    except SettingError as exc:
        raise CliError(str(exc)) from None
    from app.gui.application import launch  # Qt is loaded only here

    return launch(rig, recording=args.recording)
