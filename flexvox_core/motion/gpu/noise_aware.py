"""The noise stage on the GPU: :mod:`~flexvox_core.motion.noise_aware` on device arrays.

The noise of frame f is 1.4826 · median |Δ| / √2 over the differences Δ between successive samples of the pixels
still at both (the pairs f − 1, f and f, f + 1). The median is selected exactly on the card: non-negative
float32 values order as their bit patterns, so four passes of a 256-bucket histogram over 8 bits at a time
find the two middle values of every frame at once (radix selection); only two numbers per frame come back.
The wide kernel's weight g then follows per voxel from the high-TR video's smoothed gradient.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda

from flexvox_core.gpu.filters import blur, gaussian_taps, sobel_slopes
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import kernel, launch
from flexvox_core.motion import noise_aware


@kernel("void(uint8[:, :, ::1], uint8[:, :, ::1], uint8[:, :, ::1])")
def _still_at(still, mask, out):
    """Whether each pixel's sample of each frame is still (F, H, W)."""
    i = cuda.grid(1)
    F, H, W = out.shape
    if i >= F * H * W:
        return
    f, y, x = voxel(i, H, W)
    K = still.shape[0] // F
    found = 0
    for t in range(f * K, (f + 1) * K):
        if still[t, y, x] and mask[t, y, x]:
            found = 1
    out[f, y, x] = found


@kernel("void(float32[:, :, ::1], uint8[:, :, ::1], float32[:, :, ::1])")
def _differences(frames, still_at, out):
    """|Δ| between frames i and i + 1 at the pixels still at both, −1 elsewhere (F − 1, H, W)."""
    j = cuda.grid(1)
    P, H, W = out.shape
    if j >= P * H * W:
        return
    i, y, x = voxel(j, H, W)
    if still_at[i, y, x] and still_at[i + 1, y, x]:
        out[i, y, x] = abs(frames[i + 1, y, x] - frames[i, y, x])
    else:
        out[i, y, x] = -1


@kernel("void(uint32[:, :, ::1], uint32[:, ::1], int32, int32[:, :, ::1])")
def _histogram(diff_bits, prefix, shift, hist):
    """Pass ``shift`` of the radix selection: each difference of pair i (its float32 bits: a non-negative float
    orders as its bits; −1, not still, has the sign bit) goes to frames i and i + 1's histograms of both ranks
    whose higher bits it matches."""
    j = cuda.grid(1)
    P, H, W = diff_bits.shape
    if j >= P * H * W:
        return
    i, y, x = voxel(j, H, W)
    bits = diff_bits[i, y, x]
    if bits >= np.uint32(0x80000000):
        return
    bucket = (bits >> np.uint32(shift)) & np.uint32(255)
    for f in range(i, i + 2):
        for r in range(2):
            if shift == 24 or (bits >> np.uint32(shift + 8)) == (prefix[f, r] >> np.uint32(shift + 8)):
                cuda.atomic.add(hist, (f, r, bucket), 1)


@kernel("void(int32[:, :, ::1], uint32[:, ::1], int32[:, ::1], int32[::1], int32)")
def _pick(hist, prefix, rank, count, shift):
    """One thread per frame and rank: the bucket holding the rank, its bits added to the prefix."""
    j = cuda.grid(1)
    F = hist.shape[0]
    if j >= 2 * F:
        return
    f = j // 2
    r = j - 2 * f
    if shift == 24:  # the first pass: every value of the frame is in this histogram
        n = 0
        for b in range(256):
            n += hist[f, r, b]
        count[f] = n
        rank[f, r] = (n - 1) // 2 if r == 0 else n // 2
        prefix[f, r] = 0
    if count[f] == 0:
        return
    k = rank[f, r]
    below = 0
    for b in range(256):
        h = hist[f, r, b]
        if below + h > k:
            prefix[f, r] = prefix[f, r] | (np.uint32(b) << np.uint32(shift))
            rank[f, r] = k - below
            return
        below += h


def frame_noise(ws, frames_d, still, mask, K: int) -> np.ndarray:
    """:func:`~flexvox_core.motion.noise_aware.frame_noise` of the device capture ``frames_d`` (F, H, W) with the
    device volumes ``still`` and ``mask`` (S, H, W) uint8: the noise of each frame (F,) float32, on the host."""
    F, H, W = frames_d.shape
    if F < 2:
        return np.zeros(F, np.float32)
    still_at = ws.get("noise.still_at", (F, H, W), np.uint8)
    launch(_still_at, F * H * W, still, mask, still_at)
    diffs = ws.get("noise.diffs", (F - 1, H, W))
    launch(_differences, (F - 1) * H * W, frames_d, still_at, diffs)
    bits = diffs.view(np.uint32)
    prefix = ws.get("noise.prefix", (F, 2), np.uint32)
    rank = ws.get("noise.rank", (F, 2), np.int32)
    count = ws.get("noise.count", (F,), np.int32)
    hist = ws.get("noise.hist", (F, 2, 256), np.int32)
    zeros = np.zeros((F, 2, 256), np.int32)
    for shift in (24, 16, 8, 0):
        hist.copy_to_device(zeros)
        launch(_histogram, (F - 1) * H * W, bits, prefix, np.int32(shift), hist)
        launch(_pick, 2 * F, hist, prefix, rank, count, np.int32(shift))
    middle = prefix.copy_to_host().view(np.float32)
    n = count.copy_to_host()
    median = (middle[:, 0].astype(np.float64) + middle[:, 1]) / 2
    noise = np.where(n >= noise_aware.MIN_PIXELS, noise_aware.MAD_TO_SIGMA * median / math.sqrt(2), 0.0)
    return noise.astype(np.float32)


@kernel("void(float32[:, :, ::1], float32[::1], float32[:, :, ::1])")
def _smooth_weight(energy, inv_lam2, g):
    i = cuda.grid(1)
    S, H, W = energy.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    if inv_lam2[t] > 0:
        g[t, y, x] = math.exp(-energy[t, y, x] * inv_lam2[t])
    else:
        g[t, y, x] = 0


@kernel("void(float32[:, :, ::1], float32[:, :, ::1], float32[:, :, ::1])")
def _square_sum(gx, gy, out):
    i = cuda.grid(1)
    S, H, W = out.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    out[t, y, x] = gx[t, y, x] * gx[t, y, x] + gy[t, y, x] * gy[t, y, x]


def noise_weights(ws, frames_d, current, still, mask, K: int, out) -> bool:
    """The noise-aware weights g (S, H, W) into ``out``; False (and ``out`` untouched) for a noiseless or
    single-frame capture."""
    noise = frame_noise(ws, frames_d, still, mask, K)
    if not noise.any():
        return False
    S, H, W = current.shape
    lam = noise_aware.KAPPA * np.repeat(noise.astype(np.float64), K)
    inv = np.where(lam > 0, 1 / np.where(lam > 0, lam * lam, 1), 0).astype(np.float32)
    gx = ws.get("noise.gx", (S, H, W))
    gy = ws.get("noise.gy", (S, H, W))
    sobel_slopes(ws, current, gx, gy, noise_aware.GRADIENT_SIGMA, tag="noise.slopes")
    energy = ws.get("noise.energy", (S, H, W))
    launch(_square_sum, S * H * W, gx, gy, energy)
    taps = gaussian_taps(noise_aware.RHO)
    blur(ws, energy, energy, taps, taps, tag="noise.blur")
    launch(_smooth_weight, S * H * W, energy, ws.put("noise.inv", inv), out)
    return True
