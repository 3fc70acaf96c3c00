"""Synthetic image pairs with known flow for the DIS tests, and the end-point-error table of
docs/gpu.md ("Optical flow on the GPU (DIS)").

Each pair samples a smooth random texture T (Gaussian-blurred noise): I0(x) = T(x) and I1 the texture moved
by an affine motion about the image centre c, so that the true flow is u(x) = (A - 1)(x - c) + t
(I1(x + u(x)) = I0(x)); the moving-square pair pastes a second texture over a static one. Run
``python -m tests.flexvox_core.gpu.dis_cases`` from the repository root to print the tables (the second: the
built-in scenes' high-TR pairs, as motion-aware's flow sees them; no true flow there, the reference against
OpenCV only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

MARGIN = 40
"""Texture beyond the image on every side (so that the moved image has no border fill)."""


@dataclass(frozen=True)
class Case:
    name: str
    I0: np.ndarray  # (H, W) uint8
    I1: np.ndarray  # (H, W) uint8
    truth: np.ndarray  # (H, W, 2) float32
    mask: np.ndarray  # (H, W) bool: where the truth is compared (inside, away from edges and occlusions)


def texture(rng: np.random.Generator, h: int, w: int, sigma: float = 1.5) -> np.ndarray:
    """float32 (h + 2 MARGIN, w + 2 MARGIN) in [0, 255]: blurred uniform noise, stretched to the range."""
    a = cv2.GaussianBlur(rng.random((h + 2 * MARGIN, w + 2 * MARGIN)).astype(np.float32), (0, 0), sigma)
    return (a - a.min()) / (a.max() - a.min()) * np.float32(255)


def _sample(T: np.ndarray, mx: np.ndarray, my: np.ndarray) -> np.ndarray:
    out = cv2.remap(T, (mx + MARGIN).astype(np.float32), (my + MARGIN).astype(np.float32), cv2.INTER_CUBIC,
                    borderMode=cv2.BORDER_REFLECT)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def affine_case(name: str, rng, h: int, w: int, *, shift=(0.0, 0.0), angle_deg=0.0, zoom=1.0, edge=8) -> Case:
    """x -> A (x - c) + c + shift, A a rotation by ``angle_deg`` times ``zoom``."""
    T = texture(rng, h, w)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    th = math.radians(angle_deg)
    A = zoom * np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    Ai = np.linalg.inv(A)
    # I1(y) = T(x) where y = A (x - c) + c + shift
    dx, dy = xx - c[0] - shift[0], yy - c[1] - shift[1]
    sx, sy = Ai[0, 0] * dx + Ai[0, 1] * dy + c[0], Ai[1, 0] * dx + Ai[1, 1] * dy + c[1]
    I0, I1 = _sample(T, xx, yy), _sample(T, sx, sy)
    ux = (A[0, 0] - 1) * (xx - c[0]) + A[0, 1] * (yy - c[1]) + shift[0]
    uy = A[1, 0] * (xx - c[0]) + (A[1, 1] - 1) * (yy - c[1]) + shift[1]
    truth = np.stack([ux, uy], -1).astype(np.float32)
    mask = np.zeros((h, w), bool)
    mask[edge:h - edge, edge:w - edge] = True
    # only where the moved point stays inside the image
    mask &= (xx + ux >= 0) & (xx + ux <= w - 1) & (yy + uy >= 0) & (yy + uy <= h - 1)
    return Case(name, I0, I1, truth, mask)


def square_case(name: str, rng, h: int, w: int, *, side=32, move=(3, 2), edge=8) -> Case:
    """A textured square of ``side`` pixels moved by ``move`` (whole pixels) over a static texture."""
    B, S = texture(rng, h, w)[MARGIN:MARGIN + h, MARGIN:MARGIN + w], texture(rng, side, side)
    S = S[MARGIN:MARGIN + side, MARGIN:MARGIN + side]
    y0, x0 = (h - side) // 2, (w - side) // 2
    I0, I1 = B.copy(), B.copy()
    I0[y0:y0 + side, x0:x0 + side] = S
    I1[y0 + move[1]:y0 + move[1] + side, x0 + move[0]:x0 + move[0] + side] = S
    truth = np.zeros((h, w, 2), np.float32)
    truth[y0:y0 + side, x0:x0 + side] = move
    mask = np.zeros((h, w), bool)
    mask[edge:h - edge, edge:w - edge] = True
    # leave out a band of 4 pixels around both squares' outlines (occlusion, disocclusion)
    band = np.zeros((h, w), bool)
    for oy, ox in ((y0, x0), (y0 + move[1], x0 + move[0])):
        band[max(oy - 4, 0):oy + side + 4, max(ox - 4, 0):ox + side + 4] = True
        band[oy + 4:oy + side - 4, ox + 4:ox + side - 4] = False
    mask &= ~band
    return Case(name, np.rint(I0).astype(np.uint8), np.rint(I1).astype(np.uint8), truth, mask)


def cases(seed: int = 20261121) -> list[Case]:
    """The synthetic pairs of the tests and the docs' table."""
    rng = np.random.default_rng(seed)
    return [
        affine_case("translation (0.37, -0.21) px, 64x96", rng, 64, 96, shift=(0.37, -0.21)),
        affine_case("translation (1.3, -0.6) px, 80x107", rng, 80, 107, shift=(1.3, -0.6)),
        affine_case("translation (4.6, 2.3) px, 128x160", rng, 128, 160, shift=(4.6, 2.3)),
        affine_case("rotation 2 deg, 128x160", rng, 128, 160, angle_deg=2.0),
        affine_case("zoom 1.04, 96x128", rng, 96, 128, zoom=1.04),
        square_case("square 32 px moved (3, 2) px, 96x128", rng, 96, 128),
    ]


