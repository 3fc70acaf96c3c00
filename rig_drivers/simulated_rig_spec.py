"""What a simulated rig is built from: :class:`SimulatedRigSpec`, checked when it is made.

:meth:`SimulatedRig.build <rig_drivers.simulated_rig.SimulatedRig.build>` turns a spec into the rig;
``SimulatedRig.create(scene, **fields)`` and ``open_rig("mock", **fields)`` take the spec's fields as
keywords. A bad value is refused here, before any scene is rendered, with a
:class:`~rig_drivers.errors.SettingError` that names the field and the rule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from flexvox_core.reprs import describe_array
from flexvox_core.simulate.effects import Effect, parse_effects
from flexvox_core.simulate.scene_file import SceneSpec
from flexvox_core.simulate.scenes import SCENES
from rig_drivers.errors import SettingError
from rig_drivers.interfaces import TriggerSource, check_int
from rig_drivers.pixel_layout import check_layout

WIRINGS = ("projector", "syncbox")
"""How the camera's trigger line is driven: the projector's TRIG_OUT_2, or the sync box."""

DEFAULT_CAMERA_SIZE = (120, 160)
"""The simulated camera's size (H, W) when neither the caller nor a scene file gives one."""


def check_homography(h) -> np.ndarray:
    """Validate a 3×3 invertible, finite homography; return it as float64 with h[2, 2] = 1."""
    arr = np.asarray(h, dtype=np.float64)
    if arr.shape != (3, 3) or not np.isfinite(arr).all():
        raise SettingError(f"`homography` must be a finite 3x3 matrix; got shape {arr.shape}")
    if abs(arr[2, 2]) < 1e-12 or abs(np.linalg.det(arr)) < 1e-12:
        raise SettingError("`homography` must be invertible with h[2, 2] != 0")
    return arr / arr[2, 2]


def check_size(name: str, value) -> tuple[int, int]:
    """Validate an image size ``(H, W)`` of 8..8192 pixels each way."""
    if not isinstance(value, tuple | list) or len(value) != 2:
        raise SettingError(f"`{name}` must be (H, W); got {value!r}")
    return (check_int(f"{name}[0]", value[0], 8, 8192), check_int(f"{name}[1]", value[1], 8, 8192))


def check_effects(effects) -> list[Effect]:
    """Effects as :class:`~flexvox_core.simulate.effects.Effect` objects: from a ``{name: params}`` table, a list
    of them, or None (none)."""
    if effects is None:
        return []
    if isinstance(effects, dict):
        return parse_effects(effects)
    out = list(effects)
    for e in out:
        if not isinstance(e, Effect):
            raise SettingError(f"`effects` must be Effect objects or a {{name: params}} table; got {e!r}")
    return out


