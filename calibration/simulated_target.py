"""The simulated rig set up for calibration: a static textured target, declared effects,
a finer projector, a hidden sync phase, and targets at other depths.

Depth emulation (parallax)
--------------------------
The simulated rig images a single plane, so it has one projector→camera homography. A
target at another depth is emulated, exactly, by building the rig with the homography that
a fronto-parallel plane at depth ``Z`` induces when the projector's centre of projection
sits at ``b = (bx, by, bz)`` from the camera's (same orientation, camera focal length
``f`` pixels, principal point at the frame centre). A ray of the co-located rig that
lands at camera point ``x₀`` lands, for the displaced projector, at

.. math::  x − c = (1 − b_z/Z)(x₀ − c) + f·(b_x, b_y)/Z

(pinhole geometry: the projector ray from ``b`` meets the plane ``Z``, which the camera
images). So :func:`plane_homography` = ``A_Z · H₀`` with that affine ``A_Z``. With
``b = 0`` it is ``H₀`` at every depth: the co-located case the parallax test must pass;
with ``b ≠ 0`` near and far targets disagree by ``f·b·(1/Z_near − 1/Z_far)``.
"""

from __future__ import annotations

import math

import numpy as np

from flexvox_core.simulate.textures import fine_texture
from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock

DEFAULT_CAMERA_SIZE = (120, 160)

DECLARED_EFFECTS = {
    "photon_noise": {},
    "read_noise": {"sigma": 5.0},
    "pattern_blur": {"sigma": 0.3},
    "ambient": {"level": 0.02},
}
"""Noise, defocus and ambient light: what the calibration targets are met with.

Defocus σ = 0.3 camera px is a rig focused for per-pixel shuttering. At σ = 0.5 px a fifth of
the camera pixels get a neighbour's slot at more than 3/4 of their own light, and about 1 %
see a neighbour's slot *more* than their own: no calibration can fix that (focus the
projector); :func:`calibration.shutter.verify_shutter` reports it as crosstalk."""

SHUTTER_SLOTS = 16
"""K of the shutter code the simulated rig is calibrated for (4×4 tiles)."""

SLOT_PERIOD_US = 4166
"""Pattern period of the simulated rig (240 Hz)."""

FOCAL_PX = 200.0
"""Camera focal length, pixels, used by the depth emulation."""


