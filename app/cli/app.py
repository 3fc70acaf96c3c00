"""The command line's one door into Qt: ``flexvox app`` and the projector screen.

``flexvox app`` starts the Qt application (device panel; Calibrate, Capture and Review
workspaces). ``flexvox calibrate|capture --projector-screen N`` show the projector's patterns on
a screen (a DLPC350 takes them on its video input) through :mod:`flexvox_app.gui.projector.display`.
Both import :mod:`flexvox_app.gui` lazily, here and nowhere else in :mod:`flexvox_app.cli` (an import-linter
contract in pyproject.toml holds every other CLI module to that).
"""

from __future__ import annotations

from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, CliError, arg_type
from flexvox_app.qt_platform import display_problem, missing_gui_extra

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
            "wizard. The simulated rig is the default: the same rig as `flexvox calibrate|capture --rig mock "
            "--seed S`, a projector finer than the camera behind a hidden homography and a trigger offset "
            "that is not a whole slot, so calibrate it, use the calibration for capture, record and review "
            "as at a real rig."
        ),
    )
    p.add_argument("recording", nargs="?", type=Path, metavar="REC",
                   help="a recording (.zarr) to open in the Review workspace")
    p.add_argument("--rig", default="mock", metavar="mock|RIG.toml",
                   help="the simulated rig (default) or a rig profile (rig_drivers/PROFILES.md)")
    p.add_argument("--scene", default="drummer", metavar="NAME", help="mock rig: the scene in front of it "
                   "(default drummer)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="mock rig: seed of its hidden homography, timing and noise (default 0)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Carry out ``flexvox app``."""
    from rig_drivers.errors import SettingError
    from rig_drivers.profile import open_rig

    if args.recording is not None and not args.recording.exists():
        raise CliError(f"{args.recording}: no such recording")
    problem = missing_gui_extra() or display_problem()
    if problem is not None:
        raise CliError(problem)
    def opened():  # behind the start-up window, which shows at once
        return open_rig("mock", scene=args.scene, seed=args.seed) if args.rig == "mock" else open_rig(args.rig)

    from flexvox_app.gui.application import launch  # Qt is loaded only here

    try:
        return launch(opened, recording=args.recording)
    except SettingError as exc:
        raise CliError(str(exc)) from None


# --------------------------------------------------------------------------- the projector screen


def screen_index(text: str) -> int:
    """``--projector-screen``: a screen index, a whole number >= 0 (its range is checked against the desktop)."""
    if not text.isdigit():
        raise ValueError(f"--projector-screen must be a screen index, a whole number >= 0 (see --list-screens); "
                         f"got {text!r}")
    return int(text)


def add_screen_options(p) -> None:
    """``--projector-screen N`` and ``--list-screens`` (shared with ``flexvox capture``)."""
    p.add_argument("--projector-screen", type=arg_type(screen_index), metavar="N",
                   help="real rig: the screen that feeds the projector's video input (HDMI), by index; the "
                        "patterns are shown on it full-screen and pixel-exact while the command runs "
                        "(needs a desktop session; list the screens with --list-screens)")
    p.add_argument("--list-screens", action="store_true",
                   help="list the screens (index, name, size, position) and exit")


def list_screens() -> int:
    """Print the screens ``--projector-screen`` can name."""
    require_gui_extra()
    from flexvox_app.gui.projector.display import ScreenError, screen_lines

    try:
        lines = screen_lines()
    except ScreenError as exc:
        raise CliError(str(exc)) from None
    print("\n".join(lines))
    return EXIT_OK


def require_gui_extra() -> None:
    """Refuse (exit 2, one line naming the extra) when Qt, which the window needs, is not installed."""
    problem = missing_gui_extra()
    if problem is not None:
        raise CliError(problem)


def needs_screen(spec) -> bool:
    """True when the rig's projector takes its patterns on a video input (a DLPC350)."""
    return not spec.simulated and spec.projector.kind == "dlpc350"


def with_projector_screen(args, spec, work):
    """Run ``work(display, interrupted)`` as the rig needs: directly (no display) or with the patterns on a screen.

    The simulated rig takes no screen; a DLPC350 needs one (``--projector-screen``): a QApplication
    runs the event loop while ``work`` runs on a worker thread with the window's display sink.
    """
    if spec.simulated or not needs_screen(spec):
        if args.projector_screen is not None:
            raise CliError("--projector-screen is for a projector driven through its video input (a DLPC350); "
                           f"{'the simulated rig (--rig mock)' if spec.simulated else 'this rig'} needs none")
        return work(None, None)
    if args.projector_screen is None:
        raise CliError("the DLP LightCrafter 4500 takes its patterns on its video input: give --projector-screen N, "
                       "the screen its HDMI input is (list them with --list-screens)")
    require_gui_extra()
    from flexvox_app.gui.projector.display import ScreenError, run_with_projector_screen

    try:
        return run_with_projector_screen(args.projector_screen, work)
    except ScreenError as exc:
        raise CliError(str(exc)) from None
