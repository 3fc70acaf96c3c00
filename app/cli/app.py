"""``flexvox app``: the Qt application (device panel; Calibrate, Capture and Review workspaces)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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
            "code and timing, shows a live view and records through the crash-safe capture service. Calibrate "
            "runs the whole calibration with its figures, live co-location numbers and the synchronisation "
            "wizard. The simulated rig is the default (a co-located rig: identity projector-camera map, as "
            "`flexvox capture --rig mock`)."
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
        # The simulated rig is co-located with an identity map, like `flexvox capture --rig mock`, so
        # recordings made from the window line up with the code (Capture loads no calibration yet).
        rig = open_rig(args.rig, homography=np.eye(3)) if args.rig == "mock" else open_rig(args.rig)
    except SettingError as exc:
        raise CliError(str(exc)) from None
    from app.gui.application import launch  # Qt is loaded only here

    return launch(rig, recording=args.recording)
