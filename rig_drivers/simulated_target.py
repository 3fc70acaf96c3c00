"""What the simulated rig hides and what it can be pointed at.

The simulated rig (:class:`rig_drivers.simulated_rig.SimulatedRig`, ``--rig mock``) is built as a
real rig is: a projector **finer** than the camera (twice its pixels each way by default) behind
a hidden projector→camera homography that is not the identity (:func:`fine_homography`), and a
hidden trigger offset that is not a whole slot (:func:`hidden_timing`). Calibration must find
both from frames, and capture must use what calibration found.

Like a real rig it can look at two things:

- **the scene** (a built-in scene, a scene file or a video; it loops), what captures record;
- **the calibration target** (:func:`target_video`), a still, bright, textured wall under the
  room's light (:data:`TARGET_EFFECTS`), what calibration images. On a real rig the operator
  holds a board in front of the camera; the simulated one swaps its view
  (:meth:`SimulatedRig.show_target` / :meth:`SimulatedRig.show_scene`).

Depth emulation (parallax)
--------------------------
The simulated rig images a single plane, so it has one projector→camera homography per plane.
A target at another depth is emulated exactly by the homography that a fronto-parallel plane at
depth ``Z`` induces when the projector's centre of projection sits at ``b = (bx, by, bz)`` from
the camera's (same orientation, camera focal length ``f`` pixels, principal point at the frame
centre). A ray of the co-located rig that lands at camera point ``x₀`` lands, for the displaced
projector, at

.. math::  x − c = (1 − b_z/Z)(x₀ − c) + f·(b_x, b_y)/Z

(pinhole geometry: the projector ray from ``b`` meets the plane ``Z``, which the camera images).
So :func:`plane_homography` = ``A_Z · H₀`` with that affine ``A_Z``. With ``b = 0`` it is ``H₀``
at every depth: the co-located case the parallax test must pass; with ``b ≠ 0`` near and far
targets disagree by ``f·b·(1/Z_near − 1/Z_far)``.
"""

from __future__ import annotations

import math

import numpy as np

from flexvox_core.simulate.textures import fine_texture

TARGET_EFFECTS = {
    "photon_noise": {},
    "read_noise": {"sigma": 5.0},
    "pattern_blur": {"sigma": 0.3},
    "ambient": {"level": 0.02},
}
"""What the calibration target is met with: noise, the projector's defocus, the room's light.

Defocus σ = 0.3 camera px is a rig focused for per-pixel shuttering. At σ = 0.5 px a fifth of
the camera pixels get a neighbour's slot at more than 3/4 of their own light, and about 1 %
see a neighbour's slot *more* than their own: no calibration can fix that (focus the
projector); :func:`flexvox_calibration.shutter.verify_shutter` reports it as crosstalk."""

HIDDEN_K = 16
"""Slots the hidden timing is drawn for (a 4×4 tile)."""

HIDDEN_PERIOD_US = 4166
"""Pattern period the hidden timing is drawn for (240 Hz slots: K = 16 at 15 Hz)."""

FOCAL_PX = 200.0
"""Camera focal length, pixels, used by the depth emulation."""

PROJECTOR_SCALE = 2
"""Projector pixels per camera pixel, each way, of the default simulated rig."""


def _homography(camera_size, projector_size, scale: float, angle_deg: float, shift, tilt) -> np.ndarray:
    """Projector centre → camera centre (+ shift), rotated, scaled, with a tiny perspective term."""
    H, W = camera_size
    Hp, Wp = projector_size
    a = math.radians(angle_deg)
    to_origin = np.array([[1, 0, -(Wp - 1) / 2], [0, 1, -(Hp - 1) / 2], [0, 0, 1]])
    persp = np.array([[1, 0, 0], [0, 1, 0], [tilt[0], tilt[1], 1]])
    rot = np.array([[scale * math.cos(a), -scale * math.sin(a), 0], [scale * math.sin(a), scale * math.cos(a), 0],
                    [0, 0, 1]])
    to_camera = np.array([[1, 0, (W - 1) / 2 + shift[0]], [0, 1, (H - 1) / 2 + shift[1]], [0, 0, 1]])
    h = to_camera @ rot @ persp @ to_origin
    return h / h[2, 2]


