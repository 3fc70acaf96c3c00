"""``flexvox export``: a recording's frames, ground truth or reconstruction, or a reconstructed video
(the OME-Zarr image ``reconstruct``/``batch -o OUT.zarr`` write), to common files.

Formats, by the output's suffix:

``.tif`` / ``.tiff``
    One ImageJ hyperstack (tifffile, axes TYX) that Fiji opens as a stack with time in seconds
    (``finterval``: one camera frame, or one sub-frame for ground truth and reconstructions;
    ``tunit`` sec): raw frames keep their type (uint16 counts or float32); ground truth and
    reconstructions are float32 in [0, 1].
``.npy``
    The same array (written row by row into a memory-mapped file).
``.mp4``
    8-bit grey (OpenCV), values in [0, 1] at ``--fps``; height and width even and at least 16 px (refused
    otherwise, before any reconstruction).
``.zarr``
    An OME-Zarr image (NGFF 0.5 on Zarr v3) with array ``video`` (float32 in [0, 1]) and the time
    step as its t scale, as ``flexvox reconstruct`` writes; ``--pyramid N`` adds N levels of 2×2 means.
no suffix
    A folder of 16-bit PNGs ``frame_00000.png`` ...: uint16 counts as they are, float
    values in [0, 1] scaled to 0..65535. ``--overwrite`` replaces only a folder that holds
    nothing but an earlier export's PNGs.

Camera frames in [0, 1] (.mp4, .zarr, float PNGs): counts normalised to relative units first, then divided by
the slots a pixel is open in each exposure (a multiplexed code's (K + 1)/2: its frames sum that many sub-frames;
1 for an identity code), then clipped to [0, 1]. A share of values clipped (ambient light, leakage, saturation)
is said on stderr; .tif and .npy keep the frames as they are.

Every output is written to a hidden temporary sibling and moved into place when complete; an
output that is (or holds, or lies inside) the input is refused, whatever the flags.

A reconstructed video's store as input exports its video as it is: ``--what`` may only be ``reconstruction`` (it
holds no camera frames) and the method options are refused (it is reconstructed already); its time step, method
and interpolated sub-frames go with it where the format keeps them.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from flexvox_app.cli.errors import EXIT_OK, CliError, arg_type, check_fps_output, defer, positive_fps
from flexvox_app.cli.method_options import (
    add_method_options,
    device_line,
    device_record,
    method_flags_given,
    method_from_args,
    resolved_device,
)

if TYPE_CHECKING:  # numpy and the recordings are imported where the export runs: parsing needs neither
    import numpy as np

WHAT = ("frames", "ground-truth", "reconstruction")
_PNG_NAME = re.compile(r"frame_\d{5,}\.png")
FORMATS = (".tif", ".tiff", ".npy", ".mp4", ".zarr", "(folder: PNG)")


def register(sub) -> None:
    """Add the ``export`` subcommand."""
    p = sub.add_parser(
        "export",
        help="export frames, ground truth or a reconstruction to TIFF (Fiji), MP4, PNG or .npy",
        description=(
            "Write a recording's camera frames, its ground truth (simulated recordings) or its "
            "reconstruction to OUT, by OUT's suffix: .tif/.tiff (an ImageJ hyperstack Fiji opens), "
            ".npy, .mp4 (8-bit), .zarr (an OME-Zarr image), or no suffix for a folder of 16-bit PNGs. The TIFF "
            "and the OME-Zarr image carry the time step in seconds. REC may also be a reconstructed video "
            "(the .zarr `flexvox reconstruct` or `flexvox batch` wrote): its video is written as it is. Long "
            "recordings: `flexvox batch` reconstructs chunk by chunk with dask."
        ),
    )
    p.add_argument("recording", type=Path, metavar="REC",
                   help="a flexvox recording (.zarr), or a reconstructed video (.zarr)")
    p.add_argument("--what", choices=WHAT, default=None,
                   help="what to export (default frames; a reconstructed video: its video, reconstruction)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="OUT", help="output file or folder")
    p.add_argument("--fps", type=arg_type(positive_fps),
                   help="MP4 playback rate (default: the camera rate for frames, else 30; refused with any other "
                        "output)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing output (never the input; a folder only when it holds nothing but an "
                        "earlier export's PNGs; the old output stays until the new one is complete)")
    add_pyramid_option(p)
    defer(p, _method_options)  # the methods' registry: only when this command is used
    p.set_defaults(func=run)


def _method_options(p) -> None:
    add_method_options(p, chunk=16)
    p.set_defaults(method=None)  # None: not given (a reconstruction then takes the default method)


def pyramid_levels(text: str) -> int:
    """``--pyramid``: a whole number of levels >= 0 (checked against the image size when it is known)."""
    if not text.isdigit():
        raise ValueError(f"--pyramid must be a whole number of levels >= 0; got {text!r}")
    return int(text)


def add_pyramid_option(p) -> None:
    """``--pyramid N`` (shared with ``flexvox batch``)."""
    p.add_argument("--pyramid", type=arg_type(pyramid_levels), default=0, metavar="N",
                   help=".zarr output: N pyramid levels below full resolution, each the 2x2 mean of the one above "
                        "(OME-Zarr multiscales, for viewers that zoom out; default 0: none)")


class _Source:
    """Rows to export: ``count`` rows of ``(H, W)``, raw (``row``) and in [0, 1] (``unit``)."""

    def __init__(self, rec, what: str, args):
        import numpy as np

        self.rec = rec
        self.what = what
        self.interpolated = None
        """(S,) bool for a reconstruction: the sub-frames filled across dropped frames."""
        self.attrs = {"source": str(rec.path), "what": what}
        self.gaps_line = ""
        self.device_line = ""
        self.divisor = 1
        """Camera frames in [0, 1] are divided by this: the slots a pixel is open in each exposure."""
        self.clipped = [0, 0]
        """Of the values :meth:`unit` gave: (outside [0, 1], clipped; all)."""
        if what == "frames":
            self.array = rec.frames
            self.dtype = np.dtype(rec.frames.dtype)
            self.rate = rec.attrs["rates"]["camera_hz"]
            self.divisor = int(np.asarray(rec.code).sum(axis=-1).max()) if rec.attrs.get("multiplexed") else 1
            if self.divisor != 1:
                self.attrs["frames_divided_by"] = self.divisor
        elif what == "ground-truth":
            if not rec.has_ground_truth:
                raise CliError(f"{rec.path} holds no ground truth (only simulated recordings have one)")
            self.array = rec.ground_truth
            self.dtype = np.dtype(np.float32)
            self.rate = rec.attrs["rates"]["subframe_hz"]
        else:
            from flexvox_core.capture_reader import CaptureReader

            try:
                reader = CaptureReader(rec)
                method = method_from_args(args, rec.attrs["tile"])
                result = reader.run(method, chunk_frames=args.chunk, device=resolved_device(args))
            except ValueError as exc:  # RecordingError and NotReconstructableError are ValueErrors
                raise CliError(str(exc)) from None
            self.array = result.video
            # As `flexvox reconstruct` records them: the method and the sub-frames filled across dropped frames.
            self.interpolated = result.interpolated
            self.attrs["method"] = method.as_dict()
            self.attrs.update(device_record(result))
            self.device_line = device_line(result)
            if reader.missing is not None:
                from flexvox_app.cli.reconstruct import interpolated_line

                self.gaps_line = interpolated_line(reader.gaps(), reader.K)
            self.dtype = np.dtype(np.float32)
            self.rate = rec.attrs["rates"]["subframe_hz"]
        self.shape = tuple(self.array.shape)

    def row(self, i: int) -> np.ndarray:
        import numpy as np

        return np.asarray(self.array[i])

    def unit(self, i: int) -> np.ndarray:
        import numpy as np

        if self.what == "frames":
            from flexvox_core.simulate.simulator import normalise_frames

            values = normalise_frames(self.row(i)[None], self.rec.attrs["storage"])[0]
            if self.divisor != 1:
                values = values / np.float32(self.divisor)
        else:
            values = np.asarray(self.row(i), np.float32)
        self.clipped[0] += int(np.count_nonzero((values < 0) | (values > 1)))
        self.clipped[1] += values.size
        return np.clip(values, 0, 1).astype(np.float32, copy=False)

    def clipped_line(self, out) -> str:
        """A warning when :meth:`unit` clipped values, naming their share; "" otherwise."""
        outside, count = self.clipped
        if not outside:
            return ""
        why = "ambient light, leakage or saturation" if self.what == "frames" else "values outside [0, 1]"
        return (f"warning: {outside / count:.2%} of the values lay outside [0, 1] ({why}) and were clipped in {out}; "
                ".tif and .npy keep them as they are")


class _VideoSource(_Source):
    """The rows of a reconstructed video's store (:func:`~flexvox_core.video_io.open_video_store`), as they are."""

    def __init__(self, store):
        import numpy as np

        self.rec = None
        self.what = "reconstruction"
        self.array = store.array
        self.dtype = np.dtype(np.float32)
        self.rate = None if store.time_step is None else 1.0 / store.time_step
        self.attrs = {**store.attrs, "exported_from": str(store.path), "what": "reconstruction"}
        self.interpolated = _interpolated(store.path, self.array.shape[0])
        self.gaps_line = ""
        self.device_line = ""
        self.divisor = 1
        self.clipped = [0, 0]
        self.shape = tuple(self.array.shape)


