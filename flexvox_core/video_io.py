"""Writing videos ``(S, H, W)`` in [0, 1] to files: ``.npy``, ``.tif`` (Fiji), ``.mp4``, ``.zarr`` (OME-Zarr);
reading them back (:func:`read_video`), opening a ``.zarr`` video lazily (:func:`open_video_store`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_core.output_files import atomic_output, check_output, check_path
from flexvox_core.reprs import describe_array, html_table, short_repr

WRITABLE = (".npy", ".tif", ".tiff", ".mp4", ".zarr")


def write_video(path, video, *, fps: float = 30.0, attrs: dict | None = None, overwrite: bool = False,
                time_step: float | None = None, pyramid: int = 0, interpolated=None) -> Path:
    """Write ``video`` (values in [0, 1]) by the path's suffix; :func:`read_video` reads it back.

    **Values.** A float video must hold finite values in [0, 1]: NaN or infinite values, and values outside
    [0, 1] (0–255 data in a float array, a difference image), are refused with a ``ValueError`` that names the
    range found (``np.clip(video, 0, 1)`` or ``video / 255`` first, as fits). An integer video is read as
    :func:`flexvox_core.intensity.as_relative` reads it: divided by its dtype's largest value (uint8: 255,
    uint16: 65535).

    ``.npy`` and ``.tif`` keep float32 (a TIFF stack with one page per sub-frame, which Fiji
    opens as a stack; with ``time_step`` its ImageJ metadata gives the frame interval in seconds,
    ``finterval`` and ``tunit``, and ``attrs`` its Info); ``.mp4`` is 8-bit grey at ``fps``, its height and
    width even and at least 16 px (:func:`check_mp4_size`: a ``ValueError`` otherwise); ``.zarr`` is an
    OME-Zarr image
    (NGFF 0.5 on Zarr v3, :mod:`flexvox_core.ngff`): array ``video`` (one sub-frame per chunk, axes
    t, y, x) with ``time_step`` as its t scale, ``pyramid`` levels of 2×2 means (default none) and
    ``attrs`` under ``flexvox``.

    ``time_step`` is the seconds between two of the video's frames (a reconstruction's sub-frame
    period, 1/(fps·K)); None where it is not known (the t axis then has no unit).

    ``interpolated`` (S,) bool: the sub-frames filled across dropped camera frames
    (:mod:`flexvox_core.gaps`); a ``.zarr`` output keeps it as the array ``interpolated`` beside
    the video (and its count in the attributes), the other formats have no place for it.

    The file is written to a hidden temporary sibling and moved into place when complete
    (:func:`~flexvox_core.output_files.atomic_output`): a failed write leaves an old ``path`` as it was.
    """
    from flexvox_core import ngff

    path = check_path(path, call="fv.write_video(path, video)")
    suffix = path.suffix.lower()
    if suffix not in WRITABLE:
        raise ValueError(f"cannot write {path}: the output must end in {', '.join(WRITABLE)}")
    v = np.asarray(video)
    if v.ndim != 3:
        raise ValueError(f"`video` must have shape (S, H, W); got {v.shape}")
    v = check_unit_values(v)
    if suffix == ".mp4":
        check_fps(fps)
        check_mp4_size(v.shape[1:], path)
    time_step = ngff.check_time_step(time_step)
    if pyramid and suffix != ".zarr":
        raise ValueError(f"a pyramid is written only into a .zarr store; got {path} with pyramid={pyramid!r}")
    pyramid = ngff.check_levels(pyramid, v.shape)
    if interpolated is not None:
        interpolated = np.asarray(interpolated, bool)
        if interpolated.shape != (v.shape[0],):
            raise ValueError(f"`interpolated` must hold one flag per sub-frame ({v.shape[0]}); "
                             f"got {interpolated.shape}")
    check_attrs(attrs)
    check_output(path, overwrite=overwrite)
    with atomic_output(path, overwrite=overwrite) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as fh:  # a file, not a name: np.save would add ".npy" to "OUT.NPY"'s temporary
                np.save(fh, v)
        elif suffix in (".tif", ".tiff"):
            import tifffile

            tifffile.imwrite(tmp, v, imagej=True, metadata=imagej_metadata(time_step, attrs))
        elif suffix == ".mp4":
            write_mp4(tmp, v, v.shape[1:], fps)
        else:
            import zarr

            import flexvox_core.zarr_exit  # noqa: F401 - a quiet exit (see there)

            g = zarr.open_group(str(tmp), mode="w-", zarr_format=3)
            meta = provenance(attrs, time_step)
            if interpolated is not None:
                meta["interpolated_subframes"] = int(interpolated.sum())
                g.create_array(INTERPOLATED, data=interpolated, chunks=(max(1, min(len(interpolated), 65536)),))
            g.attrs["flexvox"] = meta
            ngff.write_pyramid(ngff.create_image(g, VIDEO, v.shape, time_step=time_step, levels=pyramid), v)
    return path


def check_attrs(attrs) -> None:
    """``attrs`` must be None or a dict of JSON values (str, int, float, bool, None, and lists and dicts of them
    with str keys), checked before any work: a numpy scalar had failed inside the write with json's "Object of
    type float32 is not JSON serializable"."""
    if attrs is None:
        return
    if not isinstance(attrs, dict):
        raise TypeError(f"`attrs` must be a dict of JSON values; got {type(attrs).__name__}")

    def walk(value, where: str) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                if not isinstance(k, str):
                    raise TypeError(f"`attrs` keys must be text; got {k!r} in {where or 'attrs'}")
                walk(v, f"{where}[{k!r}]")
        elif isinstance(value, list | tuple):
            for i, v in enumerate(value):
                walk(v, f"{where}[{i}]")
        elif value is not None and not isinstance(value, str | int | float):  # bool is an int
            hint = " (a numpy value: give value.item() or value.tolist())" if type(value).__module__ == "numpy" else ""
            raise TypeError(f"`attrs` must hold JSON values (text, numbers, bools, None, lists, dicts); "
                            f"attrs{where} is a {type(value).__name__}{hint}")

    walk(attrs, "")


