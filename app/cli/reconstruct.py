"""``flexvox reconstruct``: a recording in, the full (S, H, W) video out."""

from __future__ import annotations

import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, CliError, arg_type, check_fps_output, defer, positive_fps
from flexvox_app.cli.method_options import (
    add_method_options,
    auto_knob,
    device_line,
    device_record,
    flag_of,
    method_from_args,
    resolved_device,
)

FIGURE_EXTRAS = ("flow", "tr")
"""What ``--figures`` draws: a method must return these extras."""


class _Abandoned(Exception):
    """The PSNR's reader gives up: the output's write failed or was interrupted."""


def register(sub) -> None:
    """Add the ``reconstruct`` subcommand."""
    p = sub.add_parser("reconstruct", help="reconstruct the high-speed video of a recording")
    p.add_argument("recording", type=Path, metavar="REC", help="a flexvox recording (.zarr)")

    def fill(p) -> None:  # the methods' options and the output formats: imported only when this command is used
        from flexvox_core.video_io import WRITABLE

        p.description = (
            "Reconstruct the full (S, H, W) float32 video in [0, 1] (S = F*K) of a recording and "
            f"write it to OUT ({', '.join(WRITABLE)}). Methods: rebin (re-binning at a division), "
            "diffusion (constant tensor; the default nc solver is the fast normalized convolution), "
            "gap-tv (the classical peer), motion-aware (the paper's Section 4: diffusion tensors oriented "
            "along optical flow). Multiplexed recordings are demultiplexed first. Dropped camera frames are "
            "bridged from both sides (a line says which sub-frames; a .zarr output keeps them as the array "
            "`interpolated`); a run of them longer than the method's reach is refused, naming it. "
            "--time auto (diffusion, motion-aware) and --block auto (rebin) choose the knob by the PSNR estimated "
            "from the recording alone: each candidate is reconstructed and estimated, the best is written, and every "
            "candidate's estimate and what choosing cost are printed; a candidate the estimate refuses is listed with "
            "the reason and never chosen (rebin: every division but the code's default), and a method it refuses "
            "(today motion-aware, and diffusion's explicit and steady solvers) is refused with the reason."
        )
        add_method_options(p, chunk=16, auto=True)
        p.add_argument("--figures", type=Path, metavar="DIR",
                       help="motion-aware: write flow (colour wheel, quiver), resolution map and a panel "
                            "like the paper's Figs. 7-8 as PNGs")
        p.add_argument("--fps", type=arg_type(positive_fps),
                       help="playback rate of an .mp4 output (default 30; refused with any other output)")
        p.add_argument("--estimate", action="store_true",
                       help="also estimate the result's PSNR from the recording alone (no ground truth: each probed "
                            "sample predicted without itself; one more reconstruction) and print "
                            "'estimated PSNR NN.NN dB (± ...)'; methods it cannot estimate say why")
        p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT", help="output file")
        p.add_argument("--overwrite", action="store_true",
                       help="replace an existing output (never the input recording; the old output stays until the "
                            "new one is complete)")

    defer(p, fill)
    p.set_defaults(func=run)


def interpolated_line(gaps, K: int) -> str:
    """The line that says which sub-frames were filled across dropped frames."""
    n = sum(g.frames for g in gaps) * K
    return f"interpolated {n} sub-frames across dropped frames: " + ", ".join(g.describe(K) for g in gaps)


def psnr_words(per_frame) -> str:
    """The mean PSNR of the sub-frames ("26.04 dB"); sub-frames equal to the truth (an infinite PSNR) are
    counted apart instead of making the mean infinite ("exact on 3 of 48 sub-frames, 21.50 dB over the rest")."""
    import numpy as np

    per = np.asarray(per_frame, np.float64)
    exact = np.isinf(per) & (per > 0)
    if not exact.any():
        return f"{float(np.mean(per)):.2f} dB"
    if exact.all():
        return f"exact on all {per.size} sub-frames"
    return f"exact on {int(exact.sum())} of {per.size} sub-frames, {float(np.mean(per[~exact])):.2f} dB over the rest"


