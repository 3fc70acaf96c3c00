"""The samples' mask of an identity-code capture, made a band of sub-frames at a time (no (S, H, W) volume)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flexvox_core.forward import tiled_code


class SampleMask:
    """Where an identity code samples the video, sub-frames ``t0`` to ``t1`` at a time
    (:class:`~flexvox_core.planes.Bands`): the code's lattice, repeated every K sub-frames, and no sample in
    a dropped frame's sub-frames. Holds one period (K, H, W) of it.

    Parameters
    ----------
    code : ndarray (m, n, K)
        The identity code.
    shape : (S, H, W)
        The volume's shape; S a multiple of K.
    missing : ndarray (S / K,) bool, optional
        Dropped frames.
    """

    def __init__(self, code: np.ndarray, shape: tuple[int, int, int], missing: np.ndarray | None = None) -> None:
        S, H, W = (int(v) for v in shape)
        self.period = tiled_code(code, H, W)
        K = self.period.shape[0]
        if S < 1 or S % K:
            raise ValueError(f"`shape` S = {S} must be a positive multiple of K = {K}")
        self.dropped = np.zeros(S // K, bool) if missing is None else np.asarray(missing, bool)
        if self.dropped.shape != (S // K,):
            raise ValueError(f"`missing` must hold one flag per frame ({S // K}); got shape {self.dropped.shape}")
        self._shape = (S, H, W)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S, H, W)."""
        return self._shape

    def band(self, t0: int, t1: int) -> npt.NDArray[np.bool_]:
        """Sub-frames ``t0`` to ``t1`` (exclusive) of the mask, a new C-contiguous bool array."""
        S = self._shape[0]
        if not 0 <= t0 <= t1 <= S:
            raise ValueError(f"sub-frames {t0} to {t1} are not within the mask's {S}")
        K = self.period.shape[0]
        t = np.arange(t0, t1)
        out: npt.NDArray[np.bool_] = self.period[t % K]
        out[self.dropped[t // K]] = False
        return out
