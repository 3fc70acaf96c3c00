"""Interchangeable dense optical-flow backends with named parameters (no positional magic).

The paper's §4, step 2 (it used Brox et al.'s flow; these are OpenCV's dense methods).

Each backend is a small frozen dataclass whose fields are the method's parameters and
whose ``__call__(a, b)`` takes two uint8 images ``(H, W)`` and returns the flow from a to b,
``(H, W, 2)`` float32. The OpenCV object is built per call, so backends are thread-safe.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import cv2
import numpy as np


@dataclass(frozen=True)
class DisFlow:
    """DIS (Kroeger et al. 2016) with variational refinement, which minimises the Brox et al.
    2004 energy (brightness + gradient constancy, smoothness) — the default.

    ``preset`` picks DIS's patch search (ultrafast, fast, medium); ``finest_scale`` (the finest pyramid level
    searched, 0: full size), ``patch_size``, ``patch_stride`` and ``gradient_descent_iterations`` override the
    preset's (None: the preset's; the names and meanings of :class:`flexvox_core.gpu.dis.DisParams`); the
    refinement weights ``alpha`` (smoothness), ``delta`` (colour constancy), ``gamma`` (gradient constancy).
    """

    name = "dis"
    preset: str = "medium"
    variational_iterations: int = 5
    alpha: float = 20.0
    delta: float = 5.0
    gamma: float = 10.0
    finest_scale: int | None = None
    patch_size: int | None = None
    patch_stride: int | None = None
    gradient_descent_iterations: int | None = None

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        presets = {"ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST, "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
                   "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM}
        dis = cv2.DISOpticalFlow_create(presets[self.preset])
        dis.setVariationalRefinementIterations(int(self.variational_iterations))
        dis.setVariationalRefinementAlpha(float(self.alpha))
        dis.setVariationalRefinementDelta(float(self.delta))
        dis.setVariationalRefinementGamma(float(self.gamma))
        dis.setUseSpatialPropagation(True)
        if self.patch_size is not None:
            dis.setPatchSize(int(self.patch_size))
        if self.finest_scale is not None:
            dis.setFinestScale(dis_finest_scale(a.shape, int(self.finest_scale), dis.getPatchSize()))
        if self.patch_stride is not None:
            dis.setPatchStride(int(self.patch_stride))
        if self.gradient_descent_iterations is not None:
            dis.setGradientDescentIterations(int(self.gradient_descent_iterations))
        return dis.calc(a, b, None)

    def check(self) -> None:
        if self.preset not in ("ultrafast", "fast", "medium"):
            raise ValueError(f"dis.preset must be ultrafast, fast or medium; got {self.preset!r}")
        _nonneg(self, "variational_iterations", "alpha", "delta", "gamma")
        for name, lo in (("finest_scale", 0), ("patch_size", 2), ("patch_stride", 1),
                         ("gradient_descent_iterations", 1)):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo):
                raise ValueError(f"dis.{name} must be None or a whole number >= {lo}; got {v!r}")


def dis_finest_scale(shape: tuple[int, ...], finest_scale: int, patch_size: int) -> int:
    """``finest_scale`` for DIS on images of ``shape`` (H, W), no coarser than the coarsest level OpenCV searches
    there (:func:`flexvox_core.gpu.dis.scales`' rule; 0 at the least): OpenCV reads past its buffers when the finest
    is coarser."""
    H, W = int(shape[0]), int(shape[1])
    by_motion = int(math.log(max(W, H) / (4.0 * patch_size)) / math.log(2.0) + 0.5)
    by_patch = int(math.log(max(1, min(W, H) // patch_size)) / math.log(2.0))
    return max(0, min(finest_scale, by_motion, by_patch))


@dataclass(frozen=True)
class DeepFlow:
    """DeepFlow (Weinzaepfel et al. 2013): Brox-style variational flow with deep matching —
    the closest to the paper's Brox et al. flow; about 0.9 s per VGA pair here."""

    name = "deepflow"

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return cv2.optflow.createOptFlow_DeepFlow().calc(a, b, None)

    def check(self) -> None:
        return None


@dataclass(frozen=True)
class FarnebackFlow:
    """Farnebäck 2003 polynomial-expansion flow."""

    name = "farneback"
    pyr_scale: float = 0.5
    levels: int = 5
    winsize: int = 15
    iterations: int = 3
    poly_n: int = 5
    poly_sigma: float = 1.2

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return cv2.calcOpticalFlowFarneback(
            a, b, None, pyr_scale=self.pyr_scale, levels=self.levels, winsize=self.winsize,
            iterations=self.iterations, poly_n=self.poly_n, poly_sigma=self.poly_sigma, flags=0,
        )

    def check(self) -> None:
        if not 0 < self.pyr_scale < 1:
            raise ValueError(f"farneback.pyr_scale must be in (0, 1); got {self.pyr_scale}")
        _nonneg(self, "levels", "winsize", "iterations", "poly_n", "poly_sigma")


@dataclass(frozen=True)
class TvL1Flow:
    """Dual TV-L1 (Zach et al. 2007). Fails on large motion with OpenCV's defaults.

    See docs/architecture.md, "Facts the design rests on".
    """

    name = "tvl1"
    tau: float = 0.25
    lambda_: float = 0.15
    theta: float = 0.3
    scales: int = 5
    warps: int = 5
    epsilon: float = 0.01
    scale_step: float = 0.5

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        tv = cv2.optflow.DualTVL1OpticalFlow_create()
        tv.setTau(self.tau)
        tv.setLambda(self.lambda_)
        tv.setTheta(self.theta)
        tv.setScalesNumber(int(self.scales))
        tv.setWarpingsNumber(int(self.warps))
        tv.setEpsilon(self.epsilon)
        tv.setScaleStep(self.scale_step)
        return tv.calc(a, b, None)

    def check(self) -> None:
        _nonneg(self, "tau", "lambda_", "theta", "scales", "warps", "epsilon")
        if not 0 < self.scale_step < 1:
            raise ValueError(f"tvl1.scale_step must be in (0, 1); got {self.scale_step}")


def _nonneg(obj, *names) -> None:
    for name in names:
        v = getattr(obj, name)
        if not np.isfinite(v) or v < 0:
            raise ValueError(f"{obj.name}.{name} must be a finite number >= 0; got {v!r}")


BACKENDS = {cls.name: cls for cls in (DisFlow, DeepFlow, FarnebackFlow, TvL1Flow)}
"""Every backend by name: dis (default), deepflow, farneback, tvl1."""


def make_backend(name: str = "dis", **params):
    """Build a backend by name with keyword parameters (validated)."""
    if name not in BACKENDS:
        raise ValueError(f"unknown flow backend {name!r}; backends: {', '.join(BACKENDS)}")
    cls = BACKENDS[name]
    valid = {f.name for f in fields(cls)}
    unknown = sorted(set(params) - valid)
    if unknown:
        raise ValueError(f"flow backend {name!r} has no parameter {unknown[0]!r}; its parameters: "
                         f"{', '.join(sorted(valid)) or 'none'}")
    backend = cls(**params)
    backend.check()
    return backend


def backend_params(backend) -> dict:
    """A backend's parameters, for metadata."""
    return {"backend": backend.name, **asdict(backend)}