def estimate_line(recording, method, video, chunk: int | None, device: str) -> str:
    """``estimated PSNR NN.NN dB (± ...)`` of ``video``, ``method``'s reconstruction of ``recording``
    (:func:`flexvox_core.accuracy.estimate_recording`; None: reconstructed again), or why there is none."""
    from flexvox_core.accuracy import NotEstimable, estimate_recording

    t0 = time.perf_counter()
    try:
        est = estimate_recording(recording, method, reconstruction=video, chunk_frames=chunk, device=device)
    except NotEstimable as exc:
        return f"estimated PSNR: none ({exc})"
    return f"{est.line()} in {time.perf_counter() - t0:.2f} s"


def _choose(reader, method, knob: str, args, device: str):
    """``knob`` of ``method`` chosen by the estimated PSNR on the recording
    (:func:`flexvox_core.choice.choose_recording`); a refusal is a :class:`CliError` naming the method and why."""
    from tqdm import tqdm

    from flexvox_core.accuracy import NotEstimable
    from flexvox_core.choice import choose_recording
    from flexvox_core.recording import RecordingError

    bars = []  # the bar starts with the first candidate's result: a refusal comes before it

    def progress(done, total):
        if not bars:
            bars.append(tqdm(total=total, unit="candidate", desc=f"choosing {knob}", leave=False))
        bars[0].update(done - bars[0].n)

    try:
        return choose_recording(reader.recording, method, knob, chunk_frames=args.chunk, device=device,
                                progress=progress)
    except NotEstimable as exc:
        raise CliError(f"{flag_of(knob)} auto: {exc}") from None
    except (ValueError, RecordingError) as exc:
        raise CliError(str(exc)) from None
    finally:
        for bar in bars:
            bar.close()


