"""Writing videos ``(S, H, W)`` in [0, 1] to files: ``.npy``, ``.tif`` (Fiji), ``.mp4``, ``.zarr``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexvox_core.output_files import atomic_output, check_output

WRITABLE = (".npy", ".tif", ".tiff", ".mp4", ".zarr")


def write_video(path, video, *, fps: float = 30.0, attrs: dict | None = None, overwrite: bool = False) -> Path:
    """Write ``video`` (float, values in [0, 1]) by the path's suffix.

    ``.npy`` and ``.tif`` keep float32 (a TIFF stack with one page per sub-frame, which Fiji
    opens as a stack); ``.mp4`` is 8-bit grey at ``fps``; ``.zarr`` is a Zarr v3 group with
    array ``video`` (one sub-frame per chunk) and ``attrs`` under ``flexvox``.

    The file is written to a hidden temporary sibling and moved into place when complete
    (:func:`~flexvox_core.output_files.atomic_output`): a failed write leaves an old ``path`` as it was.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITABLE:
        raise ValueError(f"cannot write {path}: the output must end in {', '.join(WRITABLE)}")
    v = np.asarray(video, dtype=np.float32)
    if v.ndim != 3:
        raise ValueError(f"`video` must have shape (S, H, W); got {v.shape}")
    if suffix == ".mp4":
        check_fps(fps)
    check_output(path, overwrite=overwrite, hint="choose another path or allow overwriting")
    with atomic_output(path, overwrite=overwrite) as tmp:
        if suffix == ".npy":
            np.save(tmp, v)
        elif suffix in (".tif", ".tiff"):
            import tifffile

            tifffile.imwrite(tmp, v, imagej=True, metadata={"axes": "TYX"})
        elif suffix == ".mp4":
            write_mp4(tmp, v, v.shape[1:], fps)
        else:
            import zarr

            g = zarr.open_group(str(tmp), mode="w-", zarr_format=3)
            arr = g.create_array("video", shape=v.shape, chunks=(1, *v.shape[1:]), dtype="float32")
            arr[:] = v
            g.attrs["flexvox"] = attrs or {}
    return path


def check_fps(fps) -> float:
    """An MP4 playback rate: a finite number above 0 and at most 1000 frames per second."""
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise ValueError(f"the playback rate must be a number of frames per second; got {fps!r}") from None
    if not (np.isfinite(value) and 0 < value <= 1000):
        raise ValueError(f"the playback rate must be above 0 and at most 1000 frames per second; got {fps!r}")
    return value


def write_mp4(path, frames, size: tuple[int, int], fps: float) -> None:
    """Write ``frames`` (an iterable of ``(H, W)`` arrays in [0, 1]) as 8-bit grey MP4 (mp4v) at ``fps``.

    ``size`` is ``(H, W)``. Writes ``path`` directly: callers go through
    :func:`~flexvox_core.output_files.atomic_output`.
    """
    import cv2

    H, W = size
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), check_fps(fps), (W, H), False)
    if not writer.isOpened():
        raise ValueError(f"cannot write {path}: OpenCV could not open an MP4 (mp4v) writer here")
    try:
        for frame in frames:
            writer.write((np.clip(frame, 0, 1) * 255 + 0.5).astype(np.uint8))
    finally:
        writer.release()
