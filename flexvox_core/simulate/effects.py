"""Simulation effects: each a small unit with its own parameters, applied only when declared.

The pipeline (:mod:`flexvox_core.simulate.simulator`) runs in stages:

``pattern``
    change the projected per-slot pattern P (K, H, W): misregistration, pattern blur, leakage.
``timing``
    map patterns to the camera's exposure slots: sync phase offset and jitter.
``light``
    light that reaches pixels outside the code: global illumination, ambient light.
``sensor``
    in electrons, in this order: dark current, photon (shot) noise, saturation, read noise, ADC.
``frames``
    whole camera frames: dropped frames.

Electron-domain effects share the camera's scale ``electrons_per_unit`` (the electrons a
pixel collects from a white scene, value 1, in one open slot: the full-well/exposure scale),
set in the scene file's ``[camera]`` table.

Each effect draws random numbers from its own generator, seeded by the scene seed and the
effect's name, so declaring one effect never changes another's noise, and an undeclared
effect draws nothing.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np


@dataclass(frozen=True)
class Param:
    """One effect parameter: its unit, default and allowed range (inclusive)."""

    name: str
    unit: str
    default: float
    minimum: float
    maximum: float
    description: str
    integer: bool = False


class Effect:
    """Base of all effects; subclasses set ``name``, ``stage``, ``description``, ``params``."""

    name: ClassVar[str]
    stage: ClassVar[str]
    description: ClassVar[str]
    params: ClassVar[tuple[Param, ...]] = ()
    random: ClassVar[bool] = False
    """True when the effect draws random numbers (only then is its generator made)."""

    def __init__(self, **values):
        known = {p.name: p for p in self.params}
        unknown = sorted(set(values) - set(known))
        if unknown:
            valid = ", ".join(known) or "none"
            raise ValueError(f"effect {self.name!r} has no parameter {unknown[0]!r}; its parameters: {valid}")
        self.values = {}
        for p in self.params:
            v = values.get(p.name, p.default)
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
                raise ValueError(f"{self.name}.{p.name} must be a number ({p.unit}); got {v!r}")
            v = float(v)
            if not math.isfinite(v) or not p.minimum <= v <= p.maximum:
                raise ValueError(
                    f"{self.name}.{p.name} must be between {p.minimum:g} and {p.maximum:g} {p.unit}; got {v:g}"
                )
            if p.integer:
                if v != int(v):
                    raise ValueError(f"{self.name}.{p.name} must be a whole number; got {v:g}")
                v = int(v)
            self.values[p.name] = v
        self._check_together()

    def _check_together(self) -> None:
        """Rules between parameters (each one alone is checked above); raise ``ValueError`` naming them."""

    def __getattr__(self, item):
        try:
            return self.__dict__["values"][item]
        except KeyError:
            raise AttributeError(item) from None

    def as_dict(self) -> dict:
        """Parameters as recorded in a recording's metadata."""
        return dict(self.values)

    def rng(self, seed: int, stream: int = 0) -> np.random.Generator:
        """This effect's own random generator for a scene seed (and a stream, e.g. a frame index)."""
        return np.random.default_rng([int(seed), zlib.crc32(self.name.encode()), int(stream)])

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.values.items())
        return f"{type(self).__name__}({args})"


# --- pattern stage: (K, H, W) float32 projected light per slot, modified in place or replaced


class Misregistration(Effect):
    name = "misregistration"
    stage = "pattern"
    description = "the code seen through a small projector-camera homography error (sub-pixel)"
    params = (
        Param("dx", "px", 0.3, -20, 20, "shift along x"),
        Param("dy", "px", 0.0, -20, 20, "shift along y"),
        Param("rotation", "deg", 0.0, -5, 5, "rotation about the image centre"),
        Param("scale", "relative", 0.0, -0.05, 0.05, "scale error (0.001 = 0.1 %)"),
    )

    def matrix(self, height: int, width: int) -> np.ndarray:
        """Camera pixel -> projector pixel error mapping, a 3×3 homography."""
        cx, cy = (width - 1) / 2, (height - 1) / 2
        a = math.radians(self.rotation)
        s = 1 + self.scale
        c, si = s * math.cos(a), s * math.sin(a)
        return np.array(
            [[c, -si, cx - c * cx + si * cy + self.dx], [si, c, cy - si * cx - c * cy + self.dy], [0, 0, 1]]
        )

    def apply(self, pattern: np.ndarray) -> np.ndarray:
        K, H, W = pattern.shape
        Hm = self.matrix(H, W)
        out = np.empty_like(pattern)
        for s in range(K):
            out[s] = cv2.warpPerspective(pattern[s], Hm, (W, H), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_REFLECT_101)
        return out


