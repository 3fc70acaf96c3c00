"""``flexvox capture``: headless capture from a rig into a crash-safe recording.

``python -m flexvox_app.cli.capture ...`` runs the same command on its own (the crash-safety test
kills such a process).
"""

from __future__ import annotations

import re
import signal
import sys
import threading
import time
from pathlib import Path

from flexvox_app.cli.app import add_screen_options, list_screens, with_projector_screen
from flexvox_app.cli.errors import EXIT_FAILED, EXIT_OK, CliError, OneLineParser, arg_type, defer
from flexvox_core.tiles import parse_tile

_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


PROGRESS_EVERY_S = 0.25
"""The counters are printed this often on a terminal (every 2 s when stderr is a file or a pipe)."""
GROUND_TRUTH_RATE = 500.0
"""Sub-frames per second the simulated ground truth is written at, at least (about 1330 at 120x160 here)."""


def stop_timeout(rows: int, K: int, ground_truth: bool) -> float:
    """Seconds a stopped capture may take to finish: 30 for the writer, and with ``--ground-truth`` the time to
    write the truth of its ``rows`` frames (K sub-frames each), which the capture writes whole as it finishes."""
    return 30.0 + (rows * K / GROUND_TRUTH_RATE if ground_truth else 0.0)


def _size(text: str) -> tuple[int, int]:
    match = _SIZE_RE.match(text)
    if match is None or min(int(match.group(1)), int(match.group(2))) < 8:
        raise ValueError(f"a size must be HxW with H, W >= 8 (e.g. 120x160); got {text!r}")
    return int(match.group(1)), int(match.group(2))


