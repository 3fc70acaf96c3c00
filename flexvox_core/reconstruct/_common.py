"""Validation shared by every reconstruction: camera frames, identity codes, dtypes."""

from __future__ import annotations

import logging
import os

import numpy as np

from flexvox_core.codes import code_from_order, is_identity_code, validate_code
from flexvox_core.forward import check_video
from flexvox_core.multiplex import MultiplexedCode, demultiplex

_logger = logging.getLogger(__name__)

_DTYPES = (np.float32, np.float64)


def refuse_recording(frames, call: str, instead: str, more: str = "") -> None:
    """Refuse a recording (its path, a ``Recording``, a ``CaptureReader``) given as ``frames`` to ``call``, which
    takes frames and a code, naming ``instead``, the call that takes the recording (read as an array it was
    "dtype <U..." or "dtype object", or "0 dimensions")."""
    # Told by their modules, not imported: the recording and capture-reader modules import the reconstructions.
    kind = (type(frames).__module__, type(frames).__name__)
    if isinstance(frames, str | os.PathLike):
        what = f"a path ({frames})"
    elif kind in (("flexvox_core.capture_reader", "CaptureReader"), ("flexvox_core.recording.reader", "Recording")):
        what = f"a {type(frames).__name__}"
    else:
        return
    raise TypeError(f"`frames` is {what}: a recording goes to {instead}, which reads its code and dropped frames; "
                    f"{call} takes frames (F, H, W) and a code (fv.read_capture(path)){more}")


def check_frames(frames) -> np.ndarray:
    """Camera frames ``(F, H, W)`` as a float array; ``ValueError`` naming a bad frame.

    float32 and float64 are kept, other numbers become float32. A NaN or infinite value
    raises ``ValueError`` naming the first camera frame that holds one (via
    :func:`flexvox_core.forward.check_video`). A recording (a path, a ``Recording``, a ``CaptureReader``) is a
    ``TypeError`` naming ``fv.reconstruct_video`` (:func:`refuse_recording`).
    """
    refuse_recording(frames, "each method's function", "fv.reconstruct_video(recording, method)")
    arr = np.asarray(frames)
    if arr.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {arr.ndim} dimensions {arr.shape}")
    if arr.shape[0] == 0 or arr.shape[1] == 0 or arr.shape[2] == 0:
        raise ValueError(f"`frames` must hold at least one frame of at least 1x1 pixels; got {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise ValueError(f"`frames` must hold numbers; got dtype {arr.dtype}")
    try:
        return check_video(arr, 1, name="frames")
    except ValueError as exc:  # K = 1: every "sub-frame" is a camera frame
        raise ValueError(str(exc).replace("sub-frame", "camera frame")) from exc


def check_identity_code(code) -> np.ndarray:
    """An ``(m, n, K)`` identity code, or ``ValueError`` saying to demultiplex first."""
    if isinstance(code, MultiplexedCode):
        raise ValueError(
            "`code` is a MultiplexedCode: demultiplex the capture first, e.g. "
            "frames, code = as_identity_capture(frames, mcode)"
        )
    c = validate_code(code)
    if not is_identity_code(c):
        raise ValueError(
            "`code` must be an identity code (each pixel open in exactly one slot, each slot "
            "used once); got a multiplexed code: demultiplex the capture first "
            "(flexvox_core.reconstruct.as_identity_capture)"
        )
    return c


def check_dtype(dtype) -> type:
    """``np.float32`` or ``np.float64``, or ``ValueError``."""
    try:
        dt = np.dtype(dtype)
    except TypeError:
        raise ValueError(f"`dtype` must be float32 or float64; got {dtype!r}") from None
    if dt not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"`dtype` must be float32 or float64; got {dt}")
    return dt.type


def as_identity_capture(frames, code_or_multiplexed) -> tuple[np.ndarray, np.ndarray]:
    """Bring a capture into the form every reconstruction takes: an identity-code capture.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
        Camera frames.
    code_or_multiplexed : ndarray (m, n, K) or MultiplexedCode
        An identity code (returned unchanged), or the S-matrix code of the capture, which
        is demultiplexed with :func:`flexvox_core.multiplex.demultiplex`.

    Returns
    -------
    frames : ndarray, shape (F, H, W), float
        The identity-code capture (float32 unless the input was float64).
    code : ndarray, shape (m, n, K), bool
        Its identity code (for a multiplexed capture, the code of ``placement``).

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import capture, multiplexed_code
    >>> mc = multiplexed_code((1, 3), placement=[[0, 1, 2]])
    >>> video = np.full((3, 2, 3), 0.5, dtype=np.float32)
    >>> f, c = as_identity_capture(capture(video, mc.code), mc)
    >>> np.allclose(f, 0.5), c.shape
    (True, (1, 3, 3))
    """
    if isinstance(code_or_multiplexed, MultiplexedCode):
        f = check_frames(frames)
        _logger.debug("demultiplexing %d frames of a %s S-matrix code", f.shape[0], code_or_multiplexed.tile)
        return demultiplex(f, code_or_multiplexed), code_from_order(code_or_multiplexed.placement)
    return check_frames(frames), check_identity_code(code_or_multiplexed)