class PatternBlur(Effect):
    name = "pattern_blur"
    stage = "pattern"
    description = "defocus of the projected code (Gaussian)"
    params = (Param("sigma", "px", 0.5, 0, 10, "Gaussian standard deviation"),)

    def apply(self, pattern: np.ndarray) -> np.ndarray:
        if self.sigma == 0:
            return pattern
        out = np.empty_like(pattern)
        for s in range(pattern.shape[0]):
            out[s] = cv2.GaussianBlur(pattern[s], (0, 0), self.sigma, borderType=cv2.BORDER_REFLECT_101)
        return out


class Leakage(Effect):
    name = "leakage"
    stage = "pattern"
    description = "closed pixels pass a fraction alpha of the light (finite projector contrast 1/alpha)"
    params = (Param("alpha", "fraction", 0.01, 0, 1, "light a closed pixel passes"),)

    def apply(self, pattern: np.ndarray) -> np.ndarray:
        return (self.alpha + (1 - self.alpha) * pattern).astype(pattern.dtype, copy=False)


# --- timing stage


class SyncPhase(Effect):
    name = "sync_phase"
    stage = "timing"
    description = "projector slots shifted against the exposure by a fraction of a slot, with jitter"
    params = (
        Param("offset", "slots", 0.1, -64, 64, "constant shift (1 = one whole slot later)"),
        Param("jitter", "slots rms", 0.0, 0, 1, "per-frame random shift"),
    )

    @staticmethod
    def shifted(pattern: np.ndarray, phase: float) -> np.ndarray:
        """Weights of each exposure slot when the pattern runs ``phase`` slots late.

        The pattern of slot s is shown during [s + phase, s + 1 + phase), so exposure slot t
        sees ``(1 - f)·P[t - i] + f·P[t - i - 1]`` (indices mod K) with i = ⌊phase⌋,
        f = phase − i. A whole-slot phase re-labels the code.
        """
        i = math.floor(phase)
        f = phase - i
        a = np.roll(pattern, i, axis=0)
        if f == 0:
            return a
        return ((1 - f) * a + f * np.roll(pattern, i + 1, axis=0)).astype(pattern.dtype, copy=False)


# --- light stage


class GlobalIllumination(Effect):
    name = "global_illumination"
    stage = "light"
    description = "a fraction of the projected light scattered evenly across the image"
    params = (Param("fraction", "fraction", 0.02, 0, 1, "of each slot's mean projected light"),)

    def apply(self, weights: np.ndarray) -> np.ndarray:
        return weights + (self.fraction * weights.mean(axis=(-2, -1), keepdims=True)).astype(weights.dtype)


class Ambient(Effect):
    name = "ambient"
    stage = "light"
    description = "ambient light that reaches pixels in every slot"
    params = (Param("level", "x projector light", 0.01, 0, 10, "relative to an open projector pixel"),)

    def apply(self, weights: np.ndarray) -> np.ndarray:
        return weights + np.asarray(self.level, weights.dtype)


# --- sensor stage (electrons, float64)


class DarkCurrent(Effect):
    name = "dark_current"
    stage = "sensor"
    description = "thermal electrons collected during the exposure (one camera frame period)"
    params = (Param("rate", "e-/s", 10.0, 0, 1e6, "dark electrons per second"),)

    def apply(self, electrons: np.ndarray, *, exposure_s: float, rng=None) -> np.ndarray:
        electrons += self.rate * exposure_s
        return electrons


class PhotonNoise(Effect):
    name = "photon_noise"
    random = True
    stage = "sensor"
    description = "shot noise: Poisson in electrons (scale: [camera] electrons_per_unit)"
    params = ()

    def apply(self, electrons: np.ndarray, *, exposure_s: float, rng: np.random.Generator) -> np.ndarray:
        return rng.poisson(np.maximum(electrons, 0)).astype(np.float64)


class Saturation(Effect):
    name = "saturation"
    stage = "sensor"
    description = "pixels clip at the full-well capacity"
    params = (Param("full_well", "e-", 10000.0, 1, 1e7, "full-well capacity"),)

    def apply(self, electrons: np.ndarray, *, exposure_s: float, rng=None) -> np.ndarray:
        return np.minimum(electrons, self.full_well, out=electrons)