def register(sub) -> None:
    """Add the ``capture`` subcommand."""
    p = sub.add_parser(
        "capture",
        help="capture coded frames from the rig into a recording (headless)",
        description=(
            "Set up the projector's patterns for a code, the sync box and the camera, and record N "
            "frames (or until Ctrl-C) into a Zarr recording, printing progress and counters (frames, "
            "drops, queue depth, write rate). The recording is crash-safe: a capture killed at any "
            "moment leaves every frame it wrote readable. The code is a tile's designed code (--tile), "
            "its S-matrix multiplexed code (--multiplexed) or a `flexvox design -o` file (--code). "
            "--calibration CAL.json (from `flexvox calibrate -o`) gives the projector-camera homography, "
            "the phase and the camera trigger delay that goes with it; without it the patterns assume an "
            "identity map and phase 0, which a real rig (and the simulated one) does not have. "
            "--rig mock is the simulated rig (a projector finer than the camera behind a hidden homography, "
            "a trigger offset that is not a whole slot; calibrate it as a real one); --rig FILE.toml drives "
            "real devices (see `flexvox devices`); a DLPC350 takes its patterns on its video input, shown on "
            "--projector-screen N while the capture runs. Exit 0 when the capture ends normally, 1 when it "
            "stopped on an error (a full disk, a camera unplugged: the recording still holds what was captured)."
        ),
    )
    p.add_argument("--rig", default="mock", metavar="mock|RIG.toml", help="the rig (default mock)")
    p.add_argument("--frames", type=int, metavar="N", help="frames to record (default: until Ctrl-C)")
    p.add_argument("-o", "--output", type=Path, metavar="REC.zarr", help="recording to write (required)")
    code = p.add_mutually_exclusive_group()
    code.add_argument("--tile", type=arg_type(parse_tile), metavar="MxN",
                      help="tile of the designed code (default 4x4)")
    code.add_argument("--code", type=Path, metavar="CODE.json",
                      help="a code written by `flexvox design -o` (identity or multiplexed) instead of --tile's")
    p.add_argument("--multiplexed", action="store_true",
                   help="the tile's S-matrix multiplexed code (K = 3, 7, 15, ...: e.g. --tile 3x5)")
    p.add_argument("--calibration", type=Path, metavar="CAL.json",
                   help="a calibration from `flexvox calibrate -o` made on this rig: its homography, and the phase "
                        "and camera trigger delay of its synchronisation, drive the capture (refused when made for "
                        "another rig or resolution)")
    p.add_argument("--sync-profile", type=Path, metavar="SYNC.json",
                   help="a sync profile saved by the synchronisation wizard: its phase and trigger delay replace "
                        "the calibration's")
    p.add_argument("--delay-set-by-hand", action="store_true",
                   help="the camera cannot be told a trigger delay, and you have set the calibration's delay on it "
                        "another way (its vendor's tool)")
    p.add_argument("--rate", type=float, default=15.0, metavar="HZ", help="camera frame rate (default 15)")
    scene = p.add_argument("--scene", default="drummer", metavar="NAME", help="mock rig: built-in scene")

    def name_the_scenes(p) -> None:  # the scenes' module: imported only when this command is used
        from flexvox_core.simulate.scenes import SCENES

        scene.help = f"mock rig: built-in scene ({', '.join(SCENES)}; default drummer)"

    defer(p, name_the_scenes)
    p.add_argument("--size", type=arg_type(_size), metavar="HxW",
                   help="mock rig: camera size (default 120x160; the projector is twice as fine)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="mock rig: seed of its hidden homography, timing and noise (default 0, as flexvox calibrate)")
    p.add_argument("--ground-truth", action="store_true",
                   help="mock rig: store the scene's high-speed video as the recording's ground truth")
    p.add_argument("--clock", choices=("real", "virtual"), default="real",
                   help="mock rig: real time at the camera rate (default; a paced simulated clock), or "
                        "virtual time that runs as fast as frames can be rendered (demos, tests)")
    p.add_argument("--projector-size", type=arg_type(_size), metavar="HxW",
                   help="projector resolution, when it is not the one its driver reports (a DLPC350: 1140x912)")
    p.add_argument("--queue", type=int, default=64, metavar="FRAMES",
                   help="frames the camera-to-disk queue holds (default 64)")
    p.add_argument("--block", type=float, default=0.5, metavar="S",
                   help="seconds the camera reader waits for queue room before it discards a frame "
                        "(recorded as dropped; default 0.5)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing recording (never one another capture is writing; the old one is "
                        "deleted once the new one closes with frames)")
    p.add_argument("--durable", action="store_true",
                   help="flush every frame's chunk and journal record to the disk before the next frame: a power "
                        "cut loses at most the frame in flight (slower; see docs/recording-format.md)")
    add_screen_options(p)
    p.set_defaults(func=run)


def _plan(args):
    """The capture plan the code options describe."""
    from flexvox_app.capture import CapturePlan

    if not 0 < args.rate <= 10_000:
        raise ValueError(f"--rate must be a camera rate above 0 and at most 10000 Hz; got {args.rate:g}")
    if args.code is not None:
        if args.multiplexed:
            raise ValueError("--multiplexed goes with --tile; a --code file says itself whether it is multiplexed")
        return CapturePlan.from_code_file(args.code, camera_hz=args.rate)
    return CapturePlan(tile=tuple(args.tile or (4, 4)), multiplexed=args.multiplexed, camera_hz=args.rate)


def _build(args, display=None):
    from flexvox_app.capture import CaptureService, QueuePolicy, SyncSetting
    from flexvox_app.capture.pacing import PacedClock
    from flexvox_app.capture.service import warnings_shown_by_caller
    from flexvox_app.capture.sink import check_output
    from flexvox_core.output_errors import CLI_OVERWRITE_HINT
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    if args.frames is not None and args.frames < 1:
        raise ValueError(f"--frames must be >= 1; got {args.frames}")
    rig_file = None if args.rig == "mock" else Path(args.rig)
    check_output(args.output, overwrite=args.overwrite,  # before the rig is built (a scene renders for seconds)
                 inputs=[args.code, args.calibration, args.sync_profile, rig_file], hint=CLI_OVERWRITE_HINT)
    plan = _plan(args)
    plan.code  # noqa: B018 - refuse an impossible code before any device is opened
    if args.rig == "mock":
        from rig_drivers.simulated_rig import DEFAULT_CAMERA_SIZE
        from rig_drivers.simulated_target import PROJECTOR_SCALE

        args.size = tuple(args.size or DEFAULT_CAMERA_SIZE)
        mock_projector = tuple(PROJECTOR_SCALE * v for v in args.size)
        if args.projector_size is not None and tuple(args.projector_size) != mock_projector:
            raise ValueError(f"--projector-size {args.projector_size[0]}x{args.projector_size[1]}: the simulated "
                             f"rig's projector is {mock_projector[0]}x{mock_projector[1]} ({PROJECTOR_SCALE}x --size); "
                             "--projector-size is for a real projector whose driver reports another size")
        rig = open_rig("mock", scene=args.scene, camera_size=args.size, seed=args.seed,
                       clock=VirtualClock() if args.clock == "virtual" else PacedClock())
    else:
        if args.ground_truth:
            raise ValueError("--ground-truth goes with --rig mock (a real scene has no ground truth)")
        rig = open_rig(args.rig, projector_display=display)
    calibration = _calibration(args, rig)
    with warnings_shown_by_caller():  # _follow prints them as `warning:` lines
        service = CaptureService(
            rig, plan, args.output, frames=args.frames, calibration=calibration,
            sync=SyncSetting(delay_set_by_hand=args.delay_set_by_hand),
            queue_policy=QueuePolicy(capacity=args.queue, block_s=args.block),
            projector_size=args.projector_size, ground_truth=args.ground_truth, overwrite=args.overwrite,
            durable=args.durable, rig_info={"profile": args.rig}, progress_every_s=PROGRESS_EVERY_S)
    return service


def _calibration(args, rig):
    """The capture calibration from ``--calibration`` / ``--sync-profile`` (the one loader)."""
    from flexvox_calibration.capture_setup import load_for_capture, load_sync_for_capture
    from flexvox_calibration.session import RigSession

    if args.calibration is None and args.sync_profile is None:
        return None
    identity = RigSession.from_rig(rig, projector_size=args.projector_size).identity
    calibration = None
    if args.calibration is not None:
        try:
            calibration = load_for_capture(args.calibration, identity)
        except ValueError as exc:
            from flexvox_calibration.errors import CalibrationMismatchError
            from rig_drivers.simulated_rig import DEFAULT_CAMERA_SIZE

            mismatch = isinstance(exc, CalibrationMismatchError) or isinstance(exc.__cause__, CalibrationMismatchError)
            if args.rig == "mock" and tuple(args.size) != DEFAULT_CAMERA_SIZE and mismatch:
                # neither `flexvox calibrate` nor `flexvox app` sizes the simulated rig: say how to go on instead
                h, w = DEFAULT_CAMERA_SIZE
                raise type(exc)(f"{exc}; the simulated rig is calibrated at its default {h}x{w} camera only (flexvox "
                                f"calibrate and flexvox app have no --size): capture at {h}x{w}, or leave out "
                                "--calibration") from None
            raise
    if args.sync_profile is not None:
        calibration = load_sync_for_capture(args.sync_profile, identity, base=calibration)
    return calibration


def _counters(s) -> str:
    return (f"{s.rows_written} written, {s.drops} dropped, queue {s.queue_depth}/{s.queue_capacity}, "
            f"write {s.write_rate_hz:.1f} Hz, camera {s.camera_rate_hz:.1f} Hz")


class _ProgressLines:
    """The counters on stderr as the capture's ``progress`` events arrive: every event on a terminal (one line
    rewritten), every ``2 s`` otherwise; nothing once :meth:`close` ran (the end is printed by the caller)."""

    def __init__(self, interactive: bool):
        self.interactive = interactive
        self._every_s = PROGRESS_EVERY_S if interactive else 2.0
        self._last = 0.0
        self._closed = False
        self._lock = threading.Lock()

    def __call__(self, stats) -> None:
        with self._lock:
            now = time.monotonic()
            if self._closed or stats.state == "done" or now - self._last < self._every_s:
                return
            self._last = now
            if self.interactive:
                print(f"\r{_counters(stats)}   ", end="", file=sys.stderr, flush=True)
            else:
                print(_counters(stats), file=sys.stderr, flush=True)

    def close(self) -> None:
        """Print no more lines."""
        with self._lock:
            self._closed = True


def run(args) -> int:
    """Carry out ``flexvox capture``."""
    from rig_drivers.profile import resolve_rig

    if args.list_screens:
        return list_screens()
    if args.output is None:
        raise CliError("the following arguments are required: -o/--output")
    try:
        spec = resolve_rig(args.rig)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    return with_projector_screen(args, spec, lambda display, interrupted: _capture(args, display, interrupted))


class StopRequests:
    """Ctrl-C (SIGINT) and SIGTERM, noted instead of raised, while a capture runs (a context manager).

    Python raises KeyboardInterrupt in the main thread wherever it happens to be. Raised between a lock's
    acquisition and the ``try`` that releases it (inside ``threading.Event.wait``, say), it leaves that lock held,
    and the capture's own end (``Event.set``) and ``stop()`` then wait on it for ever. Here the handler only counts
    (no lock, no exception); the capture's loop reads :attr:`count` between its waits. The previous handlers come
    back on exit. Outside the main thread (a projector screen's worker) signals cannot be handled: nothing changes.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.count = 0
        self._previous: dict = {}

    def _note(self, signum, frame) -> None:
        self.count += 1

    def __enter__(self) -> StopRequests:
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._previous[sig] = signal.signal(sig, self._note)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()


def _capture(args, display=None, interrupted=None) -> int:
    """Build, start and follow the capture; ``interrupted`` (an Event) stops it like Ctrl-C."""
    from flexvox_app.capture import CaptureError
    from rig_drivers.errors import DeviceError

    try:
        service = _build(args, display)
    except (ValueError, CaptureError, DeviceError) as exc:
        raise CliError(str(exc)) from None
    with StopRequests() as requests:  # from here Ctrl-C stops the capture and keeps what was captured
        try:
            service.start()
        except (ValueError, CaptureError, DeviceError) as exc:
            raise CliError(str(exc)) from None
        return _follow(args, service, requests, interrupted)


def _follow(args, service, requests: StopRequests, interrupted=None) -> int:
    """Report a started capture until it ends or is stopped (``requests``, ``interrupted``); stop it; its result."""
    print(f"capturing to {args.output} at {1 / service.frame_period_s:.3f} Hz"
          f"{'' if args.frames is None else f', {args.frames} frames'} (Ctrl-C stops and keeps what was captured)",
          flush=True)
    setup = service.setup
    delay = (f"a {setup.trigger_delay_us:.0f} µs camera trigger delay (set by the {setup.delay_by})"
             if setup.trigger_delay_us > 0 else "no camera trigger delay")
    print(f"code: {service.plan.code_summary()}", flush=True)
    print(f"calibration: {service.calibration.describe()}", flush=True)
    print(f"recording with phase {setup.phase_slots} and {delay}", flush=True)
    for warning in service.warnings:
        print(f"warning: {warning}", file=sys.stderr, flush=True)
    interactive = sys.stderr.isatty()
    lines = _ProgressLines(interactive)
    service.events.progress.connect(lines)
    while not service.wait(0.25):  # the end, or Ctrl-C
        if requests.count or (interrupted is not None and interrupted.is_set()):
            lines.close()
            print("\nstopping...", file=sys.stderr, flush=True)
            break
    lines.close()
    rows = service.stats().rows_written
    timeout = stop_timeout(rows, service.K, args.ground_truth)
    if args.ground_truth and not service.wait(0):
        print(f"writing the simulated ground truth of {rows} frame(s) (up to {timeout:.0f} s)...", file=sys.stderr,
              flush=True)
    result = service.stop(timeout_s=timeout)
    if interactive:
        print(file=sys.stderr)
    if result is None:
        print(f"flexvox capture: error: the capture did not stop within {timeout:.0f} s; {args.output} keeps what "
              "was written (check it with `flexvox info`)", file=sys.stderr)
        return EXIT_FAILED
    print(_counters(result.stats))
    if not result.ok:
        print(f"flexvox capture: error: {result.message}", file=sys.stderr)
        return EXIT_FAILED
    print(result.message)
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Run ``capture`` alone (``python -m flexvox_app.cli.capture ...``)."""
    import logging

    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    register(sub)
    args = parser.parse_args(["capture", *(sys.argv[1:] if argv is None else argv)])
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    # SIGTERM stops like Ctrl-C (keeps what was captured).
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        return run(args)
    except CliError as exc:
        print(f"flexvox capture: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover - run as a process by the crash-safety test
    sys.exit(main())
