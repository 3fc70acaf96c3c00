"""DIS optical flow on the GPU for a whole batch of image pairs per launch.

Dense Inverse Search (Kroeger, Timofte, Dai, Van Gool, "Fast Optical Flow using Dense Inverse Search",
ECCV 2016) as OpenCV's ``DISOpticalFlow`` (5.0) computes it, on every pair of a batch at once: per pyramid
level from coarse to fine, an inverse-compositional search of each patch (mean-normalised SSD, Gauss-Newton
steps), spatial propagation of the neighbours' flows, densification (each pixel's flow the average of the
covering patches' flows weighted by 1 / max(1, |I1(x + u) - I0(x)|)), variational refinement
(:mod:`flexvox_core.gpu.dis_refine`) and bilinear upsampling to the next level.

The patch search follows OpenCV's order exactly: the patch rows are cut into 8 stripes, and each stripe is
swept in raster order forward and then backward, every patch trying its own flow, its already-visited
left/right and upper/lower neighbours' and keeping the best before its Gauss-Newton steps. On the GPU one
thread holds one patch row and the rows of a stripe advance along anti-diagonals (patch (r, c) at step
r + c), with a block barrier per step: every patch sees the same neighbours as in the sequential sweep, so
the result is OpenCV's, with no approximation of the propagation.

:func:`dis_pairs` is the entry point; :class:`DisParams` holds the parameters (the "medium" preset by
default) and :class:`DisWorkspace` the device buffers, reused from call to call for the same sizes.

References
----------
T. Kroeger, R. Timofte, D. Dai, L. Van Gool, "Fast optical flow using dense inverse search", ECCV 2016.
T. Brox, A. Bruhn, N. Papenberg, J. Weickert, "High accuracy optical flow estimation based on a theory for
warping", ECCV 2004.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, fields

import numpy as np
from numba import cuda

from flexvox_core.gpu.device import simulator
from flexvox_core.gpu.dis_pyramid import gradients, reduce, to_output, upsample
from flexvox_core.gpu.dis_refine import RefineBuffers, refine_level, zero4
from flexvox_core.gpu.launch import BLOCK, SIM_BLOCK, device, kernel, launch

_logger = logging.getLogger(__name__)

BORDER = 16
"""OpenCV's replicated border around I1 (it bounds the clamp of the patch positions)."""
STRIPES = 8
"""Stripes of patch rows in the spatial propagation (OpenCV's fixed number)."""
EPS = np.float32(0.001)
INF = np.float32(1e10)
ZERO = np.float32(0.0)
ONE = np.float32(1.0)

PRESETS = {
    "ultrafast": dict(finest_scale=2, patch_stride=4, gradient_descent_iterations=12, variational_iterations=0),
    "fast": dict(finest_scale=2, patch_stride=4, gradient_descent_iterations=16, variational_iterations=5),
    "medium": dict(finest_scale=1, patch_stride=3, gradient_descent_iterations=25, variational_iterations=5),
}
"""OpenCV's presets (patch size 8 in all)."""


