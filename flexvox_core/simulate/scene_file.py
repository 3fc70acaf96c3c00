"""Scene files (TOML): what to simulate.

.. code-block:: toml

    seed = 0
    [source]
    builtin = "drummer"          # or: file = "video.npy" (relative to this file); with a file of integer
                                 # counts, white = 4095 (the count that stands for white; default the dtype's max)
    height = 120                 # built-in scenes only
    width = 160
    frames = 8                   # camera frames; or duration_s = 0.5
    [camera]
    rate_hz = 15.0
    electrons_per_unit = 1000.0  # e- from a white scene in one open slot
    [code]
    tile = "4x4"                 # designed with flexvox_core.design_code
    multiplexed = false          # or an explicit identity order: order = [[0, 2], [3, 1]]
    [effects.read_noise]
    sigma = 3.0
    [effects.photon_noise]
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flexvox_core.rates import MAX_CAMERA_HZ
from flexvox_core.simulate.effects import Effect, parse_effects
from flexvox_core.simulate.scenes import SCENES
from flexvox_core.tiles import parse_tile

_TOP = {"seed", "name", "source", "camera", "code", "effects"}
_SOURCE = {"builtin", "file", "white", "height", "width", "frames", "duration_s"}
_CAMERA = {"rate_hz", "electrons_per_unit"}
_CODE = {"tile", "multiplexed", "order"}
MAX_DURATION_S = 86_400.0
"""The longest clip a scene may ask for (a day: the memory check refuses far shorter ones)."""
MAX_ELECTRONS_PER_UNIT = 1e9
"""The brightest light level (photo-electrons per unit of scene value): far above any sensor's full well."""


