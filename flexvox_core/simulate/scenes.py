"""Built-in procedural scenes, by name.

Stand-ins for the paper's sequences: ``drummer`` for its drums (§2, Figs. 1, 3–5), ``fan`` for its
rotating fan (Fig. 7), ``balls`` for its bouncing balls (Fig. 8).

Each renders a high-speed video ``(S, H, W)`` float32 in [0, 1], deterministic for a
seed. Motion is given in pixels per *sub-frame* (one shutter slot).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from flexvox_core.memory_budget import check_fits, render_bytes
from flexvox_core.simulate.textures import bar_coverage, disc_coverage, fine_texture, shift_image


@dataclass(frozen=True)
class BuiltinScene:
    """A named procedural scene and what it shows."""

    name: str
    description: str
    render: Callable[[int, int, int, np.random.Generator], np.ndarray]


def _fan(S, H, W, rng):
    wall = fine_texture(H, W, rng)
    blade_tex = fine_texture(H, W, rng, contrast=0.6) * 0.5 + 0.5
    cy, cx = H / 2, W / 2
    radius = 0.42 * min(H, W)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = np.arctan2(yy - cy, xx - cx)
    rr = np.hypot(yy - cy, xx - cx)
    hub = disc_coverage(H, W, cx, cy, 0.08 * min(H, W))
    out = np.empty((S, H, W), np.float32)
    omega = 2 * np.pi / 48  # one turn every 48 sub-frames: tips move ~radius*0.13 px/sub-frame
    for s in range(S):
        # 3 blades; supersample the blade edge in angle with a soft ramp of ~1 px at the tip
        phase = (ang - omega * s) * 3 / (2 * np.pi)
        frac = phase - np.floor(phase)
        edge = np.clip((0.35 - np.abs(frac - 0.5)) * rr * 2 * np.pi / 3 + 0.5, 0, 1)
        blade = edge * np.clip(radius - rr + 0.5, 0, 1) * np.clip(rr - 0.08 * min(H, W) + 0.5, 0, 1)
        img = wall * (1 - blade) + blade_tex * blade
        out[s] = img * (1 - hub) + 0.3 * hub
    return out


def _balls(S, H, W, rng):
    wall = fine_texture(H, W, rng) * 0.6 + 0.2
    n = 4
    r = rng.uniform(0.07, 0.12, n) * min(H, W)
    pos = np.stack([rng.uniform(r, W - r), rng.uniform(r, H - r)], axis=1)
    speed = rng.uniform(1.5, 4.0, n)  # px per sub-frame
    angle = rng.uniform(0, 2 * np.pi, n)
    vel = np.stack([np.cos(angle), np.sin(angle)], axis=1) * speed[:, None]
    shade = rng.uniform(0.75, 1.0, n)
    out = np.empty((S, H, W), np.float32)
    for s in range(S):
        img = wall.copy()
        for k in range(n):
            cov = disc_coverage(H, W, pos[k, 0], pos[k, 1], r[k])
            img = img * (1 - cov) + shade[k] * cov
        out[s] = img
        pos += vel
        for k in range(n):  # bounce off the walls
            for axis, limit in ((0, W), (1, H)):
                if pos[k, axis] < r[k] or pos[k, axis] > limit - r[k]:
                    vel[k, axis] *= -1
                    pos[k, axis] = np.clip(pos[k, axis], r[k], limit - r[k])
    return out


def _drummer(S, H, W, rng):
    """A slowly swaying body, fast sticks, drums that move only on impact."""
    wall = fine_texture(H, W, rng) * 0.5
    body_tex = fine_texture(H, W, rng) * 0.5 + 0.35
    drum_tex = fine_texture(H, W, rng) * 0.4 + 0.5
    out = np.empty((S, H, W), np.float32)
    period = 24  # sub-frames per stick stroke
    for s in range(S):
        sway = 0.04 * W * math.sin(2 * math.pi * s / 160)  # slow: < 0.1 px per sub-frame
        img = wall.copy()
        body = disc_coverage(H, W, W / 2 + sway, 0.42 * H, 0.22 * min(H, W))
        img = img * (1 - body) + shift_image(body_tex, sway, 0) * body
        hits = []
        for side, drum_x in ((-1, 0.25 * W), (1, 0.75 * W)):
            t = ((s + (period // 2 if side > 0 else 0)) % period) / period
            swing = abs(math.sin(math.pi * t))  # 0 at impact, 1 at the top
            hand = (W / 2 + sway + side * 0.18 * W, 0.55 * H)
            tip_angle = math.radians(15 + 75 * swing)
            tip = (hand[0] + side * 0.3 * W * math.cos(tip_angle), hand[1] - 0.3 * W * math.sin(tip_angle) + 0.12 * H)
            stick = bar_coverage(H, W, hand[0], hand[1], tip[0], tip[1], 0.012 * min(H, W) + 0.6)
            hits.append((drum_x, swing < 0.15))
            img = img * (1 - stick) + 0.95 * stick
        for drum_x, hit in hits:
            dy = 0.02 * H if hit else 0.0  # drums move only on impact
            drum = disc_coverage(H, W, drum_x, 0.82 * H + dy, 0.14 * min(H, W))
            img = img * (1 - drum) + shift_image(drum_tex, 0, dy) * drum
        out[s] = img
    return out


def _pan(S, H, W, rng):
    """A slowly panning texture (0.15 px/sub-frame) with a small fast object (6 px/sub-frame)."""
    big = fine_texture(H, W, rng)
    out = np.empty((S, H, W), np.float32)
    r = max(2.0, 0.05 * min(H, W))
    for s in range(S):
        img = shift_image(big, 0.15 * s, 0.05 * s)
        x = (0.1 * W + 6.0 * s) % W
        y = 0.3 * H + 0.15 * H * math.sin(2 * math.pi * s / 40)
        cov = disc_coverage(H, W, x, y, r)
        out[s] = img * (1 - cov) + 1.0 * cov
    return out


def _static(S, H, W, rng):
    return np.repeat(fine_texture(H, W, rng)[None], S, axis=0)


STROBE_PERIOD = 17
"""Sub-frames between the strobe's flashes: with K = 16 slots per frame, the flash lands one slot
earlier in every frame, so 17 frames visit every slot."""


def _strobe(S, H, W, rng):
    """A still textured wall lit by a strobe: bright in one sub-frame of every 17, dark otherwise."""
    wall = fine_texture(H, W, rng) * 0.7 + 0.3
    out = np.zeros((S, H, W), np.float32)
    out[::STROBE_PERIOD] = wall
    return out


SCENES: dict[str, BuiltinScene] = {
    s.name: s
    for s in (
        BuiltinScene("fan", "a rotating three-blade fan over a textured wall", _fan),
        BuiltinScene("balls", "four bouncing balls (1.5-4 px per sub-frame) over a textured wall", _balls),
        BuiltinScene("drummer", "a slowly swaying body, fast sticks, drums that move only on impact", _drummer),
        BuiltinScene("pan", "a slowly panning texture with a small fast object", _pan),
        BuiltinScene("static", "a still textured wall (nothing moves)", _static),
        BuiltinScene("strobe", "a still wall lit in one sub-frame of every 17: shows which slot each pixel "
                     "samples (flexvox info --slots)", _strobe),
    )
}
"""Every built-in scene by name (a :class:`BuiltinScene`: its name, what it shows, its renderer); render one with
:func:`render_scene`."""


def render_scene(name: str, subframes: int, height: int, width: int, *, seed: int = 0,
                 advice: str = "use a smaller size or fewer frames") -> np.ndarray:
    """Render built-in scene ``name`` as ``(subframes, height, width)`` float32 in [0, 1].

    Parameters
    ----------
    name : str
        A key of :data:`SCENES`: ``fan``, ``balls``, ``drummer``, ``pan``, ``static`` or ``strobe``.
    subframes : int
        S, the sub-frames (shutter slots) to render, >= 1: K per camera frame.
    height, width : int
        The frame size in pixels, each >= 8.
    seed : int
        Seeds the scene's textures and motion: the same seed renders the same video.
    advice : str
        How the caller's user can ask for less, ending the refusal of a video too large for memory.

    Returns
    -------
    ndarray (subframes, height, width) float32
        Values in [0, 1]; motion is in pixels per sub-frame.

    Raises
    ------
    ValueError
        An unknown scene, or a size that is not a whole number in range.
    MemoryBudgetError
        A video that would not fit in memory (:class:`~flexvox_core.memory_budget.MemoryBudgetError`), before
        any of it is made.

    Examples
    --------
    >>> from flexvox_core import render_scene
    >>> render_scene("balls", 32, 24, 32, seed=1).shape
    (32, 24, 32)
    """
    if name not in SCENES:
        raise ValueError(f"unknown scene {name!r}; built-in scenes: {', '.join(SCENES)}")
    for label, v, lo in (("subframes", subframes, 1), ("height", height, 8), ("width", width, 8)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
            raise ValueError(f"`{label}` must be a whole number >= {lo}; got {v!r}")
    check_fits(render_bytes(int(subframes), int(height), int(width)),
               f"the {name} scene at {height}x{width} with {subframes} sub-frames",
               advice)
    video = SCENES[name].render(int(subframes), int(height), int(width), np.random.default_rng(seed))
    return np.clip(video, 0, 1, out=video).astype(np.float32, copy=False)
