"""Reading a small JSON file (a code, a calibration) with errors that say which file and what is wrong."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

MAX_BYTES = 64 * 2**20
"""The largest JSON file read (a code or a calibration is a few kB; a device like /dev/zero never ends)."""


def read_json(path, error: type[Exception] = ValueError):
    """The parsed content of the JSON file ``path`` (at most :data:`MAX_BYTES`).

    Raises
    ------
    error
        ``"{path}: no such file"``, ``"{path} is a folder, ..."``, ``"{path}: not a code or calibration file: a binary
        file, ..."``, ``"{path}: cannot read: ..."``, ``"{path}: not valid JSON (... at line N)"`` or
        ``"{path}: ... too large / too deeply nested"`` (``error`` is the caller's exception class, e.g. a
        ``ValueError`` subclass).
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except IsADirectoryError:  # had been "cannot read: [Errno 21] Is a directory"
        raise error(f"{path} is a folder, not a code or calibration file (a JSON file)") from None
    except OSError as exc:
        raise error(f"{path}: cannot read: {exc}") from exc
    if len(raw) > MAX_BYTES:
        raise error(f"{path}: more than {MAX_BYTES // 2**20} MiB; not a code or calibration file")
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:  # had been "cannot read: 'utf-8' codec can't decode byte 0x93 in position 0"
        raise error(f"{path}: not a code or calibration file: a binary file, where those are JSON text") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise error(f"{path}: not a code or calibration file (its JSON is nested too deeply to read)") from None
    except ValueError as exc:  # e.g. an integer of thousands of digits
        raise error(f"{path}: not valid JSON ({exc})") from None


def finite_or_null(value: Any) -> Any:
    """``value`` for strict JSON: every number that is not finite (NaN, ±infinity) as None (``null``), NumPy scalars as
    Python numbers, tuples as lists, recursively through dicts and lists. JSON has no NaN or infinity: Python writes
    them as ``NaN`` and ``Infinity``, which strict parsers (``JSON.parse``, ``jq``) refuse.

    >>> finite_or_null({"rms_px": float("nan"), "slip_s": float("inf"), "K": 16, "sweep": [(0, 1.5)]})
    {'rms_px': None, 'slip_s': None, 'K': 16, 'sweep': [[0, 1.5]]}
    """
    if isinstance(value, dict):
        return {k: finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_null(v) for v in value]
    if hasattr(value, "item") and getattr(value, "shape", None) == ():  # a NumPy scalar or 0-d array
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
