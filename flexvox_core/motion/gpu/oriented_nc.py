r"""The structure tensor of every sub-frame of a guide video on the GPU, and the kernel of oriented nc's bank it
chooses per voxel (:func:`~flexvox_core.reconstruct.oriented_nc.structure`,
:func:`~flexvox_core.reconstruct.oriented_nc.bank_index`).

.. math::

    J = G_\rho * (\nabla I_\sigma \nabla I_\sigma^\top), \qquad I_\sigma = G_{\sigma_p} * I,

σ_p = :data:`~flexvox_core.reconstruct.oriented_nc.PRE_SIGMA`, ρ = :data:`~flexvox_core.reconstruct.oriented_nc.RHO`,
G OpenCV's Gaussian blur (:func:`~flexvox_core.gpu.filters.gaussian_taps`, rows then columns) and ∇ Sobel's
3×3 derivative scaled by ⅛ (:func:`flexvox_core.slopes.slopes`), all with reflecting borders (``BORDER_REFLECT``).
The bank index rounds the anisotropy A = √((J_xx − J_yy)² + 4 J_xy²) / (J_xx + J_yy) to the nearest level and the
direction ½ atan2(2 J_xy, J_xx − J_yy) to one of 8, with the CPU kernel's float64 comparisons. Four launches over
every voxel of every sub-frame; float32 sums.

References
----------
T. Q. Pham, L. J. van Vliet, K. Schutte, "Robust fusion of irregularly sampled data using adaptive normalized
convolution", EURASIP J. Adv. Signal Process. 2006, 083268.
J. Bigün, G. H. Granlund, "Optimal orientation detection of linear symmetry", ICCV 1987, pp. 433–438.
"""

from __future__ import annotations

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur, gaussian_taps, reflected, tap_sum
from flexvox_core.gpu.index import reflect, voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.reconstruct.oriented_nc import _HIGH, _LOW, _TAN, PRE_SIGMA, RHO
from flexvox_core.reconstruct.oriented_nc_kernel import bank_of

F3 = "float32[:, :, ::1]"
U3 = "uint8[:, :, ::1]"


@device
def _sobel_at(p, s, y, x, H, W):
    """(∂x, ∂y) of plane s at (y, x): Sobel's 3×3 derivative scaled by ⅛ (OpenCV's row pass, then column pass:
    [−1, 0, 1]·⅛ along x and [1, 2, 1] along y for ∂x, the transpose for ∂y), reflecting."""
    xl = reflect(x - 1, W)
    xr = reflect(x + 1, W)
    yu = reflect(y - 1, H)
    yd = reflect(y + 1, H)
    eighth = np.float32(0.125)
    two = np.float32(2)
    gx = ((p[s, yu, xr] - p[s, yu, xl]) * eighth + ((p[s, y, xr] - p[s, y, xl]) * eighth) * two
          + (p[s, yd, xr] - p[s, yd, xl]) * eighth)
    top = p[s, yu, xl] + p[s, yu, x] * two + p[s, yu, xr]
    bottom = p[s, yd, xl] + p[s, yd, x] * two + p[s, yd, xr]
    return gx, (bottom - top) * eighth


@device
def _gxx(p, s, y, x, H, W):
    """∂x² of plane s at (y, x), x reflected (a value :func:`~flexvox_core.gpu.filters.tap_sum` reads)."""
    gx, _ = _sobel_at(p, s, y, reflect(x, W), H, W)
    return gx * gx


@device
def _gxy(p, s, y, x, H, W):
    """∂x·∂y of plane s at (y, x), x reflected."""
    gx, gy = _sobel_at(p, s, y, reflect(x, W), H, W)
    return gx * gy


@device
def _gyy(p, s, y, x, H, W):
    """∂y² of plane s at (y, x), x reflected."""
    _, gy = _sobel_at(p, s, y, reflect(x, W), H, W)
    return gy * gy


@kernel(f"void({F3}, float32[::1], {F3}, {F3}, {F3})")
def _products_x(p, taps, rxx, rxy, ryy):
    """The gradient products of every plane of the blurred guide ``p``, blurred along x (reflecting)."""
    i = cuda.grid(1)
    S, H, W = p.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    axx = tap_sum(_gxx, p, s, y, x, H, W, taps, 2)
    axy = tap_sum(_gxy, p, s, y, x, H, W, taps, 2)
    ayy = tap_sum(_gyy, p, s, y, x, H, W, taps, 2)
    rxx[s, y, x] = axx
    rxy[s, y, x] = axy
    ryy[s, y, x] = ayy


_bank_index = device(bank_of)
"""The CPU kernel's scalar bank index (:func:`~flexvox_core.reconstruct.oriented_nc_kernel.bank_of`) on the card."""


@kernel(f"void({F3}, {F3}, {F3}, float32[::1], {U3}, float32[:, :, :, ::1], uint8)")
def _structure_y(rxx, rxy, ryy, taps, bank, j, keep):
    """The column pass of the structure tensor, and the bank index from it (J itself into ``j`` if ``keep``)."""
    i = cuda.grid(1)
    S, H, W = bank.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    jxx = tap_sum(reflected, rxx, s, y, x, H, W, taps, 1)
    jxy = tap_sum(reflected, rxy, s, y, x, H, W, taps, 1)
    jyy = tap_sum(reflected, ryy, s, y, x, H, W, taps, 1)
    bank[s, y, x] = _bank_index(float(jxx), float(jxy), float(jyy), _LOW, _HIGH, _TAN)
    if keep:
        j[0, s, y, x] = jxx
        j[1, s, y, x] = jxy
        j[2, s, y, x] = jyy


def structure_bank(ws, guide, bank, j=None) -> None:
    """The bank index (S, H, W) uint8 of every voxel of ``guide`` (S, H, W) float32 (device arrays) from its
    sub-frame's structure tensor; the tensor (3, S, H, W) float32 into ``j`` too if given. Uses the
    workspace's ``choice.vol0`` … ``choice.vol3``."""
    S, H, W = guide.shape
    n = S * H * W
    v0, v1, v2, v3 = (ws.get(f"choice.vol{k}", (S, H, W)) for k in range(4))
    rho = ws.put("choice.taps.rho", gaussian_taps(RHO))
    pre = gaussian_taps(PRE_SIGMA)
    blur(ws, guide, v1, pre, pre, tag="choice.pre", scratch=v0)
    launch(_products_x, n, v1, rho, v0, v2, v3)
    keep = j is not None
    if not keep:
        j = ws.get("choice.j0", (3, 1, 1, 1))
    launch(_structure_y, n, v0, v2, v3, rho, bank, j, np.uint8(keep))