def check_unit_values(video) -> np.ndarray:
    """``video`` as float32 in [0, 1]: integers divided by their dtype's largest value
    (:func:`~flexvox_core.intensity.as_relative`); floats checked. ``ValueError`` for NaN, infinite values or
    values outside [0, 1], naming the frame and the range found."""
    from flexvox_core.intensity import as_relative

    v = np.asarray(as_relative(video, name="video"), dtype=np.float32)
    if not v.size:
        return v
    finite = np.isfinite(v).all(axis=tuple(range(1, v.ndim)))
    if not finite.all():
        raise ValueError(f"`video` frame {int(np.flatnonzero(~finite)[0])} holds NaN or infinite values; a video "
                         "holds finite values in [0, 1]")
    lo, hi = float(v.min()), float(v.max())
    if lo < 0 or hi > 1:
        hint = ("8-bit values in a float array? divide by 255" if hi > 1 and hi <= 255 and lo >= 0
                else "np.clip(video, 0, 1) keeps the range, or rescale it")
        raise ValueError(f"`video` values must lie in [0, 1]; got {lo:g} to {hi:g} ({hint})")
    return v


VIDEO = "video"
"""The array of a reconstruction store (NGFF's full-resolution dataset; its pyramid levels are ``video_1`` ...)."""
INTERPOLATED = "interpolated"
"""The (S,) bool array of a reconstruction store: sub-frames filled across dropped camera frames."""


def imagej_metadata(time_step: float | None, attrs: dict | None = None) -> dict:
    """ImageJ metadata of a TYX stack: Fiji shows time in seconds when the frame interval is known,
    and ``attrs`` (the method and its options, the source) as the image's Info (Image > Show Info)."""
    import json

    meta = {"axes": "TYX", "unit": "pixel"}
    if time_step is not None:
        meta.update(finterval=float(time_step), tunit="sec")
    if attrs:
        meta["Info"] = "flexvox: " + json.dumps(attrs, sort_keys=True, default=str)
    return meta


def provenance(attrs: dict | None, time_step: float | None) -> dict:
    """The ``flexvox`` attribute block of a written video: the caller's ``attrs`` (method, source ...)
    plus the software version, the time of writing and the time step."""
    import datetime

    from flexvox_core._version import __version__

    now = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    return {"software_version": __version__, "created_utc": now, "time_step_s": time_step, **(attrs or {})}


