"""The coupled simulated rig: a projector, a camera and a sync box that see one scene.

The camera sees the scene lit by the projector's *current* pattern sequence. Patterns are
in projector pixels ``(Hp, Wp)``; they reach camera pixels ``(H, W)`` through a hidden
projector→camera homography (a co-located rig has one for every depth, docs/architecture.md).
Camera pixels that no projector pixel reaches get no projected light, only what the
scene's ``ambient`` effect declares. The scene's declared effects (ambient light, leakage,
defocus, noise, sync offset, dropped frames, ...) are applied by
:func:`flexvox_core.simulate.simulator.render_exposures`; nothing undeclared is simulated.

Warp: area-correct
------------------
Each pattern is mapped into the camera with :func:`cv2.warpPerspective` at
:data:`SUPERSAMPLE`\\ × the camera resolution with *nearest* interpolation, then averaged
back with :func:`cv2.resize` (``INTER_AREA``). A camera pixel's light is therefore the
fraction of its area lit by open mirrors (to 1/SUPERSAMPLE² precision), which is what a
sensor integrates: a camera pixel straddling an open and a closed mirror gets a grey value
instead of either (nearest) or a bilinear mix of mirror *values* at its centre (which
blurs an edge by one projector pixel whatever the scale). It keeps light in [0, 1], puts a
single bright projector pixel's centroid where the homography maps its centre, and with
the identity homography it reproduces the patterns exactly (every sub-sample of a camera
pixel rounds to the same mirror), which the forward-model check relies on.

Timing
------
Slot = one projector pattern period. With the camera triggered by a hardware line (the
projector's TRIG_OUT_2, once per K patterns, wired to ``camera_line``), exposure ``e``
starts ``phase_slots·period + delay_us`` after the start of a sequence (plus the camera's
own ``TriggerConfig.delay_us``) and integrates K slots, so exposure slot ``t`` sees
projector pattern ``(t + phase_slots) mod K`` when the delay is 0; a fractional delay mixes
neighbouring patterns. Free-running and software-triggered exposures start on the camera's
clock and see whatever the projector shows then. The scene advances K sub-frames per
exposure and loops. All of it runs on one injectable clock
(:class:`~rig_drivers.simulated_camera.VirtualClock` in tests: nothing sleeps).

Built as a real rig
-------------------
By default (``--rig mock``, the app, the demo) the rig is what a lab builds: a projector twice
as fine as the camera behind a hidden homography that is not the identity, and a trigger offset
that is not a whole slot (:mod:`rig_drivers.simulated_target`). It looks at its scene, or at the
calibration target once :meth:`SimulatedRig.show_target` puts it in view (as an operator holds a
board in front of the camera). :meth:`SimulatedRig.create` with ``ideal=True`` builds the
textbook rig instead (projector = camera, identity map, no offset): for tests of the capture
path itself, never the default.

The hidden values are in :attr:`SimulatedRig.truth` for tests; code under test (the
calibration and sync wizards) must find them from frames.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import cv2
import numpy as np

from flexvox_core.memory_budget import check_fits, render_bytes
from flexvox_core.simulate.effects import Effect
from flexvox_core.simulate.scene_file import SceneSpec
from flexvox_core.simulate.scenes import SCENES, render_scene
from rig_drivers.errors import SettingError
from rig_drivers.interfaces import PatternSequence, RunState, TriggerSource, check_int
from rig_drivers.pixel_layout import check_layout, mirror_at
from rig_drivers.simulated import SimulatedProjector, SimulatedSyncController
from rig_drivers.simulated_camera import MonotonicClock, SceneVideo, SimClock, SimulatedCamera
from rig_drivers.simulated_rig_spec import (
    DEFAULT_CAMERA_SIZE,
    SimulatedRigSpec,
    check_effects,
    check_homography,
    check_size,
)
from rig_drivers.simulated_target import (
    PROJECTOR_SCALE,
    TARGET_EFFECTS,
    fine_homography,
    hidden_timing,
    plane_homography,
    target_video,
)

_logger = logging.getLogger(__name__)

SUPERSAMPLE = 4
"""Sub-samples per camera pixel side in the area-correct warp."""

# --------------------------------------------------------------------------- geometry


def warp_patterns(patterns, homography, camera_size, *, supersample: int = SUPERSAMPLE,
                  layout: str = "square") -> np.ndarray:
    """Projector patterns ``(K, Hp, Wp)`` → light in camera pixels ``(K, H, W)`` float32.

    Area-correct (see the module docstring): nearest-neighbour warp at ``supersample``×
    resolution, then area averaging. Outside the projector: 0. ``layout`` is how the projector's
    pixels sit (:mod:`rig_drivers.pixel_layout`): on a diamond DMD each sub-sample takes the
    mirror of the staggered grid that covers it.
    """
    H, W = camera_size
    s = int(supersample)
    if check_layout(layout) != "square":
        return _warp_layout(np.asarray(patterns), check_homography(homography), (H, W), s, layout)
    up = np.array([[s, 0, (s - 1) / 2], [0, s, (s - 1) / 2], [0, 0, 1]], dtype=np.float64)
    m = up @ check_homography(homography)
    pats = np.asarray(patterns)
    out = np.empty((pats.shape[0], H, W), np.float32)
    for k, p in enumerate(pats):
        fine = cv2.warpPerspective(p.astype(np.uint8) * np.uint8(255), m, (W * s, H * s), flags=cv2.INTER_NEAREST,
                                   borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        small = fine if s == 1 else cv2.resize(fine.astype(np.float32), (W, H), interpolation=cv2.INTER_AREA)
        out[k] = small
    out /= np.float32(255)
    return out


def _warp_layout(pats: np.ndarray, homography: np.ndarray, camera_size, s: int, layout: str,
                 rows_per_block: int = 64) -> np.ndarray:
    """:func:`warp_patterns` for a non-square layout: each sub-sample maps back into mirror
    coordinates and takes the mirror that covers it there (``rows_per_block`` camera rows at a time)."""
    H, W = camera_size
    inv = np.linalg.inv(homography)
    out = np.empty((pats.shape[0], H, W), np.float32)
    bools = np.asarray(pats, bool)
    for r0 in range(0, H, rows_per_block):
        r1 = min(H, r0 + rows_per_block)
        ys, xs = np.mgrid[r0 * s:r1 * s, 0:W * s].astype(np.float64)
        cam = np.stack([(xs + 0.5) / s - 0.5, (ys + 0.5) / s - 0.5, np.ones_like(xs)], axis=-1)
        proj = cam @ inv.T
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v = proj[..., 0] / proj[..., 2], proj[..., 1] / proj[..., 2]
        row, col, inside = mirror_at(u, v, pats.shape[1:], layout)
        for k, p in enumerate(bools):
            fine = (p[row, col] & inside).astype(np.float32)
            out[k, r0:r1] = fine.reshape(r1 - r0, s, W, s).mean(axis=(1, 3))
    return out


# --------------------------------------------------------------------------- truth


@dataclass(frozen=True, eq=False)
class RigTruth:
    """What the simulated rig hides from the code under test. For tests only.

    Attributes
    ----------
    homography : ndarray, shape (3, 3)
        Projector pixel (x, y) → camera pixel (x, y) on the scene's plane (depth 1), float64,
        ``h[2, 2] = 1``.
    phase_slots : int
        The projected pattern that lands in exposure slot 0 (hardware trigger, zero delay).
    delay_us : int
        Trigger latency (cable, opto-coupler) between TRIG_OUT_2 and the exposure start.
    seed : int
        The seed of every effect's noise and of the default homography.
    scene : SceneVideo
        The scene's ground truth (it loops; exposure e sees sub-frames (e·K + s) mod S), rendered when first read
        (:attr:`video`).
    effects : dict
        ``{name: params}`` of the scene's declared effects.
    baseline : (bx, by, bz)
        The projector's offset from the camera's centre of projection, in units of the scene's
        distance (0: co-located; see :func:`~rig_drivers.simulated_target.plane_homography`).
    """

    homography: np.ndarray
    phase_slots: int
    delay_us: int
    seed: int
    scene: SceneVideo
    effects: dict = field(default_factory=dict)
    baseline: tuple = (0.0, 0.0, 0.0)

    @property
    def video(self) -> np.ndarray:
        """The scene's ground truth ``(S, H, W)`` (rendered on the first read)."""
        return self.scene.array

    def homography_at(self, depth: float) -> np.ndarray:
        """The projector→camera homography of a plane at ``depth`` (1: the scene's plane, :attr:`homography`).

        The same as :attr:`homography` at every depth for a co-located rig (no baseline).
        """
        size = self.scene.shape[1:]
        at_1 = plane_homography(np.eye(3), size, baseline=self.baseline, depth=1.0)
        at_z = plane_homography(np.eye(3), size, baseline=self.baseline, depth=depth)
        h = at_z @ np.linalg.inv(at_1) @ self.homography
        return h / h[2, 2]

    def projector_to_camera(self, xy) -> np.ndarray:
        """Map projector points ``(N, 2)`` (x, y) to camera points with the true homography."""
        pts = np.asarray(xy, dtype=np.float64).reshape(-1, 1, 2)
        return cv2.perspectiveTransform(pts, self.homography).reshape(-1, 2)

    def subframes(self, frame_id: int, K: int) -> np.ndarray:
        """Sub-frame indices of :attr:`video` integrated by the frame with ``frame_id``."""
        return (int(frame_id) * K + np.arange(K)) % self.scene.shape[0]

    def subframe_video(self, frame_id: int, K: int) -> np.ndarray:
        """The scene's ``(K, H, W)`` sub-frames the frame with ``frame_id`` integrates (a recording's ground truth)."""
        return self.video[self.subframes(frame_id, K)]