def run(args) -> int:
    """Carry out ``flexvox reconstruct``."""
    from tqdm import tqdm

    from flexvox_core.capture_reader import open_capture
    from flexvox_core.methods import specs
    from flexvox_core.output_files import CLI_OVERWRITE_HINT, check_output, is_recording
    from flexvox_core.recording import RecordingError
    from flexvox_core.video_io import WRITABLE, check_mp4_size, write_video

    try:
        if args.output.suffix.lower() not in WRITABLE:
            raise ValueError(f"-o {args.output}: the output must end in {', '.join(WRITABLE)}")
        check_fps_output(args.fps, args.output)
        if args.recording.is_dir() and not is_recording(args.recording):  # `.`: said for what it is, not as the
            open_capture(args.recording)  # folder the output would lie in (its refusal names what the folder is)
        check_output(args.output, overwrite=args.overwrite, inputs=[args.recording], hint=CLI_OVERWRITE_HINT)
        if args.figures is not None:
            from flexvox_app.figures import check_figures_dir

            check_figures_dir(args.figures, overwrite=args.overwrite, inputs=[args.recording])
        reader = open_capture(args.recording)
        rec = reader.recording
        if args.output.suffix.lower() == ".mp4":  # refused before the reconstruction, not after it
            check_mp4_size(reader.shape, args.output)
        knob = auto_knob(args)
        method = method_from_args(args, rec.attrs["tile"], auto=True)
        device = resolved_device(args)
        if args.figures and not set(FIGURE_EXTRAS) <= set(method.spec.extras):
            drawable = " or ".join(s.name for s in specs() if set(FIGURE_EXTRAS) <= set(s.extras))
            raise ValueError(f"--figures goes with --method {drawable} (the methods that return the flow)")
    except (ValueError, RecordingError) as exc:
        raise CliError(str(exc)) from None
    F, (H, W) = reader.n_frames, reader.shape
    choice = None
    if knob is not None:
        choice = _choose(reader, method, knob, args, device)
        method = choice.method
        for line in choice.lines():
            print(line)
    t0 = time.perf_counter()
    if choice is not None and choice.output is not None:
        out = choice.output  # made while choosing: not run again
        seconds = next(c.run_seconds for c in choice.candidates if c.value == choice.value)
    else:
        with tqdm(total=F, unit="frame", desc=method.label(), disable=F <= args.chunk, leave=False) as bar:
            def progress(done, total):
                bar.update(done - bar.n)
            try:
                out = reader.run(method, chunk_frames=args.chunk, progress=progress, device=device)
            except (ValueError, RecordingError) as exc:
                raise CliError(str(exc)) from None
        seconds = time.perf_counter() - t0  # the reconstruction itself (reading the ground truth is not)
    video = out.video
    attrs = {"source": str(args.recording), "method": method.as_dict(), "seconds": seconds, **device_record(out)}
    if choice is not None:
        attrs["chosen_by_estimate"] = {
            "knob": choice.knob, "seconds": choice.seconds, "reconstructions": choice.runs,
            "candidates": [{"method": c.method.as_dict(), "seconds": c.seconds, "why": c.why,
                            "estimate": None if c.estimate is None else c.estimate.as_dict()}
                           for c in choice.candidates]}
    score = None
    stop = threading.Event()  # set when the write fails or is interrupted: the PSNR gives up at its next block
    pool = ThreadPoolExecutor(max_workers=1)
    try:
        if rec.has_ground_truth:
            from flexvox_core.metrics import psnr_of_rows

            def truth(a, b):
                if stop.is_set():
                    raise _Abandoned
                return rec.ground_truth[a:b]

            # While the output is written (compression and files on one core, the truth's decompression, checks
            # and the PSNR on the other), a few sub-frames at a time, each checked as it is read: the truth is
            # never held whole.
            score = pool.submit(psnr_of_rows, truth, video)
        try:
            write_video(args.output, video, fps=args.fps or 30.0, attrs=attrs, overwrite=args.overwrite,
                        time_step=1.0 / rec.attrs["rates"]["subframe_hz"], interpolated=out.interpolated)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        except OSError as exc:
            raise CliError(f"cannot write {args.output}: {exc.strerror or exc}; nothing was replaced") from None
    except BaseException:
        stop.set()
        raise
    finally:
        pool.shutdown(wait=True)
    line = f"{method.label()}: {video.shape[0]} sub-frames of {H}x{W} in {seconds:.2f} s"
    line += f" ({voxel_rate(video.size, seconds)})"
    if score is not None:
        try:
            scores = score.result()
            line += f"; PSNR vs ground truth {psnr_words(scores.per_frame)}"
            if args.estimate:  # beside the estimate: the PSNR it estimates, of the clip's mean squared error
                line += f" (of the clip's MSE, as estimated: {scores.clip:.2f} dB)"
        except (RecordingError, ValueError) as exc:  # the video is written: a bad truth costs only its PSNR
            print(f"warning: no PSNR: {exc}", file=sys.stderr)
    print(line)
    if args.estimate and choice is not None:
        print(choice.estimate.line() + " (made while choosing)")
    elif args.estimate:
        print(estimate_line(args.recording, method, video if reader.multiplexed is None else None, args.chunk,
                            device))
    print(device_line(out))
    if reader.missing is not None:
        print(interpolated_line(reader.gaps(), reader.K))
    print(f"wrote {args.output}")
    if args.figures:
        from flexvox_app.figures import write_figures

        written = write_figures(args.figures, *reader.input(method), method, missing=reader.missing)
        print(f"wrote {len(written)} figures to {args.figures}")
    return EXIT_OK


def voxel_rate(voxels: int, seconds: float) -> str:
    """``voxels`` made in ``seconds`` in words: "74 M voxels/s", two figures below ten ("0.028 M voxels/s")."""
    rate = voxels / max(seconds, 1e-9) / 1e6
    return f"{rate:.0f} M voxels/s" if rate >= 10 else f"{rate:.2g} M voxels/s"