@dataclass(frozen=True)
class VideoStore:
    """A video store opened by :func:`open_video_store`: the (S, H, W) array (lazy, zarr), its
    ``flexvox`` attributes, its time step in seconds (None: not known) and its pyramid levels."""

    path: Path
    array: object
    attrs: dict
    time_step: float | None
    levels: tuple

    def _facts(self) -> list[tuple[str, str]]:
        step = "unknown" if self.time_step is None else f"{self.time_step:g} s"
        return [("path", str(self.path)), ("video", describe_array(self.array)), ("time step", step),
                ("pyramid levels", str(len(self.levels))),
                ("method", str(self.attrs.get("method", "unknown"))),
                ("from", str(self.attrs.get("recording", self.attrs.get("source", "unknown"))))]

    def __repr__(self) -> str:
        step = "" if self.time_step is None else f"time step {self.time_step:g} s"
        levels = f"{len(self.levels)} pyramid levels" if len(self.levels) > 1 else ""
        return short_repr(f"VideoStore {self.path.name}:", [describe_array(self.array), step, levels])

    def _repr_html_(self) -> str:
        return html_table("VideoStore", self._facts())


def open_video_store(path) -> VideoStore:
    """Open a reconstruction store (``reconstruct``/``export``/``batch -o OUT.zarr``) for reading.

    Reads the OME-Zarr image flexvox writes now and the plain group (array ``video``, no ``ome``
    attribute) it wrote before; the time step then comes from the recording it names, when that is
    still there, else it is None.

    Raises
    ------
    ValueError
        Not a Zarr store, or no ``video`` array in it.
    """
    import zarr

    import flexvox_core.zarr_exit  # noqa: F401 - a quiet exit (see there)
    from flexvox_core import ngff

    path = check_path(path, call="fv.open_video_store(path)")
    try:
        group = zarr.open_group(str(path), mode="r")
    except (FileNotFoundError, ValueError, zarr.errors.NodeTypeValidationError) as exc:
        raise ValueError(f"{path}: not a Zarr store ({exc})") from None
    if VIDEO not in group:
        what = ("a recording (camera frames): fv.open_recording opens it, "
                "fv.reconstruct_video(fv.open_recording(path)) reconstructs it" if "frames" in group
                else "not a flexvox reconstruction")
        raise ValueError(f"{path}: no `{VIDEO}` array: {what}")
    attrs = dict(group.attrs)
    meta = dict(attrs.get("flexvox") or {})
    step = ngff.time_step(attrs, VIDEO)
    paths = []
    for multiscale in (attrs.get("ome") or {}).get("multiscales", [])[:1]:
        paths = [d["path"] for d in multiscale.get("datasets", []) if d.get("path") in group]
    if step is None:
        step = _source_time_step(meta.get("source"))
    levels = tuple(group[p] for p in paths) or (group[VIDEO],)
    return VideoStore(path, group[VIDEO], meta, step, levels)


def read_video(path) -> np.ndarray:
    """Read a video :func:`write_video` wrote (or any of its formats): ``(S, H, W)`` float32.

    The counterpart of :func:`write_video`: ``.npy`` and ``.tif`` come back exactly, ``.zarr`` too (its
    ``video`` array; :func:`open_video_store` opens it lazily, with its time step and attributes), ``.mp4`` as
    its 8-bit grey values divided by 255.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    ndarray (S, H, W) float32

    Raises
    ------
    ValueError
        A path that does not exist, a suffix none of the formats has, a file that is not a video (a recording:
        :func:`flexvox_core.recording.open_recording` opens it).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> video = np.random.default_rng(0).random((4, 8, 8)).astype(np.float32)
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "v.tif"
    >>> bool(np.array_equal(read_video(write_video(out, video)), video))
    True
    """
    path = check_path(path, call="fv.read_video(path)")
    suffix = path.suffix.lower()
    if suffix not in WRITABLE:
        raise ValueError(f"cannot read {path} as a video: a video ends in {', '.join(WRITABLE)}")
    if not path.exists():
        raise ValueError(f"{path}: no such video")
    if suffix == ".zarr":
        return np.asarray(open_video_store(path).array[:], dtype=np.float32)
    if suffix == ".npy":
        v = np.load(path, allow_pickle=False)
    elif suffix in (".tif", ".tiff"):
        import tifffile

        v = tifffile.imread(path)
    else:
        v = _read_mp4(path)
    v = np.asarray(v)
    if v.ndim == 2:
        v = v[None]
    if v.ndim != 3:
        raise ValueError(f"{path}: a video has shape (S, H, W); this file holds an array of shape {v.shape}")
    return v.astype(np.float32, copy=False) if v.dtype.kind == "f" else np.asarray(
        check_unit_values(v), np.float32)