class ReadNoise(Effect):
    name = "read_noise"
    random = True
    stage = "sensor"
    description = "Gaussian read noise"
    params = (Param("sigma", "e- rms", 3.0, 0, 1e4, "read noise"),)

    def apply(self, electrons: np.ndarray, *, exposure_s: float, rng: np.random.Generator) -> np.ndarray:
        electrons += rng.normal(0.0, self.sigma, electrons.shape)
        return electrons


class Adc(Effect):
    name = "adc"
    stage = "sensor"
    description = "analogue-to-digital conversion: gain, black level, bit depth (frames stored as uint16 counts)"
    params = (
        Param("bits", "bits", 12, 8, 16, "bit depth", integer=True),
        Param("gain", "DN/e-", 0.25, 1e-6, 1e3, "conversion gain"),
        Param("black_level", "DN", 64, 0, 65535, "offset added before quantisation"),
    )

    def _check_together(self) -> None:
        top = 2 ** self.bits - 1
        if self.black_level >= top:
            raise ValueError(f"adc.black_level must be below the {self.bits}-bit ADC's largest count {top}; got "
                             f"{self.black_level:g} (every pixel would read {top})")

    def apply(self, electrons: np.ndarray, *, exposure_s: float, rng=None) -> np.ndarray:
        dn = np.rint(electrons * self.gain + self.black_level)
        return np.clip(dn, 0, 2**self.bits - 1).astype(np.uint16)


# --- frames stage


class DroppedFrames(Effect):
    name = "dropped_frames"
    random = True
    stage = "frames"
    description = "camera frames lost in transfer (kept as zero rows flagged dropped)"
    params = (Param("probability", "fraction", 0.01, 0, 1, "chance that a frame is dropped"),)

    def drops(self, n_frames: int, rng: np.random.Generator) -> np.ndarray:
        return rng.random(n_frames) < self.probability


_ORDER = (
    Misregistration, PatternBlur, Leakage, SyncPhase, GlobalIllumination, Ambient,
    DarkCurrent, PhotonNoise, Saturation, ReadNoise, Adc, DroppedFrames,
)
EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in _ORDER}
"""Every effect by name, in the order the pipeline applies them."""


def parse_effects(table) -> list[Effect]:
    """Build effects from a mapping ``{name: {param: value}}`` (a scene file's ``[effects]``).

    Returns them in pipeline order. Unknown names raise ``ValueError`` listing the valid ones.
    """
    if table is None:
        return []
    if not isinstance(table, dict):
        raise ValueError(f"`effects` must be a table of effect names; got {type(table).__name__}")
    out = []
    for name, values in table.items():
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; effects: {', '.join(EFFECTS)}")
        if values is None or values is True:
            values = {}
        if not isinstance(values, dict):
            raise ValueError(f"effect {name!r} needs a table of parameters; got {values!r}")
        out.append(EFFECTS[name](**values))
    rank = {name: i for i, name in enumerate(EFFECTS)}
    return sorted(out, key=lambda e: rank[e.name])


def as_effects(effects) -> list[Effect]:
    """The effects ``simulate_video`` takes, in pipeline order (the order of :data:`EFFECTS`).

    Parameters
    ----------
    effects : list of str or Effect, mapping, str or None
        Effect names at their defaults (``["photon_noise", "read_noise"]``), :class:`Effect` objects
        (``ReadNoise(sigma=2)``), both mixed, a mapping ``{name: {param: value}}`` (:func:`parse_effects`), one
        name, or None (none).

    Raises
    ------
    ValueError
        An unknown name (the message lists :data:`EFFECTS`) or an item that is neither a name nor an Effect.
    """
    if effects is None:
        return []
    if isinstance(effects, dict):
        return parse_effects(effects)
    if isinstance(effects, str):
        effects = [effects]
    out: list[Effect] = []
    try:
        items = list(effects)
    except TypeError:
        raise ValueError(f"`effects` must be a list of effect names ({', '.join(EFFECTS)}) or Effect objects, or a "
                         f"table {{name: {{param: value}}}}; got {effects!r}") from None
    for e in items:
        if isinstance(e, str):
            out.extend(parse_effects({e: {}}))
        elif isinstance(e, Effect):
            out.append(e)
        else:
            raise ValueError(f"`effects` items must be effect names ({', '.join(EFFECTS)}) or Effect objects; "
                             f"got {e!r}")
    rank = {name: i for i, name in enumerate(EFFECTS)}
    return sorted(out, key=lambda e: rank.get(e.name, len(rank)))
