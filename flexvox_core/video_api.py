"""``flexvox_core.reconstruct_video``: the package's one-call reconstruction (the name ``reconstruct`` is the
subpackage of the algorithms, :mod:`flexvox_core.reconstruct`)."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from flexvox_core.progress import Progress

if TYPE_CHECKING:
    from flexvox_core.methods import Method

__all__ = ["reconstruct_video"]


def reconstruct_video(frames: Any, code: ArrayLike | None = None, method: Method | str | None = None, *,
                      chunk_frames: int | None = 16,
                      progress: bool | Progress | None = False, missing: ArrayLike | None = None,
                      device: str = "cpu", origin: tuple[int, int] | None = None, white: float | None = None,
                      **options: Any) -> np.ndarray:
    """The high-speed video ``(F·K, H, W)`` float32 in [0, 1] of a capture (:func:`flexvox_core.methods.run`).

    Parameters
    ----------
    frames : ndarray (F, H, W), Recording, str or Path
        The camera frames. Floats are relative units (white = 1); integer counts (what a camera gives) are
        divided by their dtype's largest value (uint8: 255, uint16: 65535) unless ``white`` gives the white level
        (:mod:`flexvox_core.intensity`). Or a :class:`~flexvox_core.recording.Recording`
        (``fv.open_recording(path)``), or its path, in place of frames and code: its code, its counts'
        normalisation and its dropped frames come with it (``reconstruct_video(rec)``,
        ``reconstruct_video("run1.zarr", "diffusion")``).
    code : ndarray (m, n, K)
        The code they were captured with: an identity code, or a multiplexed one for a method that takes it
        (any other code is refused: :func:`flexvox_core.codes.check_reconstructable`). Left out with a Recording.
    method : Method or str, optional
        Default motion-aware. A method's name with its options as keywords (``"gap-tv", iterations=40``) or a
        :class:`~flexvox_core.methods.Method` (``fv.Method("rebin", block="2x2x4")``); ``fv.METHODS`` lists the
        names.
    chunk_frames : int or None, keyword-only
        Camera frames per chunk (None: all at once); the result does not depend on it.
    progress : bool or callable(done_frames, total_frames), keyword-only
        True: a ``tqdm.auto`` bar (a widget in Jupyter with ``ipywidgets`` installed, text in a terminal); a
        callable is called after each chunk; False or None: nothing (:mod:`flexvox_core.progress`).
    missing : ndarray (F,) bool, optional, keyword-only
        Frames the camera dropped (``Recording.dropped``): bridged from both sides. A Recording brings its own.
    device : {"cpu", "cuda", "auto"}, keyword-only
        Where it runs; ``auto`` takes a usable NVIDIA GPU.
    origin : (int, int), optional, keyword-only
        For frames cropped from the camera frame (a region of a recording): the crop's top-left pixel
        ``(row, col)`` in the camera frame. The code's phase follows it: pixel ``(y, x)`` of the crop uses
        ``code[(y + row) % m, (x + col) % n]``. Default (0, 0): the frames start on the tile grid.
    white : float, optional, keyword-only
        The count that stands for white in integer frames (a 12-bit camera's: 4095); float frames are divided by
        it when given.
    **options
        The method's options, with a method's name or the default method (``time=3``).

    Returns
    -------
    ndarray (F·K, H, W) float32

    Raises
    ------
    TypeError
        A ``method`` that is neither an ``fv.Method`` nor a method's name, options beside an ``fv.Method``,
        a code or ``missing`` beside a Recording, or a ``progress`` that is not a bool or a callable.
    ValueError
        Frames, a code, an origin or an option that break their rule; the message names the value and the rule.
    RecordingError
        A path that holds no readable recording.

    Examples
    --------
    >>> import flexvox_core as fv
    >>> code = fv.code_from_order(fv.sequential_order((2, 2)))
    >>> frames = fv.capture(fv.render_scene("balls", 8, 16, 16), code)
    >>> fv.reconstruct_video(frames, code, "diffusion", time=2).shape
    (8, 16, 16)
    """
    from flexvox_core.capture_reader import CaptureReader, open_capture
    from flexvox_core.methods import Method, run
    from flexvox_core.methods.runner import as_method
    from flexvox_core.recording import Recording

    if isinstance(frames, str | os.PathLike):
        frames = open_capture(frames)
    if not isinstance(frames, Recording | CaptureReader):
        return run(frames, code, method, chunk_frames=chunk_frames, progress=progress, missing=missing,
                   device=device, origin=origin, white=white, **options).video
    if method is None and isinstance(code, str | Method):
        code, method = None, code  # reconstruct_video(recording, "diffusion"): the method in the code's place
    for name, value, why in (("code", code, "its code"), ("missing", missing, "its dropped frames"),
                             ("white", white, "the normalisation of its counts (its `storage` attributes)"),
                             ("origin", origin, "its whole camera frame (crop the reconstruction instead)")):
        if value is not None:
            raise TypeError(f"a Recording carries {why}: give the recording and the method alone, "
                            f"reconstruct_video(recording, method); got `{name}` as well")
    reader = frames if isinstance(frames, CaptureReader) else CaptureReader(frames)
    video: np.ndarray = reader.run(as_method(method, options), chunk_frames=chunk_frames, progress=progress,
                                   device=device).video
    return video