@dataclass
class SceneSpec:
    """A parsed scene: source, size and duration, camera, code and declared effects."""

    builtin: str | None = "static"
    file: Path | None = None
    height: int = 120
    width: int = 160
    frames: int | None = 8
    duration_s: float | None = None
    rate_hz: float = 15.0
    electrons_per_unit: float = 1000.0
    white: float | None = None
    """A ``file``'s count that stands for white (None: its dtype's largest value)."""
    tile: tuple[int, int] = (4, 4)
    multiplexed: bool = False
    order: list | None = None
    placement: list | None = None
    """A multiplexed code's placement order (:func:`~flexvox_core.multiplex.multiplexed_code`'s; None: its default);
    set from a code file (``flexvox simulate --code``), not from a scene file."""
    effects: list[Effect] = field(default_factory=list)
    seed: int = 0
    name: str = ""

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per camera frame."""
        return self.tile[0] * self.tile[1]

    def camera_frames(self) -> int | None:
        """Camera frames asked for (from ``frames`` or ``duration_s × rate_hz``)."""
        if self.frames is not None:
            return self.frames
        if self.duration_s is not None:
            return max(1, round(self.duration_s * self.rate_hz))
        return None

    def source_label(self) -> str:
        """Where the video comes from, in words."""
        return f"builtin:{self.builtin}" if self.file is None else str(self.file)


def _check_keys(table: dict, allowed: set, where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(sorted(allowed))}")


def _table(data: dict, key: str, where: str) -> dict:
    """The sub-table ``[key]`` (empty when absent); anything else under that name is refused."""
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ValueError(f"{where}: `{key}` must be a table ([{key}] with its keys); got {value!r}")
    return value


def _number(value, where: str, *, minimum: float, integer: bool = False, maximum: float = math.inf):
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where} must be a number; got {value!r}")
    if not math.isfinite(value) or value < minimum:
        raise ValueError(f"{where} must be >= {minimum:g}; got {value!r}")
    if value > maximum:
        raise ValueError(f"{where} must be at most {maximum:g}; got {value!r}")
    if integer and value != int(value):
        raise ValueError(f"{where} must be a whole number; got {value!r}")
    return int(value) if integer else float(value)


def scene_from_mapping(data: dict, *, base_dir: Path | None = None, where: str = "scene") -> SceneSpec:
    """Build a :class:`SceneSpec` from a parsed TOML mapping (validating every value)."""
    _check_keys(data, _TOP, where)
    spec = SceneSpec()
    spec.name = str(data.get("name", ""))
    spec.seed = _number(data.get("seed", 0), f"{where}: seed", minimum=0, integer=True)
    src = _table(data, "source", where)
    _check_keys(src, _SOURCE, f"{where} [source]")
    if "builtin" in src and "file" in src:
        raise ValueError(f"{where} [source]: give either `builtin` or `file`, not both")
    for key in ("builtin", "file"):
        if key in src and not isinstance(src[key], str):
            raise ValueError(f"{where} [source] {key} must be a string; got {src[key]!r}")
    if "file" in src:
        spec.builtin = None
        f = Path(src["file"])
        spec.file = f if f.is_absolute() or base_dir is None else base_dir / f
    elif "builtin" in src:
        if src["builtin"] not in SCENES:
            raise ValueError(
                f"{where} [source]: unknown scene {src['builtin']!r}; built-in scenes: {', '.join(SCENES)}"
            )
        spec.builtin = src["builtin"]
    if "white" in src:
        if spec.file is None:
            raise ValueError(f"{where} [source]: `white` is the count that stands for white in a `file` of counts; a "
                             "built-in scene has none")
        spec.white = _number(src["white"], f"{where} [source] white", minimum=1)
    for key in ("height", "width"):
        if key in src and spec.file is not None:
            raise ValueError(f"{where} [source]: `{key}` sets the size of a built-in scene; a `file` is a video of "
                             "its own size")
        if key in src:
            setattr(spec, key, _number(src[key], f"{where} [source] {key}", minimum=8, integer=True))
    if "frames" in src and "duration_s" in src:
        raise ValueError(f"{where} [source]: give either `frames` or `duration_s`, not both")
    if "frames" in src:
        spec.frames = _number(src["frames"], f"{where} [source] frames", minimum=1, integer=True)
    elif "duration_s" in src:
        spec.frames = None
        spec.duration_s = _number(src["duration_s"], f"{where} [source] duration_s", minimum=1e-6,
                                  maximum=MAX_DURATION_S)
    elif spec.file is not None:
        spec.frames = None  # the whole file
    cam = _table(data, "camera", where)
    _check_keys(cam, _CAMERA, f"{where} [camera]")
    if "rate_hz" in cam:
        spec.rate_hz = _number(cam["rate_hz"], f"{where} [camera] rate_hz", minimum=1e-3, maximum=MAX_CAMERA_HZ)
    if "electrons_per_unit" in cam:
        spec.electrons_per_unit = _number(cam["electrons_per_unit"], f"{where} [camera] electrons_per_unit",
                                          minimum=1e-3, maximum=MAX_ELECTRONS_PER_UNIT)
    code = _table(data, "code", where)
    _check_keys(code, _CODE, f"{where} [code]")
    if "tile" in code:
        try:
            spec.tile = parse_tile(code["tile"])
        except ValueError as exc:
            raise ValueError(f"{where} [code]: {exc}") from None
    multiplexed = code.get("multiplexed", False)
    if not isinstance(multiplexed, bool):
        raise ValueError(f"{where} [code] multiplexed must be true or false; got {multiplexed!r}")
    spec.multiplexed = multiplexed
    if "order" in code:
        if multiplexed:
            raise ValueError(f"{where} [code]: `order` places an identity code's slots; a multiplexed code has none "
                             "(give one or the other)")
        try:
            order = np.asarray(code["order"])
        except ValueError:  # ragged rows
            order = np.empty(0)
        if order.ndim != 2:
            raise ValueError(f"{where} [code] order must be m rows of n slot numbers each; got {code['order']!r}")
        if "tile" in code and tuple(order.shape) != spec.tile:
            raise ValueError(f"{where} [code]: `order` has {order.shape[0]}x{order.shape[1]} slots but `tile` is "
                             f"{spec.tile[0]}x{spec.tile[1]}")
        spec.order = order.tolist()
        spec.tile = (order.shape[0], order.shape[1])
    try:
        spec.effects = parse_effects(data.get("effects", {}))
    except ValueError as exc:
        raise ValueError(f"{where} [effects]: {exc}") from None
    return spec


def load_scene(path) -> SceneSpec:
    """Read a scene TOML file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{path}: not valid TOML: {exc}") from None
    spec = scene_from_mapping(data, base_dir=path.parent, where=str(path))
    spec.name = spec.name or path.stem
    return spec
