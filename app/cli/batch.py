"""``flexvox batch``: reconstruct a long recording chunk by chunk with dask, into Zarr."""

from __future__ import annotations

from pathlib import Path

from flexvox_app.cli.errors import EXIT_OK, CliError, defer


def register(sub) -> None:
    """Add the ``batch`` subcommand."""
    from flexvox_app.cli.export import add_pyramid_option
    from flexvox_app.cli.method_options import add_method_options

    p = sub.add_parser(
        "batch",
        help="reconstruct a long recording chunk by chunk with dask (local or a dask.distributed cluster)",
        description=(
            "Reconstruct a recording in time chunks with the overlap the method needs "
            "(dask.array.map_overlap), writing the (F*K, H, W) float32 video to an OME-Zarr image chunk by "
            "chunk (array `video`, the sub-frame period as its time step): memory depends on --chunk, not on "
            "the recording's length, and the "
            "result equals `flexvox reconstruct`'s. Runs on dask's local threads, or on a "
            "dask.distributed cluster with --scheduler (its workers must see REC and OUT)."
        ),
    )
    p.add_argument("recording", type=Path, metavar="REC", help="a flexvox recording (.zarr)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT.zarr",
                   help="OME-Zarr store (NGFF 0.5) to write")
    p.add_argument("--scheduler", metavar="ADDRESS", help="dask.distributed scheduler, e.g. tcp://host:8786")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing output (never the input; the old output stays until every chunk of "
                        "the new one is written)")
    add_pyramid_option(p)
    defer(p, lambda p: add_method_options(p, chunk=32))  # the methods' registry: only when this command is used
    p.set_defaults(func=run)


def run(args) -> int:
    """Carry out ``flexvox batch``."""
    from tqdm import tqdm

    from flexvox_app.cli.method_options import device_line, method_from_args, resolved_device
    from flexvox_core.batch import reconstruct_batch
    from flexvox_core.output_files import CLI_OVERWRITE_HINT, check_output
    from flexvox_core.recording import RecordingError, open_recording

    try:
        if args.output.suffix.lower() == ".zarr":  # reconstruct_batch names any other suffix
            check_output(args.output, overwrite=args.overwrite, inputs=[args.recording], hint=CLI_OVERWRITE_HINT)
        rec = open_recording(args.recording)
        method = method_from_args(args, rec.attrs["tile"])
        device = resolved_device(args)
    except (ValueError, RecordingError) as exc:
        raise CliError(str(exc)) from None
    with tqdm(unit="chunk", desc=method.label(), leave=False, disable=True if args.scheduler else None) as bar:
        def progress(done, total):
            bar.total = total
            bar.update(done - bar.n)
        try:
            result = reconstruct_batch(args.recording, args.output, method, chunk_frames=args.chunk,
                                       scheduler=args.scheduler, overwrite=args.overwrite, progress=progress,
                                       pyramid=args.pyramid, device=device)
        except (ValueError, OSError, TimeoutError) as exc:
            raise CliError(str(exc)) from None
    S, H, W = result.shape
    print(f"{method.label()}: {S} sub-frames of {H}x{W} in {result.seconds:.2f} s on {result.scheduler} "
          f"(chunks of {result.chunk_frames} frames, overlap {result.overlap_frames})")
    print(device_line(result))
    dropped = rec.per_frame("dropped")
    if dropped.any():
        from flexvox_app.cli.reconstruct import interpolated_line
        from flexvox_core.gaps import find_gaps

        print(interpolated_line(find_gaps(dropped), S // len(dropped)))
    print(f"wrote {args.output}")
    return EXIT_OK
