r"""The per-voxel diffusion tensor of the paper's Eq. 4, and the resolution it amounts to.

With (u, v) the flow at a voxel (pixels per sub-frame):

.. math::

    \lambda = \frac{(u, v, 1)}{\sqrt{u^2 + v^2 + 1}}, \quad \psi = \lambda \times (0, 0, 1),
    \quad \gamma = \lambda \times \psi, \qquad T = c_1 \lambda\lambda^T + c_2 \psi\psi^T + c_3 \gamma\gamma^T

in (x, y, t) order. Where the flow is (nearly) zero, ψ is undefined; flexvox takes
ψ = (0, −1, 0), so zero flow gives the fixed tensor ``diag(c3, c2, c1)`` (with the
default c2 = c3: ``diag(0.05, 0.05, 0.95)``, the paper's high-SR tensor up to scale).
"""

from __future__ import annotations

import numpy as np

DEFAULT_C = (0.95, 0.05, 0.05)
"""(c1, c2, c3) of the paper: smooth sharply along the motion direction λ."""

_EPS = 1e-6


def check_c(c) -> tuple[float, float, float]:
    """``(c1, c2, c3)`` as floats with c1 ≥ c2 ≥ c3 ≥ 0 (what the monotone schemes need)."""
    try:
        c1, c2, c3 = (float(x) for x in c)
    except (TypeError, ValueError):
        raise ValueError(f"`c` must be three numbers (c1, c2, c3); got {c!r}") from None
    if not all(np.isfinite([c1, c2, c3])) or not c1 >= c2 >= c3 >= 0 or c1 == 0:
        raise ValueError(f"`c` must satisfy c1 >= c2 >= c3 >= 0 and c1 > 0 (finite); got {(c1, c2, c3)}")
    return c1, c2, c3


def frames_basis(flow: np.ndarray):
    """Unit vectors λ, ψ, γ of every voxel: three arrays ``(..., 3)`` in (x, y, t) order."""
    f = np.asarray(flow, dtype=np.float64)
    u, v = f[..., 0], f[..., 1]
    norm = np.sqrt(u * u + v * v + 1)
    lam = np.stack([u / norm, v / norm, 1 / norm], axis=-1)
    speed = np.hypot(u, v)
    moving = speed > _EPS
    # ψ = λ × (0, 0, 1) = (λy, -λx, 0), normalised; (0, 1, 0)·-1 convention where still.
    sx = np.where(moving, v / np.maximum(speed, _EPS), 0.0)
    sy = np.where(moving, -u / np.maximum(speed, _EPS), -1.0)
    psi = np.stack([sx, sy, np.zeros_like(sx)], axis=-1)
    gam = np.cross(lam, psi)
    return lam, psi, gam


def tensor_field(flow, c=DEFAULT_C) -> np.ndarray:
    """The tensor of Eq. 4 at every voxel: ``(..., 3, 3)`` float32 for a flow ``(..., 2)``.

    Memory is 9 floats per voxel; reconstructions never build it (they use λ and the
    coefficients directly), it is here for inspection and tests.
    """
    c1, c2, c3 = check_c(c)
    lam, psi, gam = frames_basis(flow)
    T = (c1 * lam[..., :, None] * lam[..., None, :] + c2 * psi[..., :, None] * psi[..., None, :]
         + c3 * gam[..., :, None] * gam[..., None, :])
    return T.astype(np.float32)


def resolution_map(flow, K: int, c=DEFAULT_C) -> tuple[np.ndarray, np.ndarray]:
    """Effective [TR, SR] the motion-aware tensor chooses at every voxel.

    The share of the tensor along time, τ = T_tt / trace T, runs from c1/Σc (still: smoothing
    mostly in time, high SR) to c3/Σc (fast: smoothing in space, high TR). flexvox reports
    ``TR = K^(1 − τ)`` and ``SR = 1/TR``, which puts ``diag(0, 0, 1)`` at [1, 1] and
    ``diag(1, 1, 0)`` at [K, 1/K], as the paper's limiting cases.
    """
    c1, c2, c3 = check_c(c)
    f = np.asarray(flow, dtype=np.float32)
    tr = np.empty(f.shape[:-1], np.float32)
    sr = np.empty_like(tr)
    a, b, logk = np.float32(c1), np.float32(c3), np.float32(np.log(K))
    total = np.float32(c1 + c2 + c3)
    for i in np.ndindex(f.shape[:-3]) if f.ndim > 3 else [()]:  # a frame at a time: stays in cache
        u, v = f[i][..., 0], f[i][..., 1]
        s2 = u * u + v * v
        s2[~np.isfinite(s2)] = 0
        tau = (a + b * s2) / ((1 + s2) * total)
        np.exp((1 - tau) * logk, out=tr[i])
        np.divide(1, tr[i], out=sr[i])
    return tr, sr
