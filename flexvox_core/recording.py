"""Recordings: a Zarr v3 store (a directory) readable by anyone with zarr, dask or napari.

Layout (schema version 1)::

    REC.zarr/
      zarr.json            group attributes under "flexvox": schema_version, software_version,
                           created_utc, kind (simulated | captured), tile, K, code (m×n×K 0/1),
                           order (identity codes), multiplexed, placement_order, rates
                           {camera_hz, subframe_hz}, effects {name: params}, seed, source,
                           storage {kind: float | counts, ...}, calibration, rig
      frames/              (F, H, W) float32 (relative units) or uint16 counts; one frame per chunk
      frame_id/            (F,) int64
      timestamp/           (F,) float64, seconds
      dropped/             (F,) bool; a dropped frame is a zero row with its flag set
      ground_truth/        (S, H, W) float32, S = F·K — simulated recordings only

Frames are written as they arrive (:class:`RecordingWriter`); every completed frame is a
chunk of its own, so a capture that stops early still leaves the frames it wrote.
"""

from __future__ import annotations

import datetime as _dt
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import zarr

from flexvox_core._version import __version__
from flexvox_core.codes import is_identity_code, order_from_code, validate_code

_logger = logging.getLogger(__name__)

SCHEMA_VERSION = 1
"""Bumped when the layout changes in a way older readers cannot follow."""

PER_FRAME = ("frame_id", "timestamp", "dropped")
_PER_FRAME_DTYPES = {"frame_id": "int64", "timestamp": "float64", "dropped": "bool"}
_REQUIRED_ATTRS = ("schema_version", "tile", "K", "code", "rates", "storage")


class RecordingError(ValueError):
    """A recording that cannot be read or is damaged; the message says what is wrong."""


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def recording_attrs(code, *, rate_hz: float, kind: str, storage: dict, effects: dict | None = None,
                    seed: int | None = None, source: str = "", multiplexed: bool = False,
                    placement=None, calibration=None, rig=None) -> dict:
    """The ``flexvox`` attribute block of a recording."""
    code = validate_code(code)
    m, n, K = code.shape
    identity = is_identity_code(code)
    return {
        "schema_version": SCHEMA_VERSION,
        "software_version": __version__,
        "created_utc": _now(),
        "kind": kind,
        "tile": [m, n],
        "K": K,
        "code": code.astype(int).tolist(),
        "order": order_from_code(code).tolist() if identity else None,
        "multiplexed": bool(multiplexed),
        "placement_order": None if placement is None else np.asarray(placement).tolist(),
        "rates": {"camera_hz": float(rate_hz), "subframe_hz": float(rate_hz) * K},
        "effects": effects or {},
        "seed": seed,
        "source": source,
        "storage": storage,
        "calibration": calibration,
        "rig": rig or {"kind": "simulated" if kind == "simulated" else "unknown"},
    }


class RecordingWriter:
    """Append frames to a new recording as they arrive.

    Each :meth:`append` writes the frame's chunk, then its per-frame values, then grows
    the arrays, so a recording interrupted between two appends holds every completed frame.
    """

    def __init__(self, path, *, height: int, width: int, dtype, attrs: dict, overwrite: bool = False):
        self.path = Path(path)
        if self.path.exists() and not overwrite:
            raise RecordingError(f"{self.path} already exists; choose another path or allow overwriting")
        dtype = np.dtype(dtype)
        if dtype not in (np.dtype("float32"), np.dtype("uint16")):
            raise RecordingError(f"frames must be float32 or uint16; got {dtype}")
        self.group = zarr.open_group(str(self.path), mode="w", zarr_format=3)
        self.group.attrs["flexvox"] = attrs
        self.frames = self.group.create_array("frames", shape=(0, height, width), chunks=(1, height, width),
                                              dtype=dtype, fill_value=0)
        self.per_frame = {
            name: self.group.create_array(name, shape=(0,), chunks=(4096,), dtype=_PER_FRAME_DTYPES[name],
                                          fill_value=0)
            for name in PER_FRAME
        }
        self.count = 0
        self._hw = (height, width)
        self._dtype = dtype

    def append(self, frame, *, frame_id: int, timestamp: float, dropped: bool = False) -> None:
        """Write one camera frame ``(H, W)`` and its per-frame values."""
        frame = np.asarray(frame)
        if frame.shape != self._hw:
            raise RecordingError(f"frame must have shape {self._hw}; got {frame.shape}")
        i = self.count
        self.frames.resize((i + 1, *self._hw))
        self.frames[i] = frame.astype(self._dtype, copy=False)
        for name, value in (("frame_id", frame_id), ("timestamp", timestamp), ("dropped", dropped)):
            arr = self.per_frame[name]
            arr.resize((i + 1,))
            arr[i] = value
        self.count = i + 1

    def write_ground_truth(self, video: np.ndarray) -> None:
        """Store the simulated ground truth ``(S, H, W)`` float32."""
        video = np.asarray(video, dtype=np.float32)
        gt = self.group.create_array("ground_truth", shape=video.shape, chunks=(1, *video.shape[1:]),
                                     dtype="float32", fill_value=0)
        gt[:] = video


