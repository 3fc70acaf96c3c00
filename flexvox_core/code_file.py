"""Code files: what ``flexvox design -o CODE.json`` writes, read back for verification and capture.

A code file is a JSON object with an ``order`` (m rows of slot numbers, an identity code), or a
``code`` (m × n × K of 0/1), or both; a multiplexed code (``flexvox design --multiplexed``) also
has ``"multiplexed": true``, its ``tile`` and the ``placement_order`` its demultiplexed slots take.

- :func:`read_code` gives the raw ``(m, n, K)`` array whatever it holds (``flexvox design --verify``
  reports what is wrong with it);
- :func:`load_shutter_code` gives what a capture can shutter with: an identity code, or the
  :class:`~flexvox_core.multiplex.MultiplexedCode` it describes, and refuses anything else.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexvox_core.codes import code_from_order, is_identity_code, validate_code
from flexvox_core.json_file import read_json
from flexvox_core.multiplex import MultiplexedCode, multiplexed_code


class CodeFileError(ValueError):
    """A code file cannot be read, or does not hold a code that can be used; the message says why."""


def _payload(path: Path) -> dict:
    payload = read_json(path, CodeFileError)
    if not isinstance(payload, dict) or (payload.get("code") is None and payload.get("order") is None):
        raise CodeFileError(f"{path}: a code file needs an `order` (m rows of slots) or a `code` (m x n x K 0/1)")
    return payload


def read_code(path) -> np.ndarray:
    """The raw ``(m, n, K)`` array of a code file (its ``code``, else the code of its ``order``)."""
    path = Path(path)
    payload = _payload(path)
    try:
        if payload.get("code") is not None:
            return np.asarray(payload["code"])
        return code_from_order(payload["order"])
    except ValueError as exc:
        raise CodeFileError(f"{path}: {exc}") from None


def load_shutter_code(path) -> np.ndarray | MultiplexedCode:
    """A code a capture can shutter with: an identity code ``(m, n, K)`` bool, or a multiplexed code.

    Raises
    ------
    CodeFileError
        For an unreadable file, a malformed code, or a code that is neither an identity code nor
        the S-matrix code of ``flexvox design --multiplexed``.
    """
    path = Path(path)
    payload = _payload(path)
    raw = read_code(path)
    try:
        code = validate_code(raw)
    except ValueError as exc:
        raise CodeFileError(f"{path}: {exc}") from None
    if payload.get("multiplexed"):
        try:
            tile = tuple(payload.get("tile") or code.shape[:2])
            mc = multiplexed_code(tile, placement=payload.get("placement_order"))
        except (TypeError, ValueError) as exc:
            raise CodeFileError(f"{path}: not a multiplexed code flexvox can demultiplex: {exc}") from None
        if mc.code.shape != code.shape or not np.array_equal(mc.code, code):
            raise CodeFileError(f"{path}: its `code` is not the S-matrix code of its tile (write it again with "
                                "flexvox design --multiplexed)")
        return mc
    tile = payload.get("tile")
    if tile is not None and (not isinstance(tile, list | tuple) or list(tile) != list(code.shape[:2])):
        raise CodeFileError(f"{path}: its `tile` {tile!r} disagrees with its code's {code.shape[0]}x{code.shape[1]}")
    if not is_identity_code(code):
        raise CodeFileError(f"{path}: not an identity code (each pixel open in exactly one slot, each slot once per "
                            "tile) and not marked multiplexed: capture cannot shutter with it (check it with "
                            "flexvox design --verify)")
    if payload.get("order") is not None and payload.get("code") is not None:
        try:
            from_order = code_from_order(payload["order"])
        except ValueError as exc:
            raise CodeFileError(f"{path}: its `order`: {exc}") from None
        if not np.array_equal(from_order, code):
            raise CodeFileError(f"{path}: its `order` and its `code` disagree")
    return code


__all__ = ["CodeFileError", "load_shutter_code", "read_code"]
