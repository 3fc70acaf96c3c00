"""Writing videos ``(S, H, W)`` in [0, 1] to files: ``.npy``, ``.tif`` (Fiji), ``.mp4``, ``.zarr``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

WRITABLE = (".npy", ".tif", ".tiff", ".mp4", ".zarr")


def write_video(path, video, *, fps: float = 30.0, attrs: dict | None = None, overwrite: bool = False) -> Path:
    """Write ``video`` (float, values in [0, 1]) by the path's suffix.

    ``.npy`` and ``.tif`` keep float32 (a TIFF stack with one page per sub-frame, which Fiji
    opens as a stack); ``.mp4`` is 8-bit grey at ``fps``; ``.zarr`` is a Zarr v3 group with
    array ``video`` (one sub-frame per chunk) and ``attrs`` under ``flexvox``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITABLE:
        raise ValueError(f"cannot write {path}: the output must end in {', '.join(WRITABLE)}")
    v = np.asarray(video, dtype=np.float32)
    if v.ndim != 3:
        raise ValueError(f"`video` must have shape (S, H, W); got {v.shape}")
    if path.exists() and not overwrite:
        raise ValueError(f"{path} already exists; choose another path or allow overwriting")
    if not path.parent.exists():
        raise ValueError(f"cannot write {path}: the folder {path.parent} does not exist")
    if suffix == ".npy":
        np.save(path, v)
    elif suffix in (".tif", ".tiff"):
        import tifffile

        tifffile.imwrite(path, v, imagej=True, metadata={"axes": "TYX"})
    elif suffix == ".mp4":
        _write_mp4(path, v, fps)
    else:
        import zarr

        g = zarr.open_group(str(path), mode="w", zarr_format=3)
        arr = g.create_array("video", shape=v.shape, chunks=(1, *v.shape[1:]), dtype="float32")
        arr[:] = v
        g.attrs["flexvox"] = attrs or {}
    return path


def _write_mp4(path: Path, v: np.ndarray, fps: float) -> None:
    import cv2

    S, H, W = v.shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps), (W, H), False)
    if not writer.isOpened():
        raise ValueError(f"cannot write {path}: OpenCV has no MP4 encoder here")
    try:
        for frame in v:
            writer.write((np.clip(frame, 0, 1) * 255 + 0.5).astype(np.uint8))
    finally:
        writer.release()
