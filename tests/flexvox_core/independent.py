"""Independent checks written straight from the definitions (no shared code with the package)."""

import numpy as np


def divisions_slow(m, n):
    K = m * n
    return [
        (a, b, c)
        for a in range(1, m + 1)
        for b in range(1, n + 1)
        for c in range(1, K + 1)
        if m % a == 0 and n % b == 0 and K % c == 0 and a * b * c == K
    ]


def supports_all_slow(order):
    """Every block of every division of the tile holds exactly one sample."""
    order = np.asarray(order)
    m, n = order.shape
    K = m * n
    if sorted(order.ravel().tolist()) != list(range(K)):
        return False
    for a, b, c in divisions_slow(m, n):
        for i0 in range(0, m, a):
            for j0 in range(0, n, b):
                for s0 in range(0, K, c):
                    count = 0
                    for i in range(i0, i0 + a):
                        for j in range(j0, j0 + b):
                            if s0 <= order[i, j] < s0 + c:
                                count += 1
                    if count != 1:
                        return False
    return True


def capture_slow(video, code):
    """capture[f, y, x] = sum_s code[y % m, x % n, s] * video[f*K + s, y, x], a loop per voxel."""
    m, n, K = code.shape
    S, H, W = video.shape
    F = S // K
    out = np.zeros((F, H, W), dtype=video.dtype)
    for f in range(F):
        for y in range(H):
            for x in range(W):
                total = video.dtype.type(0)
                for s in range(K):
                    if code[y % m, x % n, s]:
                        total = total + video[f * K + s, y, x]
                out[f, y, x] = total
    return out