@dataclass(frozen=True, eq=False)
class SimulatedRigSpec:
    """Everything a :class:`~rig_drivers.simulated_rig.SimulatedRig` is built from (all checked when made).

    Parameters
    ----------
    scene : str, SceneSpec or ndarray (S, H, W)
        A built-in scene name (``flexvox_core.simulate.scenes.SCENES``), a parsed scene
        file (its source, seed, ``electrons_per_unit`` and effects are used; a built-in
        source is rendered at ``camera_size``), or a video in [0, 1] to use as it is.
    camera_size : (H, W), optional
        Default: the scene file's size, else :data:`DEFAULT_CAMERA_SIZE`.
    projector_size : (H, W), optional
        Default :data:`~rig_drivers.simulated_target.PROJECTOR_SCALE` × the camera's (a finer
        projector, as per-pixel shuttering needs); the camera's with ``ideal``.
    homography : array (3, 3), optional
        Projector→camera (in mirror coordinates) on the scene's plane. Default
        :func:`~rig_drivers.simulated_target.fine_homography` drawn from ``seed`` (the identity
        with ``ideal``).
    seed : int, optional
        Default: the scene file's seed, else 0. Seeds the hidden homography and timing, the
        calibration target's texture and every effect's noise.
    effects : list of Effect or dict, optional
        The scene's declared effects (``{name: {param: value}}`` like a scene file's table).
        Default: the scene file's, else none.
    subframes : int, optional
        Scene length S (it loops). Default 256, or the scene file's frames × K.
    phase_slots, delay_us : int, optional
        Hidden timing of the hardware trigger (see :mod:`rig_drivers.simulated_rig`). Default
        :func:`~rig_drivers.simulated_target.hidden_timing` of ``seed`` (0 and 0 with ``ideal``).
    ideal : bool
        The textbook rig: projector = camera, identity homography, no trigger offset (each
        still overridable). For tests of the capture path; a real rig is never like this.
    baseline : (bx, by, bz)
        The projector's offset from the camera (parallax), in units of the scene's distance.
    target_effects : dict or list of Effect, optional
        The effects met with the calibration target in view; default
        :data:`~rig_drivers.simulated_target.TARGET_EFFECTS`, ``{}`` for none.
    wiring : {"projector", "syncbox"}
        ``projector``: TRIG_OUT_2 drives the camera line. ``syncbox``: the sync box drives
        it, so frames also need the sync box running (the projector is assumed slaved).
    camera_line : TriggerSource
        The camera line the trigger is wired to (a rig wired to another line than the one it is
        triggered on delivers no frame).
    electrons_per_unit : float, optional
        The camera's gain (> 0). Default: the scene file's, else 1000.
    clock : SimClock, optional
        Default (None): real time (:class:`~rig_drivers.simulated_camera.MonotonicClock`): the camera delivers
        a frame every frame period. A :class:`~rig_drivers.simulated_camera.VirtualClock` jumps ahead whenever a
        device waits, so captures and calibrations run as fast as the scene renders (tests, notebooks).
    buffer_frames : int
        Frames the camera buffers (1..10000).
    pixel_layout : "square", "diamond" or "diamond-even"
        How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`): "diamond" staggers
        the odd rows by half a pixel, as the LightCrafter 4500's DMD does ("diamond-even": the even
        rows). Default square.

    Examples
    --------
    ``open_rig("mock", **fields)`` builds the rig of ``SimulatedRigSpec(**fields)``; its repr lists what differs
    from the defaults:

    >>> from rig_drivers import SimulatedRigSpec, VirtualClock
    >>> SimulatedRigSpec("balls", camera_size=(24, 32), seed=2, clock=VirtualClock())
    SimulatedRigSpec(scene='balls', camera_size=(24, 32), seed=2, clock=<VirtualClock at 0 µs>)
    """

    scene: str | SceneSpec | np.ndarray = "drummer"
    camera_size: tuple[int, int] | None = None
    projector_size: tuple[int, int] | None = None
    homography: np.ndarray | None = None
    seed: int | None = None
    effects: list | dict | None = None
    subframes: int | None = None
    phase_slots: int | None = None
    delay_us: int | None = None
    ideal: bool = False
    baseline: tuple[float, float, float] = (0.0, 0.0, 0.0)
    target_effects: list | dict | None = None
    wiring: str = "projector"
    camera_line: TriggerSource = TriggerSource.LINE0
    electrons_per_unit: float | None = None
    clock: object | None = None
    buffer_frames: int = 16
    pixel_layout: str = "square"

    def __repr__(self) -> str:
        """The scene and the fields that differ from their defaults; an array as its shape and dtype."""

        def shown(value) -> str:
            return f"array {describe_array(value)}" if isinstance(value, np.ndarray) else repr(value)

        parts = [f"scene={shown(self.scene)}"]
        for f in fields(self)[1:]:
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray) or value != f.default:
                parts.append(f"{f.name}={shown(value)}")
        return f"SimulatedRigSpec({', '.join(parts)})"

    def __post_init__(self):
        scene = self.scene
        if not isinstance(scene, SceneSpec | np.ndarray) and (not isinstance(scene, str) or scene not in SCENES):
            raise SettingError(f"unknown scene {scene!r}; built-in scenes: {', '.join(SCENES)} (or pass a SceneSpec)")
        if self.wiring not in WIRINGS:
            raise SettingError(f"`wiring` must be one of {', '.join(WIRINGS)}; got {self.wiring!r}")
        line = self.camera_line
        if not isinstance(line, TriggerSource) or not line.value.startswith("Line"):
            raise SettingError(f"`camera_line` must be a TriggerSource line (Line0..Line3); got {line!r}")
        if not isinstance(self.ideal, bool):
            raise SettingError(f"`ideal` must be True or False; got {self.ideal!r}")
        fix = {}
        if self.camera_size is not None:
            fix["camera_size"] = check_size("camera_size", self.camera_size)
        if self.projector_size is not None:
            fix["projector_size"] = check_size("projector_size", self.projector_size)
        if self.homography is not None:
            fix["homography"] = check_homography(self.homography)
        if self.seed is not None:
            fix["seed"] = check_int("seed", self.seed, 0, 2**63 - 1)
        check_effects(self.effects)
        check_effects(self.target_effects)
        if self.subframes is not None:
            fix["subframes"] = check_int("subframes", self.subframes, 1, 1_000_000)
        if self.phase_slots is not None:
            fix["phase_slots"] = check_int("phase_slots", self.phase_slots, 0, 1023)
        if self.delay_us is not None:
            fix["delay_us"] = check_int("delay_us", self.delay_us, 0, 10**7)
        try:
            base = tuple(float(v) for v in self.baseline)
        except (TypeError, ValueError):
            base = ()
        if len(base) != 3 or not all(math.isfinite(v) for v in base):
            raise SettingError(f"`baseline` must be three finite numbers (bx, by, bz); got {self.baseline!r}")
        fix["baseline"] = base
        epu = self.electrons_per_unit
        if epu is not None and (isinstance(epu, bool) or not isinstance(epu, int | float) or not 0 < epu < math.inf):
            raise SettingError(f"`electrons_per_unit` must be a number > 0; got {epu!r}")
        fix["buffer_frames"] = check_int("buffer_frames", self.buffer_frames, 1, 10_000)
        check_layout(self.pixel_layout)
        for name, value in fix.items():
            object.__setattr__(self, name, value)