def _read_mp4(path: Path) -> np.ndarray:
    import cv2

    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise ValueError(f"{path}: OpenCV cannot open it as an MP4 video")
    frames = []
    try:
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            frames.append(frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY))
    finally:
        cap.release()
    if not frames:
        raise ValueError(f"{path}: an MP4 with no frame OpenCV can read")
    return np.stack(frames)


def _source_time_step(source) -> float | None:
    """An older store's sub-frame period, from the recording it was made from (when it is still there)."""
    if not source:
        return None
    try:
        import zarr

        rates = dict(zarr.open_group(str(source), mode="r").attrs)["flexvox"]["rates"]
        return 1.0 / float(rates["subframe_hz"])
    except Exception:  # noqa: BLE001 - gone, moved or not a recording: the step is simply unknown
        return None


def check_fps(fps) -> float:
    """An MP4 playback rate: a finite number above 0 and at most 1000 frames per second."""
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise ValueError(f"the playback rate must be a number of frames per second; got {fps!r}") from None
    if not (np.isfinite(value) and 0 < value <= 1000):
        raise ValueError(f"the playback rate must be above 0 and at most 1000 frames per second; got {fps!r}")
    return value


MP4_MIN_SIDE = 16
"""The smallest height and width an ``.mp4`` is written at (both even, too)."""


def check_mp4_size(size: tuple[int, int], path) -> None:
    """Refuse an ``.mp4`` of frames ``size`` = (H, W) unless both are even and at least :data:`MP4_MIN_SIDE`:
    OpenCV's MPEG-4 (mp4v) writer drops an odd last row or column without a word, and on some smaller frames
    (4×4, 8×6, 20×4, 24×6: found by writing every even size up to 24) corrupts memory and aborts the process.
    Even sizes of at least 16 px were written and read back whole (100 sizes from 16×16 to 480×640)."""
    H, W = (int(v) for v in size)
    if H >= MP4_MIN_SIDE and W >= MP4_MIN_SIDE and H % 2 == 0 and W % 2 == 0:
        return
    odd, small = bool(H % 2 or W % 2), min(H, W) < MP4_MIN_SIDE
    why = (f"even and of at least {MP4_MIN_SIDE} px" if odd and small else
           "even (OpenCV's writer would drop the odd row or column)" if odd else f"of at least {MP4_MIN_SIDE} px")
    raise ValueError(f"cannot write {path}: an .mp4 (MPEG-4, mp4v) needs a height and width {why}; the frames are "
                     f"{H}x{W}: write .tif, .npy or .zarr instead, which keep every pixel")


def write_mp4(path, frames, size: tuple[int, int], fps: float) -> None:
    """Write ``frames`` (an iterable of ``(H, W)`` arrays in [0, 1]) as 8-bit grey MP4 (mp4v) at ``fps``.

    ``size`` is ``(H, W)``, both even and at least :data:`MP4_MIN_SIDE` (:func:`check_mp4_size`; ``ValueError``
    otherwise, before anything is written). Writes ``path`` directly: callers go through
    :func:`~flexvox_core.output_files.atomic_output`.
    """
    import cv2

    check_mp4_size(size, path)
    H, W = size
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), check_fps(fps), (W, H), False)
    if not writer.isOpened():
        raise ValueError(f"cannot write {path}: OpenCV could not open an MP4 (mp4v) writer here")
    try:
        for frame in frames:
            writer.write((np.clip(frame, 0, 1) * 255 + 0.5).astype(np.uint8))
    finally:
        writer.release()