def _interpolated(path: Path, count: int):
    """The store's ``interpolated`` flags (one per sub-frame), or None where it has none."""
    import numpy as np
    import zarr

    from flexvox_core.video_io import INTERPOLATED

    group = zarr.open_group(str(path), mode="r")
    if INTERPOLATED not in group:
        return None
    flags = np.asarray(group[INTERPOLATED][:], bool)
    return flags if flags.shape == (count,) else None


def is_video_store(path: Path) -> bool:
    """Whether ``path`` is a reconstructed video's store (an array ``video``, no camera ``frames``)."""
    return (path / "zarr.json").is_file() and (path / "video" / "zarr.json").is_file() and not (
        path / "frames").exists()


def _check_video_request(args, given: list[str]) -> None:
    """A reconstructed video exports its video: no other ``--what``, no method options."""
    if args.what not in (None, "reconstruction"):
        raise CliError(f"{args.recording} is a reconstructed video: it holds no {args.what.replace('-', ' ')}, only "
                       "its video; export it without --what (or with --what reconstruction)")
    extra = list(given)
    if args.device != "auto":
        extra.append("--device")
    if extra:
        raise CliError(f"{extra[0]} does not apply: {args.recording} is a reconstructed video, exported as it is; "
                       "to reconstruct again with other options, give the recording it was made from")


