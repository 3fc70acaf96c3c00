"""Pictures of flow a person would rather look at than read.

``flow_to_color`` uses the standard colour-wheel coding of the Middlebury flow benchmark
(Baker et al. 2011): hue = direction, saturation = speed (white = still); the wheel's 55
colours run red → yellow → green → cyan → blue → magenta in steps of 15, 6, 4, 11, 13, 6.
"""

from __future__ import annotations

import cv2
import numpy as np


def _color_wheel() -> np.ndarray:
    segments = [(15, (255, 0, 0), (255, 255, 0)), (6, (255, 255, 0), (0, 255, 0)),
                (4, (0, 255, 0), (0, 255, 255)), (11, (0, 255, 255), (0, 0, 255)),
                (13, (0, 0, 255), (255, 0, 255)), (6, (255, 0, 255), (255, 0, 0))]
    rows = []
    for n, a, b in segments:
        t = np.arange(n)[:, None] / n
        rows.append((1 - t) * np.array(a) + t * np.array(b))
    return np.concatenate(rows).astype(np.float64)  # (55, 3) RGB


_WHEEL = _color_wheel()


def flow_to_color(flow, *, max_magnitude: float | None = None) -> np.ndarray:
    """Colour-wheel picture ``(H, W, 3)`` uint8 RGB of a flow ``(H, W, 2)``.

    ``max_magnitude`` is the speed shown fully saturated (default: the largest in the field).
    Still pixels are white; rightward motion is red, upward (−v) blue-violet... as in the
    Middlebury coding. NaN/inf flow is drawn black.
    """
    f = np.asarray(flow, dtype=np.float64)
    if f.ndim != 3 or f.shape[-1] != 2:
        raise ValueError(f"`flow` must have shape (H, W, 2); got {f.shape}")
    bad = ~np.isfinite(f).all(axis=-1)
    f = np.where(bad[..., None], 0, f)
    u, v = f[..., 0], f[..., 1]
    mag = np.hypot(u, v)
    top = max_magnitude if max_magnitude is not None else float(mag.max())
    rad = mag / max(top, 1e-12)
    ang = np.arctan2(-v, -u) / np.pi  # in [-1, 1]
    k = (ang + 1) / 2 * (len(_WHEEL) - 1)
    k0 = np.floor(k).astype(int)
    k1 = (k0 + 1) % len(_WHEEL)
    t = (k - k0)[..., None]
    col = ((1 - t) * _WHEEL[k0] + t * _WHEEL[k1]) / 255
    inside = (rad <= 1)[..., None]
    col = np.where(inside, 1 - rad[..., None] * (1 - col), col * 0.75)
    img = (255 * col).round().astype(np.uint8)
    img[bad] = 0
    return img


def magnitude_image(flow, *, max_magnitude: float | None = None) -> np.ndarray:
    """Speed as a colour map (blue still → red fast, like the paper's Fig. 5b), ``(H, W, 3)`` uint8 RGB."""
    f = np.asarray(flow, dtype=np.float32)
    mag = np.hypot(f[..., 0], f[..., 1])
    mag[~np.isfinite(mag)] = 0
    top = max_magnitude if max_magnitude is not None else max(float(mag.max()), 1e-6)
    u8 = np.clip(mag / top * 255, 0, 255).astype(np.uint8)
    return cv2.cvtColor(cv2.applyColorMap(u8, cv2.COLORMAP_JET), cv2.COLOR_BGR2RGB)


def quiver_image(image, flow, *, step: int = 12, gain: float = 3.0, color=(255, 40, 40)) -> np.ndarray:
    """Arrows of the flow every ``step`` pixels over a grey image ``(H, W)`` in [0, 1]; RGB uint8.

    Arrows are drawn ``gain`` times their length so sub-pixel motion stays visible.
    """
    img = np.asarray(image, dtype=np.float32)
    f = np.asarray(flow, dtype=np.float32)
    if img.shape != f.shape[:2]:
        raise ValueError(f"`image` {img.shape} and `flow` {f.shape} must share (H, W)")
    if step < 1:
        raise ValueError(f"`step` must be >= 1; got {step}")
    rgb = cv2.cvtColor((np.clip(img, 0, 1) * 255).astype(np.uint8), cv2.COLOR_GRAY2RGB)
    H, W = img.shape
    for y in range(step // 2, H, step):
        for x in range(step // 2, W, step):
            u, v = f[y, x]
            if not (np.isfinite(u) and np.isfinite(v)) or np.hypot(u, v) < 0.05:
                continue
            end = (int(round(x + gain * u)), int(round(y + gain * v)))
            cv2.arrowedLine(rgb, (x, y), end, color, 1, cv2.LINE_AA, tipLength=0.3)
    return rgb