def write_simulation(path, result, *, overwrite: bool = False) -> Path:
    """Write a :class:`~flexvox_core.simulate.SimulationResult` as a recording."""
    F, H, W = result.frames.shape
    attrs = recording_attrs(
        result.code, rate_hz=result.rate_hz, kind="simulated", storage=result.storage,
        effects=result.effects, seed=result.seed, source=result.source,
        multiplexed=result.multiplexed, placement=result.placement,
    )
    writer = RecordingWriter(path, height=H, width=W, dtype=result.frames.dtype, attrs=attrs, overwrite=overwrite)
    period = 1.0 / result.rate_hz
    for f in range(F):
        writer.append(result.frames[f], frame_id=f, timestamp=f * period, dropped=bool(result.dropped[f]))
    writer.write_ground_truth(result.ground_truth)
    return Path(path)


@dataclass
class Recording:
    """An opened, validated recording."""

    path: Path
    group: zarr.Group
    attrs: dict

    @property
    def frames(self) -> zarr.Array:
        """The raw frames ``(F, H, W)`` as stored (float32 or uint16 counts)."""
        return self.group["frames"]

    @property
    def code(self) -> np.ndarray:
        """The code ``(m, n, K)`` bool."""
        return np.asarray(self.attrs["code"], dtype=bool)

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per frame."""
        return int(self.attrs["K"])

    @property
    def n_frames(self) -> int:
        """Camera frames stored."""
        return int(self.frames.shape[0])

    @property
    def has_ground_truth(self) -> bool:
        """True for simulated recordings that hold the high-speed video."""
        return "ground_truth" in self.group

    def per_frame(self, name: str) -> np.ndarray:
        """``frame_id``, ``timestamp`` or ``dropped`` as a numpy array."""
        return np.asarray(self.group[name][:])

    def ground_truth(self) -> np.ndarray:
        """The simulated high-speed video ``(S, H, W)`` float32."""
        if not self.has_ground_truth:
            raise RecordingError(f"{self.path} holds no ground truth (a captured recording)")
        return np.asarray(self.group["ground_truth"][:])

    def normalised_frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``[start, stop)`` as float32 relative units (counts converted)."""
        from flexvox_core.simulate.simulator import normalise_frames

        return normalise_frames(np.asarray(self.frames[start:stop]), self.attrs["storage"])


def open_recording(path) -> Recording:
    """Open and validate a recording; :class:`RecordingError` says what is wrong."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such recording")
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:  # zarr raises several types for a damaged store
        raise RecordingError(f"{path}: not a readable Zarr store ({type(exc).__name__}: {exc})") from exc
    attrs = dict(group.attrs).get("flexvox")
    if not isinstance(attrs, dict):
        raise RecordingError(f"{path}: not a flexvox recording (no `flexvox` attributes)")
    version = attrs.get("schema_version")
    if version is None:
        raise RecordingError(f"{path}: the recording has no schema_version; it was not written by flexvox")
    if not isinstance(version, int) or version > SCHEMA_VERSION:
        raise RecordingError(
            f"{path}: schema version {version!r} is newer than this software reads ({SCHEMA_VERSION}); "
            "update flexvox"
        )
    rec = Recording(path, group, attrs)
    problems = validate_recording(rec)
    if problems:
        raise RecordingError(f"{path}: " + "; ".join(problems))
    return rec


def validate_recording(rec: Recording) -> list[str]:
    """Structural problems of a recording (empty when it is sound)."""
    problems = []
    missing = [k for k in _REQUIRED_ATTRS if k not in rec.attrs]
    if missing:
        return [f"missing attribute(s): {', '.join(missing)}"]
    try:
        code = validate_code(rec.attrs["code"])
    except ValueError as exc:
        return [f"bad code attribute: {exc}"]
    m, n, K = code.shape
    if [m, n] != list(rec.attrs["tile"]) or K != rec.attrs["K"]:
        problems.append(f"code shape {code.shape} disagrees with tile {rec.attrs['tile']} and K {rec.attrs['K']}")
    names = set(rec.group.array_keys())
    for name in ("frames", *PER_FRAME):
        if name not in names:
            problems.append(f"array `{name}` is missing")
    if problems:
        return problems
    F = rec.frames.shape[0]
    if rec.frames.ndim != 3:
        problems.append(f"`frames` must be (F, H, W); got {rec.frames.shape}")
    for name in PER_FRAME:
        if rec.group[name].shape != (F,):
            problems.append(f"`{name}` has {rec.group[name].shape[0]} entries for {F} frames")
    kind = rec.attrs["storage"].get("kind")
    if kind not in ("float", "counts"):
        problems.append(f"unknown storage kind {kind!r}")
    if "ground_truth" in names:
        gt = rec.group["ground_truth"].shape
        if gt != (F * K, *rec.frames.shape[1:]):
            problems.append(f"`ground_truth` {gt} does not match {F} frames of K = {K}")
    return problems