def target_video(camera_size, seed: int, *, albedo=(0.35, 0.95), shadow: str | None = None) -> np.ndarray:
    """A still, bright, textured wall ``(1, H, W)`` float32 with albedo in ``albedo``.

    ``shadow`` = ``"left"``, ``"right"``, ``"top"`` or ``"bottom"`` blacks out that half
    (a half of the image in shadow, or covered).
    """
    H, W = camera_size
    tex = fine_texture(H, W, np.random.default_rng([int(seed), 0x7A67]))
    lo, hi = albedo
    img = (lo + (hi - lo) * tex).astype(np.float32)
    if shadow == "left":
        img[:, : W // 2] = 0
    elif shadow == "right":
        img[:, W // 2:] = 0
    elif shadow == "top":
        img[: H // 2] = 0
    elif shadow == "bottom":
        img[H // 2:] = 0
    elif shadow is not None:
        raise ValueError(f"`shadow` must be left, right, top, bottom or None; got {shadow!r}")
    return img[None]


def fine_projector_homography(camera_size, projector_size, seed: int) -> np.ndarray:
    """A mild projector→camera homography with projector pixels smaller than camera pixels.

    Scale 0.55–0.70 camera px per projector px, rotation within ±1°, the projector centre
    within ±2 px of the camera centre, a tiny perspective term. Per-camera-pixel shutters
    need this: a projector pixel larger than a camera pixel cannot address it alone.
    """
    H, W = camera_size
    Hp, Wp = projector_size
    rng = np.random.default_rng([int(seed), 0x43616C])
    s = rng.uniform(0.55, 0.70)
    a = math.radians(rng.uniform(-1.0, 1.0))
    dx, dy = rng.uniform(-2.0, 2.0, 2)
    px, py = rng.uniform(-1e-6, 1e-6, 2)
    to_origin = np.array([[1, 0, -(Wp - 1) / 2], [0, 1, -(Hp - 1) / 2], [0, 0, 1]])
    tilt = np.array([[1, 0, 0], [0, 1, 0], [px, py, 1]])
    rot = np.array([[s * math.cos(a), -s * math.sin(a), 0], [s * math.sin(a), s * math.cos(a), 0], [0, 0, 1]])
    to_camera = np.array([[1, 0, (W - 1) / 2 + dx], [0, 1, (H - 1) / 2 + dy], [0, 0, 1]])
    h = to_camera @ rot @ tilt @ to_origin
    return h / h[2, 2]


def plane_homography(h0, camera_size, *, baseline=(0.0, 0.0, 0.0), depth: float = 1.0,
                     focal_px: float = FOCAL_PX) -> np.ndarray:
    """The homography a plane at ``depth`` induces when the projector is displaced by ``baseline``.

    ``baseline`` and ``depth`` share a unit (e.g. metres); see the module docstring.
    """
    H, W = camera_size
    cx, cy = (W - 1) / 2, (H - 1) / 2
    bx, by, bz = (float(v) for v in baseline)
    k = 1 - bz / depth
    a = np.array([[k, 0, (1 - k) * cx + focal_px * bx / depth],
                  [0, k, (1 - k) * cy + focal_px * by / depth],
                  [0, 0, 1]])
    h = a @ np.asarray(h0, dtype=np.float64)
    return h / h[2, 2]


def hidden_timing(seed: int, K: int = SHUTTER_SLOTS, period_us: int = SLOT_PERIOD_US) -> tuple[int, int]:
    """The phase (whole slots) and sub-slot delay (µs) a simulated rig hides, drawn from ``seed``.

    The delay is kept within 15–85 % of a slot, so the phase is well defined.
    """
    rng = np.random.default_rng([int(seed), 0x53796E])
    return int(rng.integers(0, K)), int(rng.uniform(0.15, 0.85) * period_us)


def calibration_rig(seed: int = 0, *, camera_size=DEFAULT_CAMERA_SIZE, projector_size=None, homography=None,
                    effects=None, phase_slots=None, delay_us=None, baseline=(0.0, 0.0, 0.0), depth: float = 1.0,
                    video=None, albedo=(0.35, 0.95), shadow=None, camera_line=None, electrons_per_unit=None,
                    clock=None):
    """Build the simulated rig (``open_rig("mock", ...)``) for calibration.

    Parameters
    ----------
    seed : int
        Seeds the homography, the hidden timing, the texture and every effect's noise.
    camera_size : (H, W)
    projector_size : (H, W), optional
        Default twice the camera's size.
    homography : array (3, 3), optional
        Projector→camera at depth 1; default :func:`fine_projector_homography`.
    effects : dict, optional
        Default :data:`DECLARED_EFFECTS`; ``{}`` for none.
    phase_slots, delay_us : int, optional
        Hidden timing; default :func:`hidden_timing` of the seed.
    baseline, depth
        Depth emulation (see the module docstring).
    video : ndarray (S, H, W), optional
        The scene; default :func:`target_video` with ``albedo`` and ``shadow``.
    camera_line : TriggerSource, optional
        Where the projector's trigger is wired (default Line0).
    clock : SimClock, optional
        Default a fresh :class:`VirtualClock` (nothing sleeps).

    Returns
    -------
    rig_drivers.profile.Rig
        Not opened; ``rig.simulated.truth`` holds the hidden values.
    """
    camera_size = tuple(int(v) for v in camera_size)
    projector_size = tuple(int(v) for v in (projector_size or (2 * camera_size[0], 2 * camera_size[1])))
    h0 = fine_projector_homography(camera_size, projector_size, seed) if homography is None else homography
    h = plane_homography(h0, camera_size, baseline=baseline, depth=depth)
    phase, delay = hidden_timing(seed)
    options = dict(camera_size=None, projector_size=projector_size, homography=h, seed=int(seed),
                   effects=DECLARED_EFFECTS if effects is None else effects,
                   phase_slots=phase if phase_slots is None else phase_slots,
                   delay_us=delay if delay_us is None else delay_us,
                   clock=clock or VirtualClock())
    if camera_line is not None:
        options["camera_line"] = camera_line
    if electrons_per_unit is not None:
        options["electrons_per_unit"] = electrons_per_unit
    scene = target_video(camera_size, seed, albedo=albedo, shadow=shadow) if video is None else video
    return open_rig("mock", scene=scene, **options)