def _write(out: Path, src: _Source, fps: float, pyramid: int = 0) -> None:
    import numpy as np

    n = src.shape[0]
    suffix = out.suffix.lower()
    if suffix in (".tif", ".tiff"):
        import tifffile

        from flexvox_core.video_io import imagej_metadata

        tifffile.imwrite(out, (src.row(i) for i in range(n)), shape=src.shape, dtype=src.dtype, imagej=True,
                         metadata=imagej_metadata(None if src.rate is None else 1.0 / src.rate))
    elif suffix == ".npy":
        arr = np.lib.format.open_memmap(out, mode="w+", dtype=src.dtype, shape=src.shape)
        for i in range(n):
            arr[i] = src.row(i)
        arr.flush()
        del arr
    elif suffix == ".mp4":
        from flexvox_core.video_io import write_mp4

        try:
            write_mp4(out, (src.unit(i) for i in range(n)), src.shape[1:], fps)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    elif suffix == ".zarr":
        from flexvox_core.video_io import write_video

        write_video(out, np.stack([src.unit(i) for i in range(n)]) if n else np.zeros((0, *src.shape[1:])),
                    attrs=src.attrs, time_step=None if src.rate is None else 1.0 / src.rate, pyramid=pyramid,
                    interpolated=src.interpolated)
    else:
        import cv2

        out.mkdir()
        for i in range(n):
            row = src.row(i) if src.dtype == np.uint16 else (src.unit(i) * 65535 + 0.5).astype(np.uint16)
            if not cv2.imwrite(str(out / f"frame_{i:05d}.png"), row):
                raise CliError(f"cannot write {out / f'frame_{i:05d}.png'}")