@dataclass(frozen=True)
class DisParams:
    """DIS's parameters, OpenCV's names and meanings. The defaults are OpenCV's "medium" preset with two
    fixed-point iterations of the refinement (what flexvox's CPU pipeline runs).

    patch_size, patch_stride : int
        Side of the square patches and the step between their top-left corners (pixels of a level).
    gradient_descent_iterations : int
        Gauss-Newton steps per patch, split evenly over the forward and backward sweep when
        ``use_spatial_propagation``.
    finest_scale : int
        The finest pyramid level searched (0: full size); the flow is upsampled from it.
    variational_iterations, sor_iterations : int
        Fixed-point iterations of the variational refinement (0: none) and red-black SOR sweeps in each
        (OpenCV fixes 5).
    alpha, delta, gamma, epsilon : float
        Smoothness, brightness-constancy and gradient-constancy weights, and the robust penalty's
        epsilon in sqrt(s² + epsilon²) (OpenCV's DIS default 0.01).
    use_mean_normalization, use_spatial_propagation : bool
        Patch distances with each patch's mean difference removed; neighbours' flows as candidates.
    """

    patch_size: int = 8
    patch_stride: int = 3
    gradient_descent_iterations: int = 25
    finest_scale: int = 1
    variational_iterations: int = 2
    sor_iterations: int = 5
    alpha: float = 20.0
    delta: float = 5.0
    gamma: float = 10.0
    epsilon: float = 0.01
    use_mean_normalization: bool = True
    use_spatial_propagation: bool = True

    def __post_init__(self):
        ints = {"patch_size": (2, 16), "patch_stride": (1, self.patch_size if _is_int(self.patch_size) else 16),
                "gradient_descent_iterations": (1, 1000), "finest_scale": (0, 10),
                "variational_iterations": (0, 1000), "sor_iterations": (0, 1000)}
        for name, (lo, hi) in ints.items():
            v = getattr(self, name)
            if not _is_int(v) or not lo <= v <= hi:
                raise ValueError(f"DisParams.{name} must be an integer from {lo} to {hi}; got {v!r}")
        for name in ("alpha", "delta", "gamma"):
            v = getattr(self, name)
            if not _is_real(v) or not math.isfinite(v) or v < 0:
                raise ValueError(f"DisParams.{name} must be a finite number >= 0; got {v!r}")
        if not _is_real(self.epsilon) or not math.isfinite(self.epsilon) or self.epsilon <= 0:
            raise ValueError(f"DisParams.epsilon must be a finite number > 0; got {self.epsilon!r}")
        for name in ("use_mean_normalization", "use_spatial_propagation"):
            if not isinstance(getattr(self, name), bool | np.bool_):
                raise ValueError(f"DisParams.{name} must be True or False; got {getattr(self, name)!r}")

    @classmethod
    def from_preset(cls, name: str, **overrides) -> DisParams:
        """OpenCV's preset ``name`` (ultrafast, fast, medium) with ``overrides`` (field names)."""
        if name not in PRESETS:
            raise ValueError(f"DIS preset must be one of {', '.join(PRESETS)}; got {name!r}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            raise ValueError(f"DisParams has no field {unknown[0]!r}; its fields: {', '.join(sorted(known))}")
        return cls(**{**PRESETS[name], **overrides})


def _is_int(v) -> bool:
    return isinstance(v, int | np.integer) and not isinstance(v, bool | np.bool_)


def _is_real(v) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool | np.bool_)


