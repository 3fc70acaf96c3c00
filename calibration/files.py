"""Versioned calibration files (JSON): what they hold, and refusing the wrong rig's.

Every file is a JSON object::

    {"format": "flexvox-calibration", "version": 1, "created": "2026-11-21T10:00:00+00:00",
     "software": "flexvox 0.x", "rig": {"name", "camera", "projector", "camera_size", "projector_size"},
     ...the body...}

A file with a newer version than this software reads is refused (upgrade flexvox); one made
for another rig, camera or resolution is refused with a message that names the difference.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

import numpy as np

from flexvox_calibration.errors import CalibrationError, CalibrationFileError, CalibrationMismatchError
from flexvox_core.json_file import finite_or_null, read_json

CALIBRATION_FORMAT = "flexvox-calibration"
CALIBRATION_VERSION = 1


def _software() -> str:
    from flexvox_core import __version__

    return f"flexvox {__version__}"


def _identity_dict(identity) -> dict:
    if hasattr(identity, "as_dict"):
        return identity.as_dict()
    if isinstance(identity, dict):
        return dict(identity)
    raise CalibrationError(f"`identity` must be a RigIdentity; got {type(identity).__name__}")


def write_versioned(path, fmt: str, version: int, identity, body: dict, *, overwrite: bool = False,
                    now=None) -> Path:
    """Write ``body`` with the format header, the rig's identity and the date.

    Atomically (a temporary sibling, flushed, renamed into place): a failed write leaves an old
    file as it was. ``overwrite=False`` refuses an existing file (the command line's default; GUI
    file dialogs ask the operator themselves). Strict JSON: a number that is not finite (a value a step did not
    measure, a slip time that is infinite without drift) is written as ``null``
    (:func:`flexvox_core.json_file.finite_or_null`).
    """
    from flexvox_core.output_files import OutputError, write_text_atomic

    path = Path(path)
    when = now or _dt.datetime.now(_dt.UTC)
    payload = {"format": fmt, "version": version, "created": when.isoformat(timespec="seconds"),
               "software": _software(), "rig": _identity_dict(identity), **body}
    try:
        write_text_atomic(path, json.dumps(finite_or_null(payload), indent=1, allow_nan=False) + "\n",
                          overwrite=overwrite)
    except OutputError as exc:
        raise CalibrationFileError(str(exc)) from None
    except OSError as exc:
        raise CalibrationFileError(f"cannot write {path}: {exc.strerror or exc}") from exc
    return path


def read_versioned(path, fmt: str, version: int) -> dict:
    """Read a file written by :func:`write_versioned`, checking its format and version."""
    path = Path(path)
    data = read_json(path, CalibrationFileError)
    if not isinstance(data, dict) or data.get("format") != fmt:
        got = data.get("format") if isinstance(data, dict) else type(data).__name__
        what = "it names no `format`" if got is None else f"its format is {got!r}"
        raise CalibrationFileError(f"{path}: not a {fmt} file ({what})")
    v = data.get("version")
    if not isinstance(v, int) or v < 1:
        raise CalibrationFileError(f"{path}: missing or bad `version` {v!r}")
    if v > version:
        raise CalibrationFileError(f"{path}: {fmt} version {v} is newer than this flexvox reads (version "
                                   f"{version}): upgrade flexvox")
    if not isinstance(data.get("rig"), dict):
        raise CalibrationFileError(f"{path}: missing the `rig` it was made for")
    return data


def check_identity(data: dict, identity, path) -> None:
    """Refuse a file made for another rig or resolution (:class:`CalibrationMismatchError`)."""
    want = _identity_dict(identity)
    have = data["rig"]
    for key, what in (("camera_size", "camera resolution"), ("projector_size", "projector resolution")):
        size = have.get(key, [])
        if not (isinstance(size, list) and all(isinstance(v, int) and not isinstance(v, bool) for v in size)):
            raise CalibrationFileError(f"{path}: `rig.{key}` must be [rows, columns] in pixels, the {what} it was "
                                       f"made for; got {size!r}")
        if list(size) != list(want[key]):
            a = "x".join(str(v) for v in have.get(key, [])) or "unknown"
            b = "x".join(str(v) for v in want[key])
            raise CalibrationMismatchError(
                f"{path} was made for a {what} of {a}, this rig's is {b}: calibrate this rig "
                "(flexvox calibrate) instead of reusing it")
    layout_had, layout_want = have.get("pixel_layout", "square"), want.get("pixel_layout", "square")
    if layout_had != layout_want:
        raise CalibrationMismatchError(
            f"{path} was made with the projector's pixel layout {layout_had!r}, this rig declares {layout_want!r} "
            "(rig profile [projector] pixel_layout): its homography is in the other layout's coordinates; "
            "calibrate again")
    for key, what in (("name", "rig"), ("camera", "camera"), ("projector", "projector")):
        if have.get(key) != want[key]:
            hint = ""
            if key == "name" and all(str(n).startswith("simulated rig (mock") for n in (have.get(key), want[key])):
                hint = " (or open the simulated rig with the seed it was made on: --seed)"
            raise CalibrationMismatchError(
                f"{path} was made for {what} {have.get(key)!r}, not {want[key]!r}: calibrate this rig "
                f"(flexvox calibrate) instead of reusing it{hint}")


def save_calibration(path, result, identity, *, sync=None, allow_partial: bool = False, overwrite: bool = False,
                     now=None) -> Path:
    """Write a homography calibration (and optionally its sync measurement).

    Parameters
    ----------
    path : str or Path
    result : HomographyResult
        Must be successful (``partial`` is accepted with ``allow_partial``, and recorded).
    identity : RigIdentity
    sync : SyncResult, optional
    allow_partial : bool
    overwrite : bool
        Replace an existing file (atomically); without it an existing file is refused.
    now : datetime, optional
        The date recorded (default: now, UTC).

    Raises
    ------
    CalibrationError
        For a failed result: a bad calibration is never written. :class:`CalibrationFileError`
        for an existing file without ``overwrite`` or a write that failed (an old file stays).
    """
    from flexvox_calibration.homography import HomographyResult

    if not isinstance(result, HomographyResult):
        raise CalibrationError(f"`result` must be a HomographyResult; got {type(result).__name__}")
    if not (result.success or (allow_partial and result.status == "partial")):
        raise CalibrationError(f"refusing to save a failed calibration ({result.status}): {result.message}")
    want = _identity_dict(identity)
    if list(want["camera_size"]) != list(result.camera_size) or \
            list(want["projector_size"]) != list(result.projector_size):
        raise CalibrationMismatchError("the calibration's resolutions do not match the rig identity given")
    body = {"homography": {"projector_to_camera": result.homography.tolist(),
                           "camera_to_projector": (np.linalg.inv(result.homography)
                                                   / np.linalg.inv(result.homography)[2, 2]).tolist()},
            "quality": {k: v for k, v in result.summary().items() if k != "homography"},
            "sync": None if sync is None else sync.summary()}
    return write_versioned(path, CALIBRATION_FORMAT, CALIBRATION_VERSION, identity, body, overwrite=overwrite,
                           now=now)


def load_calibration(path, identity=None) -> dict:
    """Read a calibration file; with ``identity``, refuse one made for another rig.

    Returns
    -------
    dict
        The file's content, with ``homography`` → ``projector_to_camera`` as a float64
        ``(3, 3)`` array under the key ``"H"``.
    """
    data = read_versioned(path, CALIBRATION_FORMAT, CALIBRATION_VERSION)
    if identity is not None:
        check_identity(data, identity, path)
    try:
        h = np.asarray(data["homography"]["projector_to_camera"], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        raise CalibrationFileError(f"{path}: missing or bad `homography.projector_to_camera`") from None
    if h.shape != (3, 3) or not np.isfinite(h).all():
        raise CalibrationFileError(f"{path}: `homography.projector_to_camera` must be a finite 3x3 matrix")
    data["H"] = h
    return data
