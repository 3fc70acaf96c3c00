"""What a recording holds: the schema version, its arrays and the ``flexvox`` attribute block.

The layout is described in :mod:`flexvox_core.recording`. The per-frame checksum (:func:`values_crc`)
is part of the schema: every frame and ground-truth sub-frame carries the CRC-32 of its values as
stored (C order, little-endian bytes of the stored dtype).
"""

from __future__ import annotations

import datetime as _dt
import zlib

import numpy as np

from flexvox_core._version import __version__
from flexvox_core.codes import is_identity_code, order_from_code, validate_code

SCHEMA_VERSION = 2
"""Bumped when the layout changes in a way older readers cannot follow (2: per-frame CRCs)."""

PER_FRAME = ("frame_id", "timestamp", "dropped")
"""The per-frame arrays every schema has."""
PER_FRAME_DTYPES = {"frame_id": "int64", "timestamp": "float64", "dropped": "bool", "frame_crc": "uint32"}
"""The dtype of each per-frame array."""
WRITTEN_PER_FRAME = (*PER_FRAME, "frame_crc")
"""The per-frame arrays a writer of this schema writes."""
REQUIRED_ATTRS = ("schema_version", "tile", "K", "code", "rates", "storage")
"""Entries of the ``flexvox`` attribute block no recording can be read without."""

FRAME_AXES = ("t", "y", "x")
"""The ``dimension_names`` of ``frames`` (NGFF's axes; recordings written before they were added have none)."""


def values_crc(values: np.ndarray, dtype=None) -> int:
    """CRC-32 of an array's values as stored: C order, little-endian bytes of ``dtype``."""
    arr = np.asarray(values)
    dt = np.dtype(dtype or arr.dtype).newbyteorder("<")
    return zlib.crc32(np.ascontiguousarray(arr, dtype=dt).data) & 0xFFFFFFFF


def utc_now() -> str:
    """The current time in UTC, ISO 8601 to the second (the attributes' time stamps)."""
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
        "created_utc": utc_now(),
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


def frames_ngff(attrs: dict) -> dict:
    """The group's ``ome`` attribute: ``frames`` as an OME-Zarr image whose t step is one camera frame."""
    from flexvox_core import ngff

    rate = (attrs.get("rates") or {}).get("camera_hz")
    return ngff.image_attrs("frames", time_step=1.0 / float(rate) if rate else None, name="frames")