def scales(H: int, W: int, p: DisParams) -> tuple[int, int]:
    """(finest, coarsest) pyramid scale for (H, W) images.

    OpenCV's rule: coarsest = min(int(log2(max(W, H) / (4 patch)) + 0.5), int(log2(min(W, H) // patch))),
    motions up to a quarter of the larger side and no level narrower than a patch. Where that is finer
    than ``finest_scale`` (small images) the levels run from the full size (0) to
    min(max(0, floor(log2(2 W / (5 patch)))), the patch bound) — OpenCV 5.0's levels there, measured for
    finest_scale 1 and 2 (older OpenCV reads past its buffers on such images).
    """
    psz = p.patch_size
    by_motion = int(math.log(max(W, H) / (4.0 * psz)) / math.log(2.0) + 0.5)
    by_patch = int(math.log(min(W, H) // psz) / math.log(2.0))
    coarsest = min(by_motion, by_patch)
    if coarsest >= p.finest_scale:
        return p.finest_scale, coarsest
    return 0, min(max(0, math.floor(math.log2(2.0 * W / (5.0 * psz)))), by_patch)


def level_shapes(H: int, W: int, p: DisParams) -> list[tuple[int, int]]:
    """(h, w) of the levels, finest first: H // 2**finest, then halved (floor) per level."""
    f, c = scales(H, W, p)
    out = [(H // 2**f, W // 2**f)]
    for _ in range(f, c):
        out.append((out[-1][0] // 2, out[-1][1] // 2))
    return out


def patch_grid(h: int, w: int, p: DisParams) -> tuple[int, int]:
    """(hs, ws): patches per column and per row of an (h, w) level."""
    return 1 + (h - p.patch_size) // p.patch_stride, 1 + (w - p.patch_size) // p.patch_stride


def _block() -> int:
    return SIM_BLOCK if simulator() else BLOCK


_SMS: list[int] = []


def _blocks_wanted() -> int:
    """Blocks the patch search spreads its stripes over: two per multiprocessor of the GPU (each stripe
    is a short sequential chain, so the stripes are better on many multiprocessors than packed into few
    blocks); two under the simulator."""
    if simulator():
        return 2
    if not _SMS:
        _SMS.append(int(cuda.get_current_device().MULTIPROCESSOR_COUNT))
    return 2 * _SMS[0]


# ----------------------------------------------------------------------------------------------- patch search


@device
def _cost(img, gx, gy, n0, n1, ti, tj, ux, uy, psz, mean_norm, grad, xs, ys):
    """(SSD, dUx, dUy) of the patch at (ti, tj) of image n0 against image n1 moved by (ux, uy): the
    (mean-normalised) SSD and, with ``grad``, the Gauss-Newton right-hand side sum(d * grad I0)."""
    h, w = img.shape[1], img.shape[2]
    y = min(max(np.float32(ti) + uy + np.float32(BORDER), np.float32(BORDER - psz + 1)), np.float32(BORDER + h - 1))
    x = min(max(np.float32(tj) + ux + np.float32(BORDER), np.float32(BORDER - psz + 1)), np.float32(BORDER + w - 1))
    fy = np.float32(math.floor(y))
    fx = np.float32(math.floor(x))
    w11 = (y - fy) * (x - fx)
    w10 = (y - fy) * (fx + ONE - x)
    w01 = (fy + ONE - y) * (x - fx)
    w00 = (fy + ONE - y) * (fx + ONE - x)
    r0 = int(fy) - BORDER
    c0 = int(fx) - BORDER
    sd = ZERO
    sdd = ZERO
    sgx = ZERO
    sgy = ZERO
    for a in range(psz):
        ra = min(max(r0 + a, 0), h - 1)
        rb = min(max(r0 + a + 1, 0), h - 1)
        for b in range(psz):
            ca = min(max(c0 + b, 0), w - 1)
            cb = min(max(c0 + b + 1, 0), w - 1)
            d = (w00 * np.float32(img[n1, ra, ca]) + w01 * np.float32(img[n1, ra, cb])
                 + w10 * np.float32(img[n1, rb, ca]) + w11 * np.float32(img[n1, rb, cb])
                 - np.float32(img[n0, ti + a, tj + b]))
            sdd = sdd + d * d
            sd = sd + d
            if grad:
                sgx = sgx + d * np.float32(gx[n0, ti + a, tj + b])
                sgy = sgy + d * np.float32(gy[n0, ti + a, tj + b])
    if mean_norm:
        n = np.float32(psz * psz)
        return sdd - sd * sd / n, sgx - sd * xs / n, sgy - sd * ys / n
    return sdd, sgx, sgy


@device
def _visit(img, gx, gy, st, S, n0, n1, q, r, c, dr, dc, side, up, psz, pstride, inner, mean_norm, prop):
    """Search patch (r, c) of pair q: the best of its flow and its neighbours' (c - dc), (r - dr) where
    ``side``/``up``, then ``inner`` Gauss-Newton steps; the step is kept if it moved less than a patch."""
    ti = r * pstride
    tj = c * pstride
    sx = S[q, 0, r, c]
    sy = S[q, 1, r, c]
    if prop:
        best, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, sx, sy, psz, mean_norm, False, ZERO, ZERO)
        if side:
            cx = S[q, 0, r, c - dc]
            cy = S[q, 1, r, c - dc]
            cur, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, cx, cy, psz, mean_norm, False, ZERO, ZERO)
            if cur < best:
                best = cur
                sx = cx
                sy = cy
        if up:
            cx = S[q, 0, r - dr, c]
            cy = S[q, 1, r - dr, c]
            cur, _, _ = _cost(img, gx, gy, n0, n1, ti, tj, cx, cy, psz, mean_norm, False, ZERO, ZERO)
            if cur < best:
                best = cur
                sx = cx
                sy = cy
    xx = st[n0, 0, r, c]
    yy = st[n0, 1, r, c]
    xy = st[n0, 2, r, c]
    det = xx * yy - xy * xy
    if abs(det) < EPS:
        det = EPS
    i11 = yy / det
    i12 = -xy / det
    i22 = xx / det
    xs = st[n0, 3, r, c]
    ys = st[n0, 4, r, c]
    ux = sx
    uy = sy
    prev = INF
    for _ in range(inner):
        ssd, dux, duy = _cost(img, gx, gy, n0, n1, ti, tj, ux, uy, psz, mean_norm, True, xs, ys)
        ux = ux - (i11 * dux + i12 * duy)
        uy = uy - (i12 * dux + i22 * duy)
        if ssd >= prev:
            break
        prev = ssd
    ex = ux - sx
    ey = uy - sy
    if np.float32(math.sqrt(ex * ex + ey * ey)) <= np.float32(psz):
        S[q, 0, r, c] = ux
        S[q, 1, r, c] = uy
    else:
        S[q, 0, r, c] = sx
        S[q, 1, r, c] = sy


@kernel("void(uint8[:, :, ::1], int16[:, :, ::1], int16[:, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], "
        "float32[:, :, :, ::1], int32[::1], int32[::1], int32, int32, int32, int32, int32, int32, int32, int32)")
def _search(img, gx, gy, st, U, S, pa, pb, npairs, psz, pstride, inner, stripe_rows, per_block, mean_norm, prop):
    """Sparse flow S (P, 2, hs, ws) of one level from the dense flow U (P, 2, h, w) (its value at each
    patch centre to start from). One thread per patch row; a block holds ``per_block`` whole stripes of
    ``stripe_rows`` rows (its first threads), which sweep anti-diagonals with a barrier per step. Every
    thread of every block runs the same number of steps and barriers."""
    hs, ws = S.shape[2], S.shape[3]
    k = cuda.threadIdx.x // stripe_rows
    lr = cuda.threadIdx.x - k * stripe_rows
    nstripes = (hs + stripe_rows - 1) // stripe_rows
    stripe = cuda.blockIdx.x * per_block + k
    q = stripe // nstripes
    s = stripe - q * nstripes
    r = s * stripe_rows + lr
    active = k < per_block and q < npairs and r < hs
    nrows = min(stripe_rows, hs - s * stripe_rows)
    n0 = 0
    n1 = 0
    if active:
        n0 = pa[q]
        n1 = pb[q]
        ci = r * pstride + psz // 2
        for c in range(ws):
            S[q, 0, r, c] = U[q, 0, ci, c * pstride + psz // 2]
            S[q, 1, r, c] = U[q, 1, ci, c * pstride + psz // 2]
    cuda.syncthreads()
    passes = 2 if prop else 1
    for ps in range(passes):
        fwd = ps % 2 == 0
        for step in range(ws + stripe_rows - 1):
            if active:
                order = lr if fwd else nrows - 1 - lr
                c = step - order
                if c >= 0 and c < ws:
                    d = 1 if fwd else -1
                    _visit(img, gx, gy, st, S, n0, n1, q, r, c if fwd else ws - 1 - c, d, d, c > 0, order > 0,
                           psz, pstride, inner, mean_norm, prop)
            cuda.syncthreads()


@kernel("void(uint8[:, :, ::1], float32[:, :, :, ::1], float32[:, :, :, ::1], int32[::1], int32[::1], int32, "
        "int32, int32)")
def _densify(img, S, U, pa, pb, npairs, psz, pstride):
    """U[q, :, i, j] = sum_k c_k S_k / sum_k c_k over the patches k covering (i, j) (the last patch past
    the last one), c_k = 1 / max(1, |I1(x + S_k) - I0(x)|), I1 bilinear and clamped inside the image."""
    t = cuda.grid(1)
    h, w = U.shape[2], U.shape[3]
    if t >= npairs * h * w:
        return
    q = t // (h * w)
    i = (t // w) % h
    j = t % w
    hs, ws = S.shape[2], S.shape[3]
    n0 = pa[q]
    n1 = pb[q]
    ihi = min(i // pstride, hs - 1)
    jhi = min(j // pstride, ws - 1)
    a = i - psz + 1
    ilo = min(0 if a <= 0 else (a + pstride - 1) // pstride, ihi)
    a = j - psz + 1
    jlo = min(0 if a <= 0 else (a + pstride - 1) // pstride, jhi)
    i0 = np.float32(img[n0, i, j])
    nx = ZERO
    ny = ZERO
    den = ZERO
    for r in range(ilo, ihi + 1):
        for c in range(jlo, jhi + 1):
            sx = S[q, 0, r, c]
            sy = S[q, 1, r, c]
            jm = min(max(np.float32(j) + sx, ZERO), np.float32(w) - ONE - EPS)
            im = min(max(np.float32(i) + sy, ZERO), np.float32(h) - ONE - EPS)
            jl = int(jm)
            il = int(im)
            fj = jm - np.float32(jl)
            fi = im - np.float32(il)
            gj = np.float32(jl + 1) - jm
            gi = np.float32(il + 1) - im
            diff = (fj * fi * np.float32(img[n1, il + 1, jl + 1]) + gj * fi * np.float32(img[n1, il + 1, jl])
                    + fj * gi * np.float32(img[n1, il, jl + 1]) + gj * gi * np.float32(img[n1, il, jl]) - i0)
            coef = ONE / max(ONE, abs(diff))
            nx = nx + coef * sx
            ny = ny + coef * sy
            den = den + coef
    U[q, 0, i, j] = nx / den
    U[q, 1, i, j] = ny / den


# ----------------------------------------------------------------------------------------------- host side


class DisWorkspace:
    """Device buffers of :func:`dis_pairs` for up to ``n_images`` images and ``n_pairs`` pairs of (H, W)
    images with parameters ``params``: per level the pyramid images, their gradients and structure tensors,
    the dense and sparse flows and the refinement's buffers. Reused by every call that fits; it serves one
    call at a time (calls from several threads need a workspace each)."""

    def __init__(self, n_images: int, n_pairs: int, H: int, W: int, params: DisParams):
        self.n_images, self.n_pairs, self.H, self.W, self.params = n_images, n_pairs, H, W, params
        self.shapes = level_shapes(H, W, params)
        self.pa = cuda.device_array(n_pairs, np.int32)
        self.pb = cuda.device_array(n_pairs, np.int32)
        finest, _ = scales(H, W, params)
        self.levels = []
        for lev, (h, w) in enumerate(self.shapes):
            hs, ws = patch_grid(h, w, params)
            own = lev > 0 or finest > 0
            self.levels.append({
                "img": cuda.device_array((n_images, h, w), np.uint8) if own else None,
                "gx": cuda.device_array((n_images, h, w), np.int16),
                "gy": cuda.device_array((n_images, h, w), np.int16),
                "st": cuda.device_array((n_images, 5, hs, ws), np.float32),
                "U": cuda.device_array((n_pairs, 2, h, w), np.float32),
                "S": cuda.device_array((n_pairs, 2, hs, ws), np.float32),
                "refine": RefineBuffers(n_pairs, h, w) if params.variational_iterations > 0 else None,
            })
        _logger.debug("DIS workspace: %d images, %d pairs, %dx%d, levels %s", n_images, n_pairs, W, H, self.shapes)

    @property
    def nbytes(self) -> int:
        """Device memory held, in bytes."""
        arrays = [self.pa, self.pb]
        for L in self.levels:
            arrays += [L[k] for k in ("img", "gx", "gy", "st", "U", "S") if L[k] is not None]
            if L["refine"] is not None:
                arrays += list(vars(L["refine"]).values())
        return sum(int(a.size) * a.dtype.itemsize for a in arrays)

    def fits(self, n_images: int, n_pairs: int, H: int, W: int, params: DisParams) -> bool:
        return (n_images <= self.n_images and n_pairs <= self.n_pairs and (H, W) == (self.H, self.W)
                and params == self.params)


def _index_array(name: str, v, n_images: int) -> np.ndarray:
    host = v.copy_to_host() if hasattr(v, "copy_to_host") else np.asarray(v)
    if host.ndim != 1 or host.size == 0 or not (np.issubdtype(host.dtype, np.integer)):
        raise ValueError(f"dis_pairs: {name} must be a non-empty 1-D integer array; got dtype {host.dtype}, "
                         f"shape {host.shape}")
    if host.min() < 0 or host.max() >= n_images:
        raise ValueError(f"dis_pairs: {name} must index the {n_images} images (0 to {n_images - 1}); got values "
                         f"from {host.min()} to {host.max()}")
    return np.ascontiguousarray(host, np.int32)


def dis_pairs(images, a, b, params: DisParams | None = None, *, out=None, workspace: DisWorkspace | None = None):
    """DIS flow from ``images[a[q]]`` to ``images[b[q]]`` for every pair q at once.

    Parameters
    ----------
    images : device array (N, H, W) uint8, C-contiguous
        The images (a host array is uploaded). Each side at least ``params.patch_size``.
    a, b : array (P,) of int
        Image indices of the pairs (host or device).
    params : DisParams
        Defaults to :class:`DisParams`'s ("medium", two refinement iterations).
    out : device array (P, H, W, 2) float32, optional
        Where to write the flow.
    workspace : DisWorkspace, optional
        Buffers to use (a caller that calls again keeps one, as motion-aware's engine does in its
        :class:`~flexvox_core.gpu.volumes.Workspace`); by default new ones for this call.

    Returns
    -------
    device array (P, H, W, 2) float32
        The flow in pixels, (dx, dy): I1(x + u) ≈ I0(x).
    """
    p = DisParams() if params is None else params
    if not isinstance(p, DisParams):
        raise TypeError(f"dis_pairs: params must be a DisParams; got {type(p).__name__}")
    if not hasattr(images, "copy_to_host"):
        host = np.asarray(images)
        if host.dtype != np.uint8 or host.ndim != 3:
            raise ValueError(f"dis_pairs: images must be (N, H, W) uint8; got dtype {host.dtype}, shape {host.shape}")
        images = cuda.to_device(np.ascontiguousarray(host))
    if images.dtype != np.uint8 or images.ndim != 3 or not images.is_c_contiguous():
        raise ValueError(f"dis_pairs: images must be a C-contiguous (N, H, W) uint8 array; got dtype "
                         f"{images.dtype}, shape {images.shape}")
    N, H, W = images.shape
    if min(H, W) < p.patch_size:
        raise ValueError(f"dis_pairs: each image side must be at least patch_size {p.patch_size}; got {H}x{W}")
    ha, hb = _index_array("a", a, N), _index_array("b", b, N)
    if ha.shape != hb.shape:
        raise ValueError(f"dis_pairs: a and b must have the same length; got {ha.size} and {hb.size}")
    P = ha.size
    if out is None:
        out = cuda.device_array((P, H, W, 2), np.float32)
    elif out.shape != (P, H, W, 2) or out.dtype != np.float32 or not out.is_c_contiguous():
        raise ValueError(f"dis_pairs: out must be a C-contiguous ({P}, {H}, {W}, 2) float32 array; got dtype "
                         f"{out.dtype}, shape {out.shape}")
    ws = workspace if workspace is not None else DisWorkspace(N, P, H, W, p)
    if not ws.fits(N, P, H, W, p):
        raise ValueError(f"dis_pairs: the workspace holds {ws.n_images} images, {ws.n_pairs} pairs of "
                         f"{ws.H}x{ws.W}; got {N} images, {P} pairs of {H}x{W} (or other params)")
    block = _block()
    for h, w in ws.shapes:
        hs, _ = patch_grid(h, w, p)
        if math.ceil(hs / STRIPES) > block:
            raise ValueError(f"dis_pairs: {H}x{W} images give {math.ceil(hs / STRIPES)} patch rows per stripe; at "
                             f"most {block} (threads per block) fit")
    da, db = ws.pa, ws.pb
    for dev, host in ((da, ha), (db, hb)):
        full = np.zeros(ws.n_pairs, np.int32)
        full[:P] = host
        dev.copy_to_device(full)
    i32 = np.int32
    # pyramid, gradients and structure tensors of every image
    finest, _ = scales(H, W, p)
    levels = []
    for lev, L in enumerate(ws.levels):
        img = images if L["img"] is None else L["img"]
        if L["img"] is not None:
            reduce(levels[-1] if lev else images, img, N)
        gradients(img, L["gx"], L["gy"], L["st"], N, p.patch_size, p.patch_stride)
        levels.append(img)
    # coarse to fine
    prop = p.use_spatial_propagation
    inner = int(math.floor(p.gradient_descent_iterations / (2.0 if prop else 1.0)))
    zero4(ws.levels[-1]["U"], P)
    for lev in range(len(ws.shapes) - 1, -1, -1):
        (h, w), L, img = ws.shapes[lev], ws.levels[lev], levels[lev]
        hs, _ = patch_grid(h, w, p)
        rows = math.ceil(hs / STRIPES)
        stripes = P * math.ceil(hs / rows)
        per_block = max(1, min(block // rows, math.ceil(stripes / _blocks_wanted())))
        launch(_search, math.ceil(stripes / per_block) * block, img, L["gx"], L["gy"], L["st"], L["U"], L["S"], da,
               db, i32(P), i32(p.patch_size), i32(p.patch_stride), i32(inner), i32(rows), i32(per_block),
               i32(p.use_mean_normalization), i32(prop))
        launch(_densify, P * h * w, img, L["S"], L["U"], da, db, i32(P), i32(p.patch_size), i32(p.patch_stride))
        if p.variational_iterations > 0:
            refine_level(img, L["U"], da, db, P, L["refine"], p)
        if lev > 0:
            upsample(L["U"], ws.levels[lev - 1]["U"], P, 2.0)
    to_output(ws.levels[0]["U"], out, P, 2**finest)
    return out
