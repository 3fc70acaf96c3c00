"""Video sources from files: ``.npy`` (S, H, W), multi-page TIFF, videos OpenCV reads,
and the video-SCI benchmark's ``.mat`` files (variable ``orig``, H×W×T uint8).

All load as float32 ``(S, H, W)`` in [0, 1]: uint8 / 255, uint16 / 65535 (or counts / ``white`` when it is
given: 4095 for a 12-bit camera's counts), float kept (and required to lie in [0, 1]). uint16 counts none above
4095 read without ``white`` give a :class:`~flexvox_core.intensity.CountsWarning` (a 12-bit camera's counts read
as 16-bit ones make the scene 16 times darker). Colour is converted to luminance (Rec. 601) on the same scales. Nothing
is unpickled.
A file is judged by its header first (:func:`video_shape`): a truncated ``.npy`` is named as
such, and a video that would not fit in memory as float32 is refused before it is read.
"""

from __future__ import annotations

import logging
import os
import warnings
from pathlib import Path
from struct import error as struct_error

import numpy as np

from flexvox_core.memory_budget import check_fits, video_load_bytes

_logger = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")
SUFFIXES = (".npy", ".tif", ".tiff", *VIDEO_SUFFIXES, ".mat")


class TrimWarning(UserWarning):
    """A source was shortened to whole camera frames (a multiple of K sub-frames)."""


def _to_unit_float(arr: np.ndarray, path: Path, white: float | None = None) -> np.ndarray:
    from flexvox_core.intensity import NARROW_COUNTS, CountsWarning

    if not arr.dtype.isnative:  # big-endian counts or floats (a .npy or TIFF from another machine): the same values
        arr = arr.astype(arr.dtype.newbyteorder("="))
    if white is not None:
        if arr.dtype not in (np.uint8, np.uint16):
            raise ValueError(f"{path}: `white` divides integer counts (uint8, uint16); this video holds {arr.dtype} "
                             "values (floats must lie in [0, 1] already): leave `white` out")
        top = int(arr.max()) if arr.size else 0
        if top > white:
            raise ValueError(f"{path}: counts up to {top} lie above white = {white:g}: give the count that stands "
                             "for white (4095 for a 12-bit camera, 65535 for 16-bit counts)")
        return arr.astype(np.float32) / np.float32(white)
    if arr.dtype == np.uint16 and arr.size and 0 < int(arr.max()) <= NARROW_COUNTS:
        top = int(arr.max())
        warnings.warn(f"{path}: uint16 counts none above {top}: read as 16-bit counts (white 65535) the scene lies "
                      f"within [0, {top / 65535:.4f}]; a 12-bit camera's counts need white 4095 (10-bit: 1023): "
                      "`white = 4095` in the scene file's [source], or --white 4095", CountsWarning, stacklevel=3)
    if arr.dtype == np.uint8:
        return arr.astype(np.float32) / np.float32(255)
    if arr.dtype == np.uint16:
        return arr.astype(np.float32) / np.float32(65535)
    if np.issubdtype(arr.dtype, np.floating):
        arr = arr.astype(np.float32, copy=False)
        if not np.isfinite(arr).all():
            bad = int(np.flatnonzero(~np.isfinite(arr).all(axis=(1, 2)))[0])
            raise ValueError(f"{path}: sub-frame {bad} holds NaN or infinite values")
        lo, hi = float(arr.min()), float(arr.max())
        if lo < 0 or hi > 1:
            raise ValueError(f"{path}: float video values must lie in [0, 1]; found {lo:g} .. {hi:g}")
        return arr
    raise ValueError(f"{path}: unsupported pixel type {arr.dtype} (use uint8, uint16 or float in [0, 1])")


def _gray(arr: np.ndarray, path: Path) -> np.ndarray:
    if arr.ndim == 4 and arr.shape[-1] in (3, 4):
        # Luminance (Rec. 601) on the type's own scale: 8- and 16-bit counts by their full scale, floats as they
        # are (in [0, 1], checked next) — never by a guess from the values.
        full = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}.get(arr.dtype)
        if full is None and not np.issubdtype(arr.dtype, np.floating):
            raise ValueError(f"{path}: unsupported pixel type {arr.dtype} (use uint8, uint16 or float in [0, 1])")
        weights = np.array([0.299, 0.587, 0.114], np.float32)
        arr = arr[..., :3].astype(np.float32) @ weights
        if full is not None:
            arr = np.minimum(arr / np.float32(full), np.float32(1.0))  # the weights' float sum may pass 1 by an ulp
    if arr.ndim != 3:
        raise ValueError(f"{path}: a video must have 3 dimensions (S, H, W); got {arr.ndim} {arr.shape}")
    return arr


