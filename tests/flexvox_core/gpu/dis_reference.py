"""DIS optical flow (Kroeger et al., ECCV 2016) in plain numpy: the reference the GPU kernels of
:mod:`flexvox_core.gpu.dis` are compared with.

The same algorithm and the same choices as the kernels (which follow OpenCV's ``DISOpticalFlow``), written
the straightforward way: the patch search sweeps each stripe of patch rows in raster order (forward, then
backward), vectorised over the stripes, where the kernels sweep anti-diagonals; every value is float32 and
every sum runs in the kernels' order (``np.add.accumulate`` is sequential), so the two agree to the last bit.
Nothing here uses numba or OpenCV.

``p`` is any object with :class:`flexvox_core.gpu.dis.DisParams`'s attribute names.
"""

from __future__ import annotations

import math

import numpy as np

F = np.float32
EPS = F(0.001)
INF = F(1e10)
BORDER = 16
STRIPES = 8
ZETA2 = F(0.1) * F(0.1)
OMEGA = F(1.6)


# ----------------------------------------------------------------------------------------------- pyramid


def scales(H: int, W: int, p) -> tuple[int, int]:
    """(finest, coarsest) pyramid scale. OpenCV's rule: the coarsest scale searches motions up to a quarter
    of the larger side and keeps every level at least a patch wide. Where that is finer than
    ``finest_scale`` (small images), the pyramid runs from the full size (scale 0) to
    floor(log2(2 W / (5 patch))), at least 0 and no coarser than the patch rule (OpenCV 5.0's levels there,
    measured for finest_scale 1 and 2)."""
    psz = p.patch_size
    by_motion = int(math.log(max(W, H) / (4.0 * psz)) / math.log(2.0) + 0.5)
    by_patch = int(math.log(min(W, H) // psz) / math.log(2.0))
    coarsest = min(by_motion, by_patch)
    if coarsest >= p.finest_scale:
        return p.finest_scale, coarsest
    return 0, min(max(0, math.floor(math.log2(2.0 * W / (5.0 * psz)))), by_patch)


def level_shapes(H: int, W: int, p) -> list[tuple[int, int]]:
    """(h, w) of every level from the finest to the coarsest."""
    f, c = scales(H, W, p)
    h, w = H // 2**f, W // 2**f
    out = [(h, w)]
    for _ in range(f, c):
        h, w = h // 2, w // 2
        out.append((h, w))
    return out


def _area_tab(src: int, dst: int):
    scale = src / dst
    tab = []
    for d in range(dst):
        f1 = d * scale
        f2 = f1 + scale
        cell = min(scale, src - f1)
        s1, s2 = math.ceil(f1), math.floor(f2)
        s2 = min(s2, src - 1)
        s1 = min(s1, s2)
        t = []
        if s1 - f1 > 1e-3:
            t.append((s1 - 1, F((s1 - f1) / cell)))
        t += [(s, F(1.0 / cell)) for s in range(s1, s2)]
        if f2 - s2 > 1e-3:
            t.append((s2, F(min(min(f2 - s2, 1.0), cell) / cell)))
        tab.append(t)
    return tab


def area_resize(img: np.ndarray, dh: int, dw: int) -> np.ndarray:
    """uint8 (dh, dw): OpenCV's INTER_AREA downscale (exact integer factor k: block mean, k = 2 rounding half
    up; otherwise the fractional-coverage weights summed in float32 and rounded half to even)."""
    sh, sw = img.shape
    if sh == dh and sw == dw:
        return img.copy()
    if sh % dh == 0 and sw % dw == 0 and sh // dh == sw // dw:
        k = sh // dh
        s = img.astype(np.int64).reshape(dh, k, dw, k).sum(axis=(1, 3))
        if k == 2:
            return ((s + 2) >> 2).astype(np.uint8)
        return np.clip(np.rint(s.astype(F) * F(1.0 / (k * k))), 0, 255).astype(np.uint8)
    xt, yt = _area_tab(sw, dw), _area_tab(sh, dh)
    src = img.astype(F)
    out = np.zeros((dh, dw), F)
    for dy, ty in enumerate(yt):
        for dx, tx in enumerate(xt):
            acc = F(0)
            for sy, beta in ty:
                row = F(0)
                for sx, alpha in tx:
                    row = F(row + src[sy, sx] * alpha)
                acc = F(acc + beta * row)
            out[dy, dx] = acc
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def pyramid(img: np.ndarray, p) -> list[np.ndarray]:
    """uint8 levels from the finest to the coarsest."""
    shapes = level_shapes(*img.shape, p)
    out = [area_resize(img, *shapes[0])]
    for h, w in shapes[1:]:
        out.append(area_resize(out[-1], h, w))
    return out


def sobel(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """3x3 Sobel derivatives (int32 with int16 values), border reflected about the edge pixel (OpenCV's
    BORDER_REFLECT_101, as ``spatialGradient``)."""
    a = np.pad(img.astype(np.int32), 1, mode="reflect")
    dx = a[:, 2:] - a[:, :-2]
    gx = dx[:-2] + 2 * dx[1:-1] + dx[2:]
    dy = a[2:] - a[:-2]
    gy = dy[:, :-2] + 2 * dy[:, 1:-1] + dy[:, 2:]
    return gx, gy


# ----------------------------------------------------------------------------------------------- patch search


def grid(h: int, w: int, p) -> tuple[int, int]:
    """(hs, ws): patches per column and per row."""
    return 1 + (h - p.patch_size) // p.patch_stride, 1 + (w - p.patch_size) // p.patch_stride


def structure_tensor(gx, gy, p):
    """(xx, yy, xy, x, y), each float32 (hs, ws): sums over each patch of Ix², Iy², IxIy, Ix, Iy."""
    psz, st = p.patch_size, p.patch_stride
    hs, ws = grid(*gx.shape, p)
    out = []
    for q in (gx * gx, gy * gy, gx * gy, gx, gy):
        c = np.cumsum(np.cumsum(np.pad(q.astype(np.int64), ((1, 0), (1, 0))), 0), 1)
        r = np.arange(hs) * st
        s = np.arange(ws) * st
        box = (c[r[:, None] + psz, s[None] + psz] - c[r[:, None], s[None] + psz] - c[r[:, None] + psz, s[None]]
               + c[r[:, None], s[None]])
        out.append(box.astype(F))
    return out


def _seq_sum(x):
    """Sum over the last axis in order (what one thread's loop does)."""
    return np.add.accumulate(x, axis=-1, dtype=F)[..., -1]


def patch_eval(I0, I1, gx, gy, ti, tj, ux, uy, p, xs=None, ys=None):
    """Mean-normalised (or plain) SSD of the patches with top-left (ti, tj) moved by (ux, uy), and with
    ``xs``/``ys`` given the Gauss-Newton right-hand sides (dUx, dUy). Vectorised over patches."""
    h, w = I0.shape
    psz = p.patch_size
    y = np.minimum(np.maximum(ti.astype(F) + uy + F(BORDER), F(BORDER - psz + 1)), F(BORDER + h - 1))
    x = np.minimum(np.maximum(tj.astype(F) + ux + F(BORDER), F(BORDER - psz + 1)), F(BORDER + w - 1))
    fy, fx = np.floor(y), np.floor(x)
    w11 = (y - fy) * (x - fx)
    w10 = (y - fy) * (fx + F(1) - x)
    w01 = (fy + F(1) - y) * (x - fx)
    w00 = (fy + F(1) - y) * (fx + F(1) - x)
    k = np.arange(psz + 1)
    rows = np.clip(fy.astype(np.int64)[:, None] - BORDER + k, 0, h - 1)
    cols = np.clip(fx.astype(np.int64)[:, None] - BORDER + k, 0, w - 1)
    win = I1[rows[:, :, None], cols[:, None, :]].astype(F)
    k0 = np.arange(psz)
    pr, pc = ti[:, None, None] + k0[None, :, None], tj[:, None, None] + k0[None, None, :]
    e = w00[:, None, None] * win[:, :-1, :-1] + w01[:, None, None] * win[:, :-1, 1:]
    d = e + w10[:, None, None] * win[:, 1:, :-1] + w11[:, None, None] * win[:, 1:, 1:] - I0[pr, pc].astype(F)
    d = d.reshape(len(ti), -1)
    sdd = _seq_sum(d * d)
    n = F(psz * psz)
    if p.use_mean_normalization:
        sd = _seq_sum(d)
        ssd = sdd - sd * sd / n
    else:
        ssd = sdd
    if xs is None:
        return ssd, None, None
    dux = _seq_sum(d * gx[pr, pc].reshape(len(ti), -1).astype(F))
    duy = _seq_sum(d * gy[pr, pc].reshape(len(ti), -1).astype(F))
    if p.use_mean_normalization:
        dux = dux - sd * xs / n
        duy = duy - sd * ys / n
    return ssd, dux, duy


def patch_search(I0, I1, gx, gy, U, p):
    """Sparse flow (2, hs, ws) float32 of one level: each stripe of patch rows swept in raster order, forward
    then backward, each patch starting from the best of its flow and its already-visited neighbours'
    (spatial propagation) and refined by Gauss-Newton steps of the inverse-compositional search."""
    h, w = I0.shape
    psz, st = p.patch_size, p.patch_stride
    hs, ws = grid(h, w, p)
    xx, yy, xy, xs, ys = structure_tensor(gx, gy, p)
    c = psz // 2
    S = np.stack([U[0][np.arange(hs)[:, None] * st + c, np.arange(ws)[None] * st + c],
                  U[1][np.arange(hs)[:, None] * st + c, np.arange(ws)[None] * st + c]]).astype(F)
    det = xx * yy - xy * xy
    det = np.where(np.abs(det) < EPS, EPS, det)
    ih11, ih12, ih22 = yy / det, -xy / det, xx / det
    prop = p.use_spatial_propagation
    passes = 2 if prop else 1
    inner = int(math.floor(p.gradient_descent_iterations / float(passes)))
    ssz = math.ceil(hs / STRIPES)
    starts = np.arange(0, hs, ssz)
    ends = np.minimum(starts + ssz, hs)

    def at(a, rr, cc):
        return a[rr, cc]

    for ps in range(passes):
        fwd = ps % 2 == 0
        for r in range(ssz):
            rows = starts + r if fwd else ends - 1 - r
            ok = (rows < ends) & (rows >= starts)
            rows = rows[ok]
            for cstep in range(ws):
                col = cstep if fwd else ws - 1 - cstep
                cols = np.full(len(rows), col)
                ti, tj = rows * st, cols * st
                sx, sy = S[0, rows, cols].copy(), S[1, rows, cols].copy()
                if prop:
                    best, _, _ = patch_eval(I0, I1, gx, gy, ti, tj, sx, sy, p)
                    cands = []
                    if cstep > 0:
                        cands.append((rows, cols - 1 if fwd else cols + 1))
                    if r > 0:
                        cands.append((rows - 1 if fwd else rows + 1, cols))
                    for rr, cc in cands:
                        cx, cy = S[0, rr, cc], S[1, rr, cc]
                        cur, _, _ = patch_eval(I0, I1, gx, gy, ti, tj, cx, cy, p)
                        better = cur < best
                        best = np.where(better, cur, best)
                        sx, sy = np.where(better, cx, sx), np.where(better, cy, sy)
                ux, uy = sx.copy(), sy.copy()
                a11, a12, a22 = at(ih11, rows, cols), at(ih12, rows, cols), at(ih22, rows, cols)
                gxs, gys = at(xs, rows, cols), at(ys, rows, cols)
                prev = np.full(len(rows), INF, F)
                live = np.ones(len(rows), bool)
                for _ in range(inner):
                    if not live.any():
                        break
                    ssd, dux, duy = patch_eval(I0, I1, gx, gy, ti, tj, ux, uy, p, gxs, gys)
                    dx = a11 * dux + a12 * duy
                    dy = a12 * dux + a22 * duy
                    ux = np.where(live, ux - dx, ux)
                    uy = np.where(live, uy - dy, uy)
                    live &= ~(ssd >= prev)
                    prev = np.where(live, ssd, prev)
                ex, ey = ux - sx, uy - sy
                keep = np.sqrt(ex * ex + ey * ey) <= F(psz)
                S[0, rows, cols] = np.where(keep, ux, sx)
                S[1, rows, cols] = np.where(keep, uy, sy)
    return S


def densify(I0, I1, S, p) -> np.ndarray:
    """Dense flow (2, h, w) float32: per pixel the average of the flows of the patches that cover it (the
    last patch for pixels past it), each weighted by 1 / max(1, |I1(x + u) - I0(x)|)."""
    h, w = I0.shape
    psz, st = p.patch_size, p.patch_stride
    hs, ws = grid(h, w, p)

    def span(n, ns):
        i = np.arange(n)
        hi = np.minimum(i // st, ns - 1)
        lo = np.minimum(np.maximum(0, -((psz - 1 - i) // st)), hi)
        return lo, hi

    ilo, ihi = span(h, hs)
    jlo, jhi = span(w, ws)
    I0f = I0.astype(F)
    I1f = I1.astype(F)
    ii, jj = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    num_x = np.zeros((h, w), F)
    num_y = np.zeros((h, w), F)
    den = np.zeros((h, w), F)
    nmax = -(-psz // st) + 1
    for a in range(nmax):
        for b in range(nmax):
            si = ilo[:, None] + a + 0 * jj
            sj = jlo[None, :] + b + 0 * ii
            use = (si <= ihi[:, None]) & (sj <= jhi[None, :])
            si, sj = np.minimum(si, hs - 1), np.minimum(sj, ws - 1)
            sx, sy = S[0, si, sj], S[1, si, sj]
            jm = np.minimum(np.maximum(jj.astype(F) + sx, F(0)), F(w) - F(1) - EPS)
            im = np.minimum(np.maximum(ii.astype(F) + sy, F(0)), F(h) - F(1) - EPS)
            jl, il = jm.astype(np.int64), im.astype(np.int64)
            ju, iu = jl + 1, il + 1
            fj, fi = jm - jl.astype(F), im - il.astype(F)
            gj, gi = ju.astype(F) - jm, iu.astype(F) - im
            diff = fj * fi * I1f[iu, ju] + gj * fi * I1f[iu, jl] + fj * gi * I1f[il, ju] + gj * gi * I1f[il, jl] - I0f
            coef = F(1) / np.maximum(F(1), np.abs(diff))
            num_x = np.where(use, num_x + coef * sx, num_x)
            num_y = np.where(use, num_y + coef * sy, num_y)
            den = np.where(use, den + coef, den)
    return np.stack([num_x / den, num_y / den])


# ----------------------------------------------------------------------------------------------- refinement


def _dx(a):
    """a[x+1] - a[x-1], edges replicated (OpenCV's Sobel with ksize 1, BORDER_REPLICATE)."""
    b = np.pad(a, ((0, 0), (1, 1)), mode="edge")
    return b[:, 2:] - b[:, :-2]


def _dy(a):
    b = np.pad(a, ((1, 1), (0, 0)), mode="edge")
    return b[2:] - b[:-2]


def warp(I1, u, v):
    """I1 (float32) sampled bilinearly at (x + u, y + v), each tap clamped to the image."""
    h, w = I1.shape
    ii, jj = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    mx = jj.astype(F) + u
    my = ii.astype(F) + v
    x0, y0 = np.floor(mx), np.floor(my)
    fx, fy = mx - x0, my - y0
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    ya, yb = np.clip(y0, 0, h - 1), np.clip(y0 + 1, 0, h - 1)
    src = I1.astype(F)
    top = (F(1) - fx) * src[ya, xa] + fx * src[ya, xb]
    bot = (F(1) - fx) * src[yb, xa] + fx * src[yb, xb]
    return (F(1) - fy) * top + fy * bot


def refine(I0, I1, U, p) -> np.ndarray:
    """Variational refinement (Brox et al. 2004 energy: brightness and gradient constancy, weights delta and
    gamma, smoothness alpha; robust penalties lagged in fixed-point iterations, each solved by red-black SOR),
    linearised once about the warp by ``U``. Returns U + dU, (2, h, w) float32."""
    h, w = I0.shape
    I0f = I0.astype(F)
    warped = warp(I1, U[0], U[1])
    avg = I0f * F(0.5) + warped * F(0.5)
    Iz = warped - I0f
    Ix, Iy, Ixz, Iyz = _dx(avg), _dy(avg), _dx(Iz), _dy(Iz)
    Ixx, Ixy, Iyy = _dx(Ix), _dy(Ix), _dy(Iy)
    d2, g2, a2 = F(p.delta) / F(2), F(p.gamma) / F(2), F(p.alpha) / F(2)
    EPSILON2 = F(p.epsilon) * F(p.epsilon)
    Wu, Wv = U[0].astype(F), U[1].astype(F)
    du, dv = np.zeros((h, w), F), np.zeros((h, w), F)
    ii, jj = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    red = (ii + jj) % 2 == 0
    has_r, has_l, has_d, has_u = jj < w - 1, jj > 0, ii < h - 1, ii > 0
    zero = np.zeros((h, w), F)

    def shift(a, di, dj):
        """a at (i + di, j + dj), 0 outside."""
        out = np.zeros_like(a)
        out[max(0, -di):h - max(0, di), max(0, -dj):w - max(0, dj)] = a[max(0, di):h - max(0, -di) or None,
                                                                          max(0, dj):w - max(0, -dj) or None]
        return out

    for _ in range(p.variational_iterations):
        # data term
        dn = Ix * Ix + Iy * Iy + ZETA2
        ik = Iz + Ix * du + Iy * dv
        wt = (d2 / np.sqrt(ik * ik / dn + EPSILON2)) / dn
        A11 = wt * (Ix * Ix) + ZETA2
        A12 = wt * (Ix * Iy)
        A22 = wt * (Iy * Iy) + ZETA2
        b1 = -wt * (Iz * Ix)
        b2 = -wt * (Iz * Iy)
        dn = Ixx * Ixx + Ixy * Ixy + ZETA2
        dn2 = Iyy * Iyy + Ixy * Ixy + ZETA2
        ikx = Ixz + Ixx * du + Ixy * dv
        iky = Iyz + Ixy * du + Iyy * dv
        wt = g2 / np.sqrt(ikx * ikx / dn + iky * iky / dn2 + EPSILON2)
        A11 = A11 + wt * (Ixx * Ixx / dn + Ixy * Ixy / dn2)
        A12 = A12 + wt * (Ixx * Ixy / dn + Ixy * Iyy / dn2)
        A22 = A22 + wt * (Ixy * Ixy / dn + Iyy * Iyy / dn2)
        b1 = b1 + -wt * (Ixx * Ixz / dn + Ixy * Iyz / dn2)
        b2 = b2 + -wt * (Ixy * Ixz / dn + Iyy * Iyz / dn2)
        # smoothness weights from the current flow (forward differences, zero past the right and bottom edge)
        cu, cv = Wu + du, Wv + dv
        ux = np.where(has_r, shift(cu, 0, 1) - cu, zero)
        vx = np.where(has_r, shift(cv, 0, 1) - cv, zero)
        uy = np.where(has_d, shift(cu, 1, 0) - cu, zero)
        vy = np.where(has_d, shift(cv, 1, 0) - cv, zero)
        sw = a2 / np.sqrt(ux * ux + vx * vx + uy * uy + vy * vy + EPSILON2)
        wl, wu = shift(sw, 0, -1), shift(sw, -1, 0)
        # each edge adds its weight to both ends: red pixels in the order right, left, down, up; black pixels
        # left, right, up, down (OpenCV's red pass then black pass, horizontal then vertical)
        er = np.where(has_r, sw * (shift(Wu, 0, 1) - Wu), zero), np.where(has_r, sw * (shift(Wv, 0, 1) - Wv), zero)
        el = np.where(has_l, wl * (Wu - shift(Wu, 0, -1)), zero), np.where(has_l, wl * (Wv - shift(Wv, 0, -1)), zero)
        ed = np.where(has_d, sw * (shift(Wu, 1, 0) - Wu), zero), np.where(has_d, sw * (shift(Wv, 1, 0) - Wv), zero)
        eu = np.where(has_u, wu * (Wu - shift(Wu, -1, 0)), zero), np.where(has_u, wu * (Wv - shift(Wv, -1, 0)), zero)
        wr_, wl_ = np.where(has_r, sw, zero), np.where(has_l, wl, zero)
        wd_, wu_ = np.where(has_d, sw, zero), np.where(has_u, wu, zero)
        A11r = (((A11 + wr_) + wl_) + wd_) + wu_
        A11b = (((A11 + wl_) + wr_) + wu_) + wd_
        A22r = (((A22 + wr_) + wl_) + wd_) + wu_
        A22b = (((A22 + wl_) + wr_) + wu_) + wd_
        b1r = (((b1 + er[0]) - el[0]) + ed[0]) - eu[0]
        b1b = (((b1 - el[0]) + er[0]) - eu[0]) + ed[0]
        b2r = (((b2 + er[1]) - el[1]) + ed[1]) - eu[1]
        b2b = (((b2 - el[1]) + er[1]) - eu[1]) + ed[1]
        A11 = np.where(red, A11r, A11b)
        A22 = np.where(red, A22r, A22b)
        b1 = np.where(red, b1r, b1b)
        b2 = np.where(red, b2r, b2b)
        for _ in range(p.sor_iterations):
            for colour in (red, ~red):
                su = wl * shift(du, 0, -1) + sw * shift(du, 0, 1) + wu * shift(du, -1, 0) + sw * shift(du, 1, 0)
                sv = wl * shift(dv, 0, -1) + sw * shift(dv, 0, 1) + wu * shift(dv, -1, 0) + sw * shift(dv, 1, 0)
                nu = du + OMEGA * ((su + b1 - dv * A12) / A11 - du)
                nv = dv + OMEGA * ((sv + b2 - nu * A12) / A22 - dv)
                du = np.where(colour, nu, du)
                dv = np.where(colour, nv, dv)
    return np.stack([Wu + du, Wv + dv])


# ----------------------------------------------------------------------------------------------- whole


def _linear_tab(src: int, dst: int):
    scale = src / dst
    i0 = np.zeros(dst, np.int64)
    i1 = np.zeros(dst, np.int64)
    f = np.zeros(dst, F)
    for d in range(dst):
        fx = (d + 0.5) * scale - 0.5
        s = math.floor(fx)
        fx -= s
        if s < 0:
            fx, s = 0.0, 0
        if s >= src - 1:
            fx, s = 0.0, src - 1
        i0[d], i1[d], f[d] = s, min(s + 1, src - 1), F(fx)
    return i0, i1, f


def resize_linear(a: np.ndarray, dh: int, dw: int) -> np.ndarray:
    """float32 (dh, dw): bilinear resize with half-pixel centres (OpenCV's INTER_LINEAR)."""
    sh, sw = a.shape
    x0, x1, fx = _linear_tab(sw, dw)
    y0, y1, fy = _linear_tab(sh, dh)
    rows = a[:, x0] * (F(1) - fx) + a[:, x1] * fx
    return rows[y0] * (F(1) - fy)[:, None] + rows[y1] * fy[:, None]


def dis(I0: np.ndarray, I1: np.ndarray, p) -> np.ndarray:
    """Flow (H, W, 2) float32 from I0 to I1 (uint8 (H, W)), (dx, dy) in pixels."""
    H, W = I0.shape
    P0, P1 = pyramid(I0, p), pyramid(I1, p)
    f, _ = scales(H, W, p)
    U = np.zeros((2, *P0[-1].shape), F)
    for lev in range(len(P0) - 1, -1, -1):
        a, b = P0[lev], P1[lev]
        gx, gy = sobel(a)
        S = patch_search(a, b, gx, gy, U, p)
        U = densify(a, b, S, p)
        if p.variational_iterations > 0:
            U = refine(a, b, U, p)
        if lev > 0:
            h, w = P0[lev - 1].shape
            U = np.stack([resize_linear(U[0], h, w) * F(2), resize_linear(U[1], h, w) * F(2)])
    k = F(2**f)
    return np.stack([resize_linear(U[0], H, W) * k, resize_linear(U[1], H, W) * k], axis=-1)


def dis_pairs(images: np.ndarray, a, b, p) -> np.ndarray:
    """Flows (P, H, W, 2) float32 from images[a[i]] to images[b[i]]."""
    return np.stack([dis(images[i], images[j], p) for i, j in zip(a, b, strict=True)])
