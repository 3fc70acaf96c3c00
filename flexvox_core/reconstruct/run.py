"""One entry point for every motion-free reconstruction, run in time chunks with overlap.

A :class:`Method` names the reconstruction and its knobs; :func:`reconstruct` runs it on a
capture, splitting long captures into chunks of camera frames with the overlap the method
needs on each side (so the result equals the whole-volume one), reporting progress after
each chunk, and returning the full ``(F·K, H, W)`` float32 video clipped to [0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from flexvox_core.codes import verify
from flexvox_core.divisions import Division
from flexvox_core.motion.pipeline import DEFAULT_TIME as MA_TIME
from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, SOLVERS, diffuse, sigmas
from flexvox_core.reconstruct.gaptv import gap_tv
from flexvox_core.reconstruct.rebin import rebin

METHODS = ("rebin", "diffusion", "gap-tv", "motion-aware")


@dataclass(frozen=True)
class Method:
    """A reconstruction and its knobs.

    Attributes
    ----------
    name : {"rebin", "diffusion", "gap-tv"}
    block : Division, optional
        Re-binning division (default: the supported one with TR closest to √K).
    interpolate : bool
        Re-binning with interpolation between block centres.
    tensor, time, solver
        Diffusion tensor (cx, cy, ct), diffusion time n (None: the method's default, 1.5 for
        diffusion, 5 for motion-aware), solver (nc, explicit, steady).
    iterations, tv_weight, tv_iterations
        GAP-TV.
    flow, passes, refine_time, slow_reach
        Motion-aware: flow backend, passes, variable-tensor refinement time, reach of the slow
        voxels' gather in sampling periods (None: the pipeline's default,
        :data:`flexvox_core.motion.pipeline.SLOW_REACH`; 0: no long gather). Its diffusion
        time is ``time``; see :func:`flexvox_core.motion.motion_aware`.
    """

    name: str = "diffusion"
    block: Division | None = None
    interpolate: bool = True
    tensor: tuple[float, float, float] = DEFAULT_TENSOR
    time: float | None = None
    solver: str = "nc"
    iterations: int = 40
    tv_weight: float = 0.3
    tv_iterations: int = 4
    flow: str = "dis"
    passes: int = 1
    refine_time: float = 0.0
    slow_reach: float | None = None

    def __post_init__(self):
        if self.name not in METHODS:
            raise ValueError(f"`method` must be one of {', '.join(METHODS)}; got {self.name!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"`solver` must be one of {', '.join(SOLVERS)}; got {self.solver!r}")
        if self.time is None:  # each method's own default diffusion time
            object.__setattr__(self, "time", MA_TIME if self.name == "motion-aware" else DEFAULT_TIME)
        sigmas(self.tensor, self.time)  # validates both
        r = self.slow_reach
        if r is not None and (isinstance(r, bool) or not isinstance(r, int | float) or not math.isfinite(r) or r < 0):
            raise ValueError(f"`slow_reach` must be a number >= 0 (sampling periods) or None; got {r!r}")

    def motion_kwargs(self) -> dict:
        """Keyword arguments of :func:`flexvox_core.motion.motion_aware` for this method."""
        kw = {"flow": self.flow, "passes": self.passes, "time": self.time, "refine_time": self.refine_time}
        if self.slow_reach is not None:
            kw["slow_reach"] = float(self.slow_reach)
        return kw

    def label(self) -> str:
        """Short human-readable description."""
        if self.name == "rebin":
            b = "default" if self.block is None else self.block.label
            return f"rebin {b}{' interp' if self.interpolate else ''}"
        if self.name == "gap-tv":
            return f"gap-tv {self.iterations} it"
        if self.name == "motion-aware":
            extra = f" +refine {self.refine_time:g}" if self.refine_time else ""
            extra += f" x{self.passes}" if self.passes > 1 else ""
            extra += f" slow-reach {self.slow_reach:g}" if self.slow_reach is not None else ""
            return f"motion-aware {self.flow} n={self.time:g}{extra}"
        t = ",".join(f"{c:g}" for c in self.tensor)
        return f"diffusion {self.solver} ({t}) n={self.time:g}"

    def as_dict(self) -> dict:
        """Metadata form."""
        d = asdict(self)
        d["block"] = None if self.block is None else self.block.label
        return d


def default_block(code) -> Division:
    """The supported division whose TR is closest to √K (a balanced space-time trade),
    squarest block first among ties (2×2×4 rather than 1×4×4 for a 4×4 tile)."""
    supported = verify(code).supported
    if not supported:
        raise ValueError("the code supports no division; re-binning is impossible")
    K = code.shape[2]
    return min(supported, key=lambda d: (round(abs(math.log(d.tr) - 0.5 * math.log(K)), 9), abs(d.a - d.b), -d.tr))


def overlap_frames(method: Method, K: int) -> int | None:
    """Camera frames of context each chunk needs on each side (None: cannot be chunked)."""
    if method.name == "gap-tv":
        return 0  # each measurement is reconstructed on its own
    if method.name == "rebin":
        return 1 if method.interpolate else 0
    if method.name == "motion-aware":
        # High-TR nc, the K-average gates, flow smoothing; still voxels: 4 σ = 2 periods; slow voxels:
        # their reach in periods (the default 0.75 fits in 3) and the flow and guide it reads there.
        return 3 if method.slow_reach is None else max(3, math.ceil(method.slow_reach) + 2)
    if method.solver == "steady":
        return None  # a global linear solve
    sig_t = sigmas(method.tensor, method.time)[2]
    reach = 4 * sig_t + K  # the Gaussian's support, plus one frame for the nearest-sample fallback
    if method.solver == "explicit":
        reach *= 2  # the nc start, then diffusion of the same time
    return max(1, math.ceil(reach / K))


def _run(frames: np.ndarray, code: np.ndarray, method: Method, value_range=None) -> np.ndarray:
    if method.name == "rebin":
        block = method.block or default_block(code)
        return rebin(frames, code, block, interpolate=method.interpolate)
    if method.name == "gap-tv":
        # One measurement at a time, as the SCI literature (and its reference figures) does.
        return np.concatenate([
            gap_tv(frames[f: f + 1], code, iterations=method.iterations, tv_weight=method.tv_weight,
                   tv_iterations=method.tv_iterations)
            for f in range(frames.shape[0])
        ])
    if method.name == "motion-aware":
        from flexvox_core.motion import motion_aware

        return motion_aware(frames, code, **method.motion_kwargs(), value_range=value_range).video
    return diffuse(frames, code, tensor=method.tensor, time=method.time, solver=method.solver)


def reconstruct(
    frames,
    code,
    method: Method = Method(),
    *,
    chunk_frames: int | None = 16,
    progress: Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """Reconstruct the full video ``(F·K, H, W)`` float32 in [0, 1] from an identity capture.

    Parameters
    ----------
    frames : ndarray, shape (F, H, W)
    code : ndarray, shape (m, n, K), identity code
    method : Method
    chunk_frames : int or None
        Camera frames per chunk (None: all at once). Chunks overlap by
        :func:`overlap_frames` so the result does not depend on the chunking.
    progress : callable(done_frames, total_frames), optional
        Called after each chunk.
    """
    f = np.asarray(frames)
    if f.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {f.ndim} dimensions {f.shape}")
    code = np.asarray(code, dtype=bool)
    K = code.shape[2]
    F = f.shape[0]
    ov = overlap_frames(method, K)
    if chunk_frames is not None and chunk_frames < 1:
        raise ValueError(f"`chunk_frames` must be >= 1 or None; got {chunk_frames}")
    if chunk_frames is None or ov is None or F <= chunk_frames:
        out = _run(f, code, method)
        if progress:
            progress(F, F)
    else:
        out = np.empty((F * K, *f.shape[1:]), np.float32)
        # Motion-aware scales a range weight by the samples' range: the whole recording's, in every chunk.
        value_range = (float(np.min(f)), float(np.max(f))) if method.name == "motion-aware" else None
        for start in range(0, F, chunk_frames):
            stop = min(F, start + chunk_frames)
            lo, hi = max(0, start - ov), min(F, stop + ov)
            part = _run(f[lo:hi], code, method, value_range)
            out[start * K: stop * K] = part[(start - lo) * K: (stop - lo) * K]
            if progress:
                progress(stop, F)
    return np.clip(out, 0, 1).astype(np.float32, copy=False)