def load_video(path, *, white: float | None = None) -> np.ndarray:
    """Load a video file as float32 ``(S, H, W)`` in [0, 1] (see the module docstring); ``white``: the count that
    stands for white in an integer video (default its dtype's largest value)."""
    from flexvox_core.numbers import positive_number

    path = Path(path)
    if white is not None:
        white = positive_number("`white`", white, unit="counts")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(f"{path}: unknown video type {suffix!r}; readable: {', '.join(SUFFIXES)}")
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    declared = _declared(path, suffix)
    if declared is not None:
        shape, dtype = declared
        colour = len(shape) == 4 and shape[-1] in (3, 4)
        pixels = _prod(shape[:3] if colour else shape)
        check_fits(video_load_bytes(_prod(shape) * dtype.itemsize, pixels, colour),
                   f"{path}: reading its {'x'.join(map(str, shape))} {dtype} samples as a float32 video",
                   "cut it to fewer or smaller frames")
    try:
        if suffix == ".npy":
            arr = np.load(path, allow_pickle=False)
        elif suffix in (".tif", ".tiff"):
            arr = _load_tiff(path)
        elif suffix == ".mat":
            arr = _load_mat(path)
        else:
            arr = _load_opencv_video(path)
    except ValueError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise ValueError(f"{path}: cannot read: {exc}") from exc
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc}") from exc
    arr = _gray(np.asarray(arr), path)
    if min(arr.shape) == 0:
        raise ValueError(f"{path}: the video is empty {arr.shape}")
    return np.ascontiguousarray(_to_unit_float(arr, path, white))


def video_shape(path) -> tuple[int, int, int] | None:
    """``(S, H, W)`` a video file declares in its header, without reading its pixels; None when unknown.

    ``ValueError`` for a ``.npy`` whose header is missing or that holds less data than it declares
    (truncated). A damaged TIFF or video gives None here; :func:`load_video` names its damage.
    """
    path = Path(path)
    declared = _declared(path, path.suffix.lower()) if path.exists() else None
    if declared is None or len(declared[0]) not in (3, 4):
        return None
    S, H, W = declared[0][:3]
    return int(S), int(H), int(W)


def _prod(shape) -> int:
    n = 1
    for d in shape:
        n *= int(d)
    return n


def _declared(path: Path, suffix: str) -> tuple[tuple[int, ...], np.dtype] | None:
    """The shape and sample type a file's header declares (nothing else is read); None when unknown."""
    if suffix == ".npy":
        return _npy_header(path)
    try:
        if suffix in (".tif", ".tiff"):
            import tifffile

            tiff_log = logging.getLogger("tifffile")
            level = tiff_log.level
            tiff_log.setLevel(logging.CRITICAL)  # the reader names a damaged file; the header peek stays quiet
            try:
                with tifffile.TiffFile(path) as tif:
                    series = tif.series[0]
                    return tuple(int(d) for d in series.shape), np.dtype(series.dtype)
            finally:
                tiff_log.setLevel(level)
        if suffix in VIDEO_SUFFIXES:
            import cv2

            with _quiet_ffmpeg():
                cap = cv2.VideoCapture(str(path))
            try:
                count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else 0
                H, W = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)), int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
            finally:
                cap.release()
            return ((count, H, W), np.dtype(np.uint8)) if min(count, H, W) > 0 else None
    except Exception:  # noqa: BLE001 - a header that cannot be read is the reader's to report
        return None
    return None


def _npy_header(path: Path) -> tuple[tuple[int, ...], np.dtype] | None:
    """A ``.npy`` header's shape and dtype; refuses a file without one, or with less data than it declares."""
    from numpy.lib import format as npy_format

    try:
        fh = open(path, "rb")  # noqa: SIM115 - closed by the with below; opened apart to name a read failure
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    with fh:
        if fh.read(6) != b"\x93NUMPY":
            raise ValueError(f"{path}: not a NumPy .npy file (no .npy header); it is damaged or another "
                             "format with the wrong suffix")
        fh.seek(0)
        try:
            version = npy_format.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = npy_format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, _, dtype = npy_format.read_array_header_2_0(fh)
            else:
                return None
        except ValueError:
            return None  # a damaged header: np.load names it
        offset = fh.tell()
    if dtype.hasobject:
        return None  # np.load refuses it (nothing is unpickled)
    need, have = _prod(shape) * dtype.itemsize, path.stat().st_size - offset
    if have < need:
        raise ValueError(f"{path}: a damaged .npy: its header declares {'x'.join(map(str, shape))} {dtype} "
                         f"({need} bytes) but the file holds {have} bytes after it; it may be truncated")
    return tuple(int(d) for d in shape), dtype


