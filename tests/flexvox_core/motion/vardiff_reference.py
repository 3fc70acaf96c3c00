"""The variable-tensor diffusion in plain numpy and scipy, float64: the reference the tests compare
:func:`flexvox_core.motion.vardiff.variable_tensor_diffusion` (compiled) with."""

import numpy as np

from flexvox_core.motion.tensors import DEFAULT_C
from flexvox_core.motion.vardiff import _check


def _sample(img: np.ndarray, gy, gx) -> np.ndarray:
    """Exact bilinear reads at (gy, gx), clamped at the border."""
    from scipy.ndimage import map_coordinates

    H, W = img.shape
    return map_coordinates(img.astype(np.float64), [np.clip(gy, 0, H - 1), np.clip(gx, 0, W - 1)], order=1,
                           mode="nearest")


def _sample_sharp(img: np.ndarray, gy, gx) -> np.ndarray:
    """Catmull-Rom reads at (gy, gx), clamped at the border, clipped to the range of the four nearest pixels."""
    H, W = img.shape
    img = img.astype(np.float64)
    y, x = np.clip(gy, 0, H - 1), np.clip(gx, 0, W - 1)
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)

    def weights(t):
        return (-0.5 * t**3 + t**2 - 0.5 * t, 1.5 * t**3 - 2.5 * t**2 + 1, -1.5 * t**3 + 2 * t**2 + 0.5 * t,
                0.5 * t**3 - 0.5 * t**2)

    wx, wy = weights(x - x0), weights(y - y0)
    ys = [np.clip(y0 + k - 1, 0, H - 1) for k in range(4)]
    xs = [np.clip(x0 + k - 1, 0, W - 1) for k in range(4)]
    value = sum(wy[j] * sum(wx[i] * img[ys[j], xs[i]] for i in range(4)) for j in range(4))
    four = [img[ys[1], xs[1]], img[ys[1], xs[2]], img[ys[2], xs[1]], img[ys[2], xs[2]]]
    return np.clip(value, np.minimum.reduce(four), np.maximum.reduce(four))


def variable_tensor_diffusion_reference(init, mask, flow, *, c=DEFAULT_C, time: float = 1.0,
                                        keep_samples: bool = True, sharp=None, still_speed=None) -> np.ndarray:
    """:func:`variable_tensor_diffusion` in plain numpy and scipy, float64 (slow; the tests' reference)."""
    (c1, c2, c3), vol, m, f, steps, dt = _check(init, mask, flow, time, c)
    m, f = np.asarray(m, bool), np.asarray(f)
    sh = None if sharp is None else np.asarray(sharp, bool)
    vol = vol.astype(np.float64)
    S, H, W = vol.shape
    f = np.where(np.isfinite(f), f, 0).astype(np.float64)
    if still_speed is not None:  # slower than it: still
        f[f[..., 0] ** 2 + f[..., 1] ** 2 < float(still_speed) ** 2] = 0
    gx, gy = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    speed2 = f[..., 0] ** 2 + f[..., 1] ** 2
    a = (c1 - c3) / (1 + speed2)
    b = c2 - c3
    speed = np.sqrt(speed2)
    moving = speed > 1e-6
    psx = np.where(moving, f[..., 1] / np.maximum(speed, 1e-6), 0)
    psy = np.where(moving, -f[..., 0] / np.maximum(speed, 1e-6), -1)
    free = ~m if keep_samples else np.ones_like(m)
    new = np.empty_like(vol)
    for _ in range(steps):
        for t in range(S):
            cur = vol[t]
            u, v = f[t, ..., 0], f[t, ..., 1]
            nxt = _sample(vol[t + 1], gy + v, gx + u) if t + 1 < S else cur
            prv = _sample(vol[t - 1], gy - v, gx - u) if t > 0 else cur
            if sh is not None and sh[t].any():
                if t + 1 < S:
                    nxt = np.where(sh[t], _sample_sharp(vol[t + 1], gy + v, gx + u), nxt)
                if t > 0:
                    prv = np.where(sh[t], _sample_sharp(vol[t - 1], gy - v, gx - u), prv)
            acc = a[t] * (nxt + prv - 2 * cur)
            if b > 0:
                acc += b * (_sample(cur, gy + psy[t], gx + psx[t]) + _sample(cur, gy - psy[t], gx - psx[t]) - 2 * cur)
            if c3 > 0:
                up = vol[t + 1] if t + 1 < S else cur
                dn = vol[t - 1] if t > 0 else cur
                lap = up + dn - 2 * cur
                lap[:, 1:-1] += cur[:, 2:] + cur[:, :-2] - 2 * cur[:, 1:-1]
                lap[1:-1, :] += cur[2:, :] + cur[:-2, :] - 2 * cur[1:-1, :]
                if W > 1:
                    lap[:, 0] += cur[:, 1] - cur[:, 0]
                    lap[:, -1] += cur[:, -2] - cur[:, -1]
                if H > 1:
                    lap[0, :] += cur[1, :] - cur[0, :]
                    lap[-1, :] += cur[-2, :] - cur[-1, :]
                acc += c3 * lap
            new[t] = np.where(free[t], cur + dt * acc, cur)
        vol, new = new, vol
    return vol
