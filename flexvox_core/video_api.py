"""``flexvox_core.reconstruct_video``: the package's one-call reconstruction (the name ``reconstruct`` is the
subpackage of the algorithms, :mod:`flexvox_core.reconstruct`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from flexvox_core.methods import Method

__all__ = ["reconstruct_video"]


def reconstruct_video(frames: ArrayLike, code: ArrayLike, method: Method | None = None, *,
                      chunk_frames: int | None = 16,
                      progress: bool | Callable[[int, int], None] | None = False, missing: ArrayLike | None = None,
                      device: str = "cpu") -> np.ndarray:
    """The high-speed video ``(F·K, H, W)`` float32 in [0, 1] of a capture: :func:`flexvox_core.methods.reconstruct`.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The camera frames (relative units: ``Recording.normalised_frames()``, ``read_capture``).
    code : ndarray (m, n, K)
        The code they were captured with.
    method : Method, optional
        Default ``Method()`` (motion-aware); ``Method("diffusion")``, ``Method("rebin", block=...)``, ...
    chunk_frames : int or None, keyword-only
        Camera frames per chunk (None: all at once); the result does not depend on it.
    progress : bool or callable(done_frames, total_frames), keyword-only
        True: a ``tqdm.auto`` bar (a widget in Jupyter, text in a terminal); a callable is called after each
        chunk; False or None: nothing.
    missing : ndarray (F,) bool, optional, keyword-only
        Frames the camera dropped (``Recording.dropped``): bridged from both sides.
    device : {"cpu", "cuda", "auto"}, keyword-only
        Where it runs; ``auto`` takes a usable NVIDIA GPU.

    Returns
    -------
    ndarray (F·K, H, W) float32

    Examples
    --------
    >>> import flexvox_core as fv
    >>> code = fv.code_from_order(fv.sequential_order((2, 2)))
    >>> frames = fv.capture(fv.render_scene("balls", 8, 16, 16), code)
    >>> fv.reconstruct_video(frames, code, fv.Method("diffusion")).shape
    (8, 16, 16)
    """
    from flexvox_core.methods import reconstruct

    if progress is not True:
        return reconstruct(frames, code, method, chunk_frames=chunk_frames, progress=progress or None,
                           missing=missing, device=device)
    from tqdm.auto import tqdm  # type: ignore[import-untyped]

    with tqdm(total=np.shape(frames)[0], unit="frame", desc="reconstruct", leave=False) as bar:
        def update(done: int, total: int) -> None:
            bar.update(done - bar.n)

        return reconstruct(frames, code, method, chunk_frames=chunk_frames, progress=update, missing=missing,
                           device=device)