# --------------------------------------------------------------------------- devices


class RigProjector(SimulatedProjector):
    """The rig's simulated projector: a fixed resolution, and its patterns are what the
    camera sees."""

    def __init__(self, size: tuple[int, int], *, clock_us, name: str | None = None, pixel_layout: str = "square"):
        super().__init__(clock_us=clock_us, name=name or "simulated projector")
        self.size = (int(size[0]), int(size[1]))
        self.pixel_layout = check_layout(pixel_layout)
        """How its pixels sit (:mod:`rig_drivers.pixel_layout`): "square", or "diamond" (staggered rows)."""

    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        if sequence.patterns.shape[1:] != self.size:
            raise SettingError(
                f"`patterns` must be {self.size[0]}x{self.size[1]} projector pixels (H x W) for "
                f"{self.name}; got {sequence.patterns.shape[1]}x{sequence.patterns.shape[2]}")
        super()._do_load_sequence(sequence)


class ProjectorLightPath:
    """The light path of the rig: projector → homography → camera, and the trigger wire."""

    def __init__(self, projector: RigProjector, truth: RigTruth, camera_size, *,
                 camera_line: TriggerSource, sync: SimulatedSyncController | None = None):
        self._projector = projector
        self._truth = truth
        self._homography = truth.homography
        self._camera_size = camera_size
        self._line = camera_line
        self._sync = sync
        self._warped_for: PatternSequence | None = None
        self._warped: np.ndarray | None = None

    def _sequence(self) -> PatternSequence | None:
        return self._projector.sequence

    def set_homography(self, homography) -> None:
        """Where projector pixels land now (another plane in view)."""
        self._homography = check_homography(homography)
        self._warped_for = None

    def slots(self) -> int | None:
        """K of the loaded sequence."""
        seq = self._sequence()
        return None if seq is None else seq.K

    def warped(self) -> np.ndarray:
        """The loaded patterns in camera pixels (cached per sequence)."""
        seq = self._sequence()
        if self._warped_for is not seq:
            self._warped = warp_patterns(seq.patterns, self._homography, self._camera_size,
                                         layout=self._projector.pixel_layout)
            self._warped_for = seq
        return self._warped

    def warm_up(self) -> None:
        """Warp the loaded patterns into camera pixels now (seconds at VGA), not at the first exposure."""
        if self._sequence() is not None:
            self.warped()

    def _elapsed_at(self, t_us: int, now_us: int) -> int:
        """The projector's display time (µs since start, pauses excluded) at wall time t."""
        # Ask for the display time at the caller's clock reading, not at a fresh one: with a
        # real clock the two differ and the same exposure would be delivered twice.
        return self._projector.elapsed_us(at_us=now_us) + (int(t_us) - int(now_us))

    def next_trigger_us(self, line: TriggerSource, after_us: int, now_us: int) -> tuple[int, int] | None:
        """The next TRIG_OUT_2 pulse (once per sequence) reaching the camera on ``line``."""
        seq = self._sequence()
        if line is not self._line or seq is None or self._projector.run_state is not RunState.RUNNING:
            return None
        if self._sync is not None and not self._sync.running:
            return None
        frame_us = seq.K * seq.period_us
        offset = self._truth.phase_slots * seq.period_us + self._truth.delay_us
        elapsed = self._elapsed_at(after_us, now_us)
        j = max(0, -(-(elapsed - offset) // frame_us))
        if not seq.repeat and j > 0:
            return None
        return int(after_us) + offset + j * frame_us - elapsed, frame_us

    def exposure_light(self, start_us: int, now_us: int, K: int, height: int, width: int) -> np.ndarray | None:
        """Light per exposure slot for an exposure starting at ``start_us`` (K slots long)."""
        seq = self._sequence()
        state = self._projector.run_state
        if seq is None or state is RunState.STOPPED:
            return None
        warped = self.warped()
        if state is RunState.PAUSED:
            slot = self._projector.current_slot()
            return None if slot is None else np.repeat(warped[slot][None], seq.K, axis=0)
        elapsed = self._elapsed_at(start_us, now_us)
        first, rem = divmod(elapsed, seq.period_us)
        f = np.float32(rem / seq.period_us)
        out = np.empty_like(warped)
        for t in range(seq.K):
            out[t] = self._shown(warped, seq, first + t)
            if f:
                out[t] *= 1 - f
                out[t] += f * self._shown(warped, seq, first + t + 1)
        return out

    @staticmethod
    def _shown(warped, seq: PatternSequence, slot: int) -> np.ndarray:
        if slot < 0 or (not seq.repeat and slot >= seq.K):
            return np.zeros_like(warped[0])
        return warped[slot % seq.K]


class SimulatedRig:
    """A simulated projector, camera and sync box coupled through a scene (or the calibration target).

    A :class:`~rig_drivers.interfaces.Rig`. Build one with :meth:`build` from a
    :class:`~rig_drivers.simulated_rig_spec.SimulatedRigSpec` (or :meth:`create` with the spec's
    fields as keywords). The devices are not opened; open them as any others.

    Attributes
    ----------
    projector : RigProjector
    camera : SimulatedCamera
    sync : SimulatedSyncController
    clock : SimClock
        The clock every device runs on.
    truth : RigTruth
        The hidden homography, phase, delay and seed. For tests only.
    name : str
        ``simulated rig (seed N)``: rigs of other seeds hide other homographies and timings.
    spec : SimulatedRigSpec or None
        What it was built from (None when its parts were given).
    """

    def __init__(self, projector: RigProjector, camera: SimulatedCamera, sync: SimulatedSyncController,
                 clock: SimClock, truth: RigTruth, *, light_path: ProjectorLightPath | None = None,
                 scene_effects: list[Effect] | None = None, target_effects=None, name: str | None = None,
                 spec: SimulatedRigSpec | None = None):
        self.projector = projector
        self.camera = camera
        self.sync = sync
        self.clock = clock
        self.truth = truth
        self.name = name or f"simulated rig (seed {truth.seed})"
        self.spec = spec
        self._light_path = light_path
        self._scene_effects = list(scene_effects or [])
        self._target_effects = TARGET_EFFECTS if target_effects is None else target_effects
        self._viewing = "scene"

    def __repr__(self) -> str:
        lines = [f"projector: {self.projector!r}", f"camera: {self.camera!r}", f"sync: {self.sync!r}",
                 f"clock: {self.clock!r}"]
        return f"<SimulatedRig {self.name!r}\n" + "\n".join(f"  {line}" for line in lines) + ">"

    @classmethod
    def create(cls, scene: str | SceneSpec | np.ndarray = "drummer", **fields) -> SimulatedRig:
        """:meth:`build` the rig of ``SimulatedRigSpec(scene, **fields)`` (the spec's fields as keywords)."""
        return cls.build(SimulatedRigSpec(scene, **fields))

    @classmethod
    def build(cls, spec: SimulatedRigSpec) -> SimulatedRig:
        """Build the rig a :class:`~rig_drivers.simulated_rig_spec.SimulatedRigSpec` describes (its devices not
        opened): the scene rendered, the hidden homography and timing drawn from its seed where it gives none."""
        if not isinstance(spec, SimulatedRigSpec):
            raise SettingError(f"`spec` must be a SimulatedRigSpec (rig_drivers.simulated_rig_spec); got "
                               f"{type(spec).__name__}")
        scene = spec.scene
        file = scene if isinstance(scene, SceneSpec) else None
        seed = (file.seed if file is not None else 0) if spec.seed is None else spec.seed
        declared = check_effects(file.effects if file is not None and spec.effects is None else spec.effects)
        epu = spec.electrons_per_unit or (file.electrons_per_unit if file is not None else 1000.0)
        video = cls._video(scene, file, spec.camera_size, spec.subframes, seed)
        camera_size = video.shape[1:]  # known before the scene is rendered (the camera's open renders it)
        if spec.projector_size is not None:
            projector_size = spec.projector_size
        elif spec.ideal:
            projector_size = tuple(camera_size)
        else:
            projector_size = (PROJECTOR_SCALE * camera_size[0], PROJECTOR_SCALE * camera_size[1])
        if spec.homography is not None:
            h = spec.homography
        else:
            h = np.eye(3) if spec.ideal else fine_homography(camera_size, projector_size, seed)
        hidden = (0, 0) if spec.ideal else hidden_timing(seed)
        phase = hidden[0] if spec.phase_slots is None else spec.phase_slots
        delay = hidden[1] if spec.delay_us is None else spec.delay_us
        truth = RigTruth(h, check_int("phase_slots", phase, 0, 1023), check_int("delay_us", delay, 0, 10**7),
                         seed, video, {e.name: e.as_dict() for e in declared}, spec.baseline)
        clock = spec.clock or MonotonicClock()
        projector = RigProjector(projector_size, clock_us=clock.now_us, pixel_layout=spec.pixel_layout)
        sync = SimulatedSyncController(clock_us=clock.now_us)
        path = ProjectorLightPath(projector, truth, camera_size, camera_line=spec.camera_line,
                                  sync=sync if spec.wiring == "syncbox" else None)
        camera = SimulatedCamera(video, effects=declared, seed=seed, electrons_per_unit=epu, light_path=path,
                                 clock=clock, buffer_frames=spec.buffer_frames)
        _logger.info("simulated rig: camera %dx%d, projector %dx%d, %s, effects: %s", camera_size[0], camera_size[1],
                     projector_size[0], projector_size[1], "ideal" if spec.ideal else "hidden homography and timing",
                     ", ".join(truth.effects) or "none")
        return cls(projector, camera, sync, clock, truth, light_path=path, scene_effects=declared,
                   target_effects=spec.target_effects, spec=spec)

    # ------------------------------------------------------------------ the Rig protocol
    @property
    def trigger_line(self) -> TriggerSource:
        """The camera line flexvox triggers on: Line0, as ``--rig mock`` declares it. Where the wire really goes
        (:attr:`SimulatedRigSpec.camera_line <rig_drivers.simulated_rig_spec.SimulatedRigSpec.camera_line>`) is
        part of what the rig hides: wired to another line, it delivers no frame."""
        return TriggerSource.LINE0

    @property
    def projector_size(self) -> tuple[int, int]:
        """The projector's pattern size (rows, columns)."""
        return self.projector.size

    @property
    def pixel_layout(self) -> str:
        """How the projector's pixels sit (:mod:`rig_drivers.pixel_layout`)."""
        return self.projector.pixel_layout

    @property
    def video_port(self) -> bool:
        """False: the simulated projector runs the sequences it is given, with no video input."""
        return self.projector.video_port

    @property
    def simulated(self) -> SimulatedRig:
        """The simulated rig behind this rig: itself."""
        return self

    # ------------------------------------------------------------------ what the camera looks at
    @property
    def viewing(self) -> str:
        """``"scene"`` or ``"target"``: what is in front of the camera."""
        return self._viewing

    @property
    def effects_in_view(self) -> dict:
        """``{name: params}`` of the effects simulated now (the scene's, or the calibration target's)."""
        effects = self._scene_effects if self._viewing == "scene" else check_effects(self._target_effects)
        return {e.name: e.as_dict() for e in effects}

    def show_target(self, *, depth: float = 1.0, albedo=(0.35, 0.95), shadow: str | None = None,
                    video=None) -> None:
        """Put the calibration target in front of the camera, at ``depth`` (1: the scene's plane).

        Parameters
        ----------
        depth : float
            Distance in units of the scene's; another depth moves the projector's image when the
            rig has a baseline (the parallax test). :meth:`move_target` changes only this.
        albedo, shadow
            The target's look (see :func:`~rig_drivers.simulated_target.target_video`).
        video : ndarray (S, H, W), optional
            Another target (e.g. a dark one).
        """
        H, W = self.camera.sensor_shape
        target = target_video((H, W), self.truth.seed, albedo=albedo, shadow=shadow) if video is None else video
        self.camera.set_view(target, check_effects(self._target_effects))
        self._viewing = "target"
        self.move_target(depth)

    def move_target(self, depth: float) -> None:
        """Move the calibration target (in view) to ``depth``, as the parallax test asks the operator to."""
        if self._viewing != "target":
            raise SettingError("the calibration target is not in view: show_target() first")
        self._light_path.set_homography(self.truth.homography_at(depth))
        _logger.info("simulated rig: calibration target in view at depth %g", depth)

    def show_scene(self) -> None:
        """Put the scene back in front of the camera (after calibration)."""
        self.camera.set_view(self.truth.scene, self._scene_effects)
        self._light_path.set_homography(self.truth.homography)
        self._viewing = "scene"
        _logger.info("simulated rig: the scene in view")

    @staticmethod
    def _video(scene, spec: SceneSpec | None, camera_size, subframes, seed) -> SceneVideo:
        if isinstance(scene, np.ndarray):
            if scene.ndim != 3 or not np.isfinite(scene).all() or scene.min() < 0 or scene.max() > 1:
                raise SettingError(f"a scene video must have shape (S, H, W) with values in [0, 1]; got {scene.shape}")
            if camera_size is not None and tuple(scene.shape[1:]) != check_size("camera_size", camera_size):
                raise SettingError(f"`camera_size` {tuple(camera_size)} does not match the scene video "
                                   f"{scene.shape[1]}x{scene.shape[2]}")
            return SceneVideo.of(scene.astype(np.float32, copy=False))
        if spec is not None and spec.file is not None:
            from flexvox_core.simulate.sources import load_video

            try:
                video = load_video(spec.file)
            except ValueError as exc:
                raise SettingError(f"cannot load the scene video: {exc}") from exc
            if camera_size is not None and tuple(video.shape[1:]) != check_size("camera_size", camera_size):
                raise SettingError(f"`camera_size` {tuple(camera_size)} does not match the scene video "
                                   f"{video.shape[1]}x{video.shape[2]}")
            return SceneVideo.of(video)
        if camera_size is None:
            camera_size = (spec.height, spec.width) if spec is not None else DEFAULT_CAMERA_SIZE
        H, W = check_size("camera_size", camera_size)
        if subframes is None:
            subframes = (spec.camera_frames() or 16) * spec.K if spec is not None else 256
        S = check_int("subframes", subframes, 1, 1_000_000)
        name = spec.builtin if spec is not None else scene
        advice = "use a smaller camera size"
        if name not in SCENES:
            raise SettingError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")
        check_fits(render_bytes(S, H, W), f"the {name} scene at {H}x{W} with {S} sub-frames", advice)
        # Rendered when the camera opens (seconds for the drummer): building the rig builds only its devices.
        return SceneVideo((S, H, W), lambda: render_scene(name, S, H, W, seed=seed, advice=advice))

    @property
    def devices(self) -> tuple:
        """``(projector, camera, sync)``."""
        return self.projector, self.camera, self.sync

    def close(self) -> None:
        """Close every device (each is closed even when another fails)."""
        try:
            self.camera.close()
        finally:
            try:
                self.projector.close()
            finally:
                self.sync.close()