class _quiet_ffmpeg:
    """FFmpeg's own complaints would be a second, cryptic stderr line: silence them while OpenCV opens a file."""

    def __enter__(self):
        self._saved = os.environ.get("OPENCV_FFMPEG_LOGLEVEL")
        os.environ["OPENCV_FFMPEG_LOGLEVEL"] = "-8"

    def __exit__(self, *exc):
        if self._saved is None:
            del os.environ["OPENCV_FFMPEG_LOGLEVEL"]
        else:
            os.environ["OPENCV_FFMPEG_LOGLEVEL"] = self._saved


class _Collect(logging.Handler):
    """Keeps the messages a library logs while it reads (tifffile logs a damaged file and goes on)."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record) -> None:
        self.messages.append(record.getMessage())


def _load_tiff(path: Path) -> np.ndarray:
    """A multi-page TIFF as ``(S, H, W[, C])``; a damaged or truncated one is refused, not read in part."""
    import tifffile

    log = logging.getLogger("tifffile")
    collect = _Collect()
    log.addHandler(collect)
    propagate, log.propagate = log.propagate, False
    try:
        try:
            with tifffile.TiffFile(path) as tif:
                arr = tif.asarray()
                declared = (tif.imagej_metadata or {}).get("images")
        except (tifffile.TiffFileError, ValueError, IndexError, KeyError, struct_error) as exc:
            raise ValueError(f"{path}: not a readable TIFF ({exc}); it is damaged or another format") from None
    finally:
        log.removeHandler(collect)
        log.propagate = propagate
    if collect.messages:
        raise ValueError(f"{path}: a damaged TIFF ({collect.messages[0].split('> ', 1)[-1]}); it may be truncated: "
                         "copy or export it again")
    if declared and (arr.ndim < 3 or arr.shape[0] != int(declared)):
        raise ValueError(f"{path}: a damaged TIFF: it declares {declared} images but holds "
                         f"{arr.shape[0] if arr.ndim >= 3 else 1}; it may be truncated")
    if arr.ndim == 2:
        raise ValueError(f"{path}: a single-page TIFF is one image, not a video")
    return arr


def _load_mat(path: Path) -> np.ndarray:
    import scipy.io

    try:
        data = scipy.io.loadmat(path, variable_names=["orig"])
    except NotImplementedError:
        raise ValueError(f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with -v7") from None
    except (scipy.io.matlab.MatReadError, ValueError, TypeError, EOFError) as exc:
        raise ValueError(f"{path}: cannot read it as a MATLAB file ({exc}); it is empty, damaged or not a "
                         ".mat file") from None
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if "orig" not in data:
        raise ValueError(f"{path}: no variable `orig` (the SCI benchmark's ground-truth frames)")
    orig = np.asarray(data["orig"])
    if orig.ndim != 3:
        raise ValueError(f"{path}: `orig` must be H x W x T; got {orig.shape}")
    return np.ascontiguousarray(orig.transpose(2, 0, 1))


def _load_opencv_video(path: Path) -> np.ndarray:
    import cv2

    with _quiet_ffmpeg():
        cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise ValueError(f"{path}: OpenCV cannot open this video (damaged, or a codec it lacks)")
        frames = []
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame)
    finally:
        cap.release()
    if not frames:
        raise ValueError(f"{path}: the video holds no readable frame")
    return np.stack(frames)


def trim_to_frames(video: np.ndarray, K: int, *, frames: int | None = None, source: str = "source") -> np.ndarray:
    """Cut ``video`` to whole camera frames of K sub-frames (at most ``frames`` of them).

    Warns (:class:`TrimWarning`) when sub-frames are dropped because S is not a multiple of K.
    """
    S = video.shape[0]
    whole = S // K
    if whole == 0:
        raise ValueError(f"{source} has {S} sub-frames, fewer than one camera frame (K = {K})")
    if frames is not None:
        if frames > whole:
            raise ValueError(f"{source} has {S} sub-frames: {whole} camera frames of K = {K}, not {frames}")
        whole = frames
    elif S % K:
        message = (
            f"{source}: {S} sub-frames is not a multiple of K = {K}; "
            f"using the first {whole * K} ({whole} camera frames), dropping {S - whole * K}"
        )
        _logger.info(message)  # the warning below is what callers see (the CLI prints it once)
        warnings.warn(message, TrimWarning, stacklevel=2)
    return video[: whole * K]