def epe(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """End-point error |u - v| per pixel of (..., 2) flows."""
    return np.hypot(u[..., 0] - v[..., 0], u[..., 1] - v[..., 1])


def opencv_dis(I0: np.ndarray, I1: np.ndarray, p) -> np.ndarray:
    """OpenCV's DIS with the parameters of ``p`` (a DisParams)."""
    d = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    d.setPatchSize(p.patch_size)
    d.setPatchStride(p.patch_stride)
    d.setFinestScale(p.finest_scale)
    d.setGradientDescentIterations(p.gradient_descent_iterations)
    d.setVariationalRefinementIterations(p.variational_iterations)
    d.setVariationalRefinementAlpha(p.alpha)
    d.setVariationalRefinementDelta(p.delta)
    d.setVariationalRefinementGamma(p.gamma)
    d.setVariationalRefinementEpsilon(p.epsilon)
    d.setUseMeanNormalization(p.use_mean_normalization)
    d.setUseSpatialPropagation(p.use_spatial_propagation)
    return d.calc(I0, I1, None)


def epe_table(p=None) -> str:
    """Markdown table: per case, the numpy reference against OpenCV (mean, max) and each against the truth."""
    from flexvox_core.gpu.dis import DisParams
    from tests.flexvox_core.gpu.dis_reference import dis

    p = DisParams() if p is None else p
    lines = ["| case | reference vs OpenCV, mean / max (px) | reference vs truth (px) | OpenCV vs truth (px) |",
             "|---|---|---|---|"]
    for c in cases():
        ref, ocv = dis(c.I0, c.I1, p), opencv_dis(c.I0, c.I1, p)
        e = epe(ref, ocv)
        lines.append(f"| {c.name} | {e.mean():.1e} / {e.max():.1e} | {epe(ref, c.truth)[c.mask].mean():.3f} | "
                     f"{epe(ocv, c.truth)[c.mask].mean():.3f} |")
    return "\n".join(lines)



def scene_pairs(scene: str, *, h: int = 160, w: int = 213, pairs: int = 3):
    """Successive sub-frames of a built-in scene's high-TR reconstruction at the flow's size (what motion-aware's
    flow measures on a 640×480 clip), as uint8: ``pairs`` (I0, I1) from the middle of a 4-frame capture."""
    from flexvox_core.design import design_code
    from flexvox_core.flow.estimate import to_uint8
    from flexvox_core.forward import capture
    from flexvox_core.motion.options import STEP1_TENSOR, STEP1_TIME
    from flexvox_core.reconstruct import diffuse
    from flexvox_core.simulate.scenes import render_scene

    code = design_code((4, 4)).code
    truth = render_scene(scene, 4 * 16, h, w, seed=0)
    u8 = to_uint8(diffuse(capture(truth, code), code, tensor=STEP1_TENSOR, time=STEP1_TIME))
    mid = len(u8) // 2
    return [(u8[t], u8[t + 1]) for t in range(mid, mid + pairs)]


def scene_table(p=None, scenes=("balls", "drummer", "fan", "pan")) -> str:
    """Markdown table: per built-in scene, the numpy reference against OpenCV's DIS on its high-TR pairs."""
    from flexvox_core.gpu.dis import DisParams
    from tests.flexvox_core.gpu.dis_reference import dis

    p = DisParams() if p is None else p
    lines = ["| scene (160×213, high-TR pairs) | reference vs OpenCV, mean / max (px) | OpenCV's mean speed (px) |",
             "|---|---|---|"]
    for scene in scenes:
        errs, speeds = [], []
        for a, b in scene_pairs(scene):
            ref, ocv = dis(a, b, p), opencv_dis(a, b, p)
            errs.append(epe(ref, ocv))
            speeds.append(np.hypot(ocv[..., 0], ocv[..., 1]).mean())
        e = np.stack(errs)
        lines.append(f"| {scene} | {e.mean():.1e} / {e.max():.1e} | {np.mean(speeds):.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(epe_table())
    print()
    print(scene_table())