def fine_homography(camera_size, projector_size, seed: int) -> np.ndarray:
    """The default hidden homography: projector pixels smaller than camera pixels.

    Scale 0.55–0.70 camera px per projector px, rotation within ±1°, the projector centre within
    ±2 px of the camera centre, a tiny perspective term; drawn from ``seed``. Per-camera-pixel
    shutters need a projector this fine: a projector pixel larger than a camera pixel cannot
    address it alone.
    """
    rng = np.random.default_rng([int(seed), 0x43616C])
    s = rng.uniform(0.55, 0.70)
    a = rng.uniform(-1.0, 1.0)
    shift = rng.uniform(-2.0, 2.0, 2)
    tilt = rng.uniform(-1e-6, 1e-6, 2)
    return _homography(camera_size, projector_size, s, a, shift, tilt)


def coarse_homography(camera_size, projector_size, seed: int = 0) -> np.ndarray:
    """A homography with projector pixels a little *larger* than camera pixels (for tests of that case).

    Scale 1.05–1.10, rotation within ±0.5°, the projector centre within ±1.5 px (at most 1 % of the
    smaller camera side) of the camera centre, a tiny perspective term. With equal sizes the
    projector still covers the whole camera, but some camera pixels hold no projector pixel centre.
    """
    H, W = camera_size
    rng = np.random.default_rng([int(seed), 0x486F6D])
    s = rng.uniform(1.05, 1.10)
    a = rng.uniform(-0.5, 0.5)
    lim = min(1.5, 0.01 * min(H, W))
    shift = rng.uniform(-lim, lim, 2)
    tilt = rng.uniform(-2e-6, 2e-6, 2)
    return _homography(camera_size, projector_size, s, a, shift, tilt)


def plane_homography(h0, camera_size, *, baseline=(0.0, 0.0, 0.0), depth: float = 1.0,
                     focal_px: float = FOCAL_PX) -> np.ndarray:
    """The homography a plane at ``depth`` induces when the projector is displaced by ``baseline``.

    ``baseline`` and ``depth`` share a unit (e.g. metres); see the module docstring.
    """
    H, W = camera_size
    cx, cy = (W - 1) / 2, (H - 1) / 2
    bx, by, bz = (float(v) for v in baseline)
    if not (isinstance(depth, int | float) and math.isfinite(depth) and depth > 0):
        raise ValueError(f"`depth` must be a number > 0; got {depth!r}")
    k = 1 - bz / depth
    a = np.array([[k, 0, (1 - k) * cx + focal_px * bx / depth],
                  [0, k, (1 - k) * cy + focal_px * by / depth],
                  [0, 0, 1]])
    h = a @ np.asarray(h0, dtype=np.float64)
    return h / h[2, 2]


def hidden_timing(seed: int, K: int = HIDDEN_K, period_us: int = HIDDEN_PERIOD_US) -> tuple[int, int]:
    """The phase (whole slots) and sub-slot trigger delay (µs) a simulated rig hides, drawn from ``seed``.

    The delay is kept within 15–85 % of a slot: never a whole slot, and the phase is well defined.
    """
    rng = np.random.default_rng([int(seed), 0x53796E])
    return int(rng.integers(0, K)), int(rng.uniform(0.15, 0.85) * period_us)


def target_video(camera_size, seed: int, *, albedo=(0.35, 0.95), shadow: str | None = None) -> np.ndarray:
    """The calibration target: a still, bright, textured wall ``(1, H, W)`` float32 with albedo in ``albedo``.

    ``shadow`` = ``"left"``, ``"right"``, ``"top"`` or ``"bottom"`` blacks out that half
    (a half of the image in shadow, or covered).
    """
    H, W = camera_size
    tex = fine_texture(H, W, np.random.default_rng([int(seed), 0x7A67]))
    lo, hi = albedo
    img = (lo + (hi - lo) * tex).astype(np.float32)
    halves = {"left": (slice(None), slice(0, W // 2)), "right": (slice(None), slice(W // 2, None)),
              "top": (slice(0, H // 2), slice(None)), "bottom": (slice(H // 2, None), slice(None))}
    if shadow is not None:
        if shadow not in halves:
            raise ValueError(f"`shadow` must be left, right, top, bottom or None; got {shadow!r}")
        img[halves[shadow]] = 0
    return img[None]


__all__ = ["FOCAL_PX", "HIDDEN_K", "HIDDEN_PERIOD_US", "PROJECTOR_SCALE", "TARGET_EFFECTS", "coarse_homography",
           "fine_homography", "hidden_timing", "plane_homography", "target_video"]
