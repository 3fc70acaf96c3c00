"""``flexvox clean``: what killed writers left in a folder, and removing it on request."""

from __future__ import annotations

from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, CliError


def register(sub) -> None:
    """Add the ``clean`` subcommand."""
    p = sub.add_parser(
        "clean",
        help="list (and with --remove delete) what killed writes left in a folder",
        description=(
            "Every output is written beside its place and renamed into place when complete; a write that is "
            "killed (SIGKILL, a power cut) leaves its hidden partial output (.NAME.partial-PID-XXXX.SUFFIX), "
            "perhaps the earlier output it was replacing (.NAME.replaced-PID-XXXX.SUFFIX) and its lock file "
            "(.NAME.lock). This lists them with whether their writer still runs; --remove deletes those whose "
            "writer no longer runs. One whose writer runs is never touched, nor an earlier output that is now its "
            "only copy: its output is missing, or is a recording that holds no frame (a capture with --overwrite "
            "killed before its first frame; flexvox info --repair puts the earlier one back). The next write to "
            "the same output also removes a killed writer's partial output and says so."
        ),
    )
    p.add_argument("folder", type=Path, nargs="?", default=Path("."), metavar="FOLDER",
                   help="the folder to look in (default: the current one)")
    p.add_argument("--remove", action="store_true", help="delete the leftovers whose writer no longer runs")
    p.set_defaults(func=run)


def run(args) -> int:
    """Carry out ``flexvox clean``."""
    from flexvox_core.leftovers import find_leftovers
    from flexvox_core.output_files import remove_path

    folder = args.folder
    if not folder.is_dir():
        raise CliError(f"{folder}: {'not a folder' if folder.exists() else 'no such folder'}; flexvox clean looks "
                       "in a folder")
    found = find_leftovers(folder)
    if not found:
        print(f"{folder}: no leftovers of unfinished writes")
        return EXIT_OK
    removable = 0
    for item in found:
        if item.writer is not None:
            state = f"kept: its writer runs ({item.writer})"
        elif not item.removable:
            state = "kept"
        elif args.remove:
            remove_path(item.path)
            state = "removed"
        else:
            state = "its writer no longer runs"
        removable += item.removable
        print(f"{item.path.name}: {item.why}; {state}")
    if removable and not args.remove:
        print(f"{removable} of {len(found)} can go: flexvox clean {folder} --remove")
    elif args.remove:
        print(f"removed {removable} of {len(found)}")
    return EXIT_OK