def _video_source(path: Path) -> _VideoSource:
    """The reconstructed video at ``path`` (a store :func:`open_video_store` cannot read is said in words)."""
    from flexvox_core.video_io import open_video_store

    try:
        return _VideoSource(open_video_store(path))
    except ValueError as exc:
        raise CliError(str(exc)) from None


def run(args) -> int:
    """Carry out ``flexvox export``."""
    from flexvox_core.ngff import check_levels
    from flexvox_core.output_files import CLI_OVERWRITE_HINT, OutputError, atomic_output, check_output, is_recording
    from flexvox_core.recording import RecordingError, open_recording

    given = method_flags_given(args)
    video = args.recording.is_dir() and is_video_store(args.recording)
    if video:
        _check_video_request(args, given)
    elif args.what is None:
        args.what = "frames"
    # else the frames would be exported as they are, without a word
    if given and not video and args.what != "reconstruction":
        default = " (the default)" if args.what == "frames" else ""
        what = "camera frames as they are" if args.what == "frames" else "ground truth as it is"
        raise CliError(f"{given[0]} goes with --what reconstruction; --what {args.what}{default} exports the {what}: "
                       "add --what reconstruction")
    if args.method is None:
        from flexvox_core.methods import DEFAULT

        args.method = DEFAULT
    out: Path = args.output
    suffix = out.suffix.lower()
    if suffix and suffix not in FORMATS:
        raise CliError(f"-o {out}: the output must end in .tif, .tiff, .npy, .mp4 or .zarr, or be a folder (PNG)")
    if args.pyramid and suffix != ".zarr":
        raise CliError(f"--pyramid goes with a .zarr output (an OME-Zarr image); got -o {out}")
    check_fps_output(args.fps, out)
    try:
        if not video and args.recording.is_dir() and not is_recording(args.recording):
            # `.`: said for what it is, not as the folder the output would lie in (its refusal names what it is)
            open_recording(args.recording)
        check_output(out, overwrite=args.overwrite, inputs=[args.recording], kind="folder" if suffix == "" else "auto",
                     hint=CLI_OVERWRITE_HINT)
        if suffix == "" and out.is_dir():
            others = sorted(p.name for p in out.iterdir() if not _PNG_NAME.fullmatch(p.name))
            if others:
                raise OutputError(f"{out} holds other files than an earlier export's PNGs ({', '.join(others[:3])}"
                                  f"{', ...' if len(others) > 3 else ''}); --overwrite replaces only such a folder: "
                                  "choose a new folder")
        if suffix == ".mp4":  # refused before a reconstruction runs, not after it
            from flexvox_core.video_io import check_mp4_size, open_video_store

            size = (open_video_store(args.recording).array if video else open_recording(args.recording).frames).shape
            check_mp4_size(size[1:], out)
        src = _video_source(args.recording) if video else _Source(open_recording(args.recording), args.what, args)
    except ValueError as exc:  # RecordingError and OutputError are ValueErrors: said as they are
        raise CliError(str(exc)) from None
    try:
        check_levels(args.pyramid, src.shape)
    except ValueError as exc:
        raise CliError(f"--pyramid: {exc}") from None
    fps = args.fps or (src.rate if src.what == "frames" else 30.0)
    try:
        with atomic_output(out, overwrite=args.overwrite, hint=CLI_OVERWRITE_HINT) as tmp:
            _write(tmp, src, fps, args.pyramid)
    except (RecordingError, OutputError) as exc:  # a damaged chunk found while writing: nothing was replaced
        raise CliError(f"{exc}; {out} was not written") from None
    except OSError as exc:
        raise CliError(f"cannot write {out}: {exc.strerror or exc}; nothing was replaced") from None
    if src.clipped_line(out):
        print(src.clipped_line(out), file=sys.stderr)
    if src.gaps_line:
        print(src.gaps_line)
    if src.device_line:
        print(src.device_line)
    print(f"wrote {src.what} ({src.shape[0]} x {src.shape[1]}x{src.shape[2]} {src.dtype}) to {out}")
    return EXIT_OK
