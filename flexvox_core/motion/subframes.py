"""What the trajectory gathers read (a sub-frame's samples and their weights) and where they compute."""

from __future__ import annotations

import numpy as np

BAND = 32
"""Rows per box of :func:`selected_boxes`."""


def selected_boxes(select: np.ndarray, pad: int, band: int = BAND):
    """Boxes that cover the True pixels of a 2-D mask: one per band of ``band`` rows that holds
    any, as ((y0, y1, x0, x1), (k0, k1)): the box padded by ``pad`` (what a computation with a
    blur of that reach must read) and the rows of it to keep (the band's own). Scattered moving
    regions then cost about their bands' area, not the whole frame's."""
    H, W = select.shape
    rows = select.any(axis=1)
    for b0 in range(0, H, band):
        b1 = min(H, b0 + band)
        if not rows[b0:b1].any():
            continue
        r = np.flatnonzero(rows[b0:b1]) + b0
        cols = np.flatnonzero(select[r[0]: r[-1] + 1].any(axis=0))
        box = (max(0, r[0] - pad), min(H, r[-1] + 1 + pad), max(0, cols[0] - pad), min(W, cols[-1] + 1 + pad))
        yield box, (int(r[0]), int(r[-1]) + 1)



def flow_at(flow_plane: np.ndarray, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of a sub-frame's flow ``(H, W, 2)`` at the pixels of flat indices ``flat``, as two
    contiguous float32 arrays. Each vector is read as one complex64 (one 8-byte element per index:
    5-10x faster than selecting rows of pairs, the same values)."""
    plane = np.ascontiguousarray(flow_plane, dtype=np.float32)
    picked = plane.reshape(-1).view(np.complex64)[flat]
    return np.ascontiguousarray(picked.real), np.ascontiguousarray(picked.imag)

def sampling_period(mask: np.ndarray) -> int:
    """Sub-frames between a pixel's samples (S / the fewest samples any pixel has; S if some pixel has none)."""
    S = len(mask)
    per_pixel = int(np.asarray(mask, bool).sum(axis=0).min()) if S else 0
    return S // per_pixel if per_pixel else S


def sample_planes(sparse: np.ndarray, mask: np.ndarray) -> tuple[list, list]:
    """The gathers' inputs, sub-frame by sub-frame, without full-volume copies where none is needed.

    Returns ``(values, weights)``, lists of S float32 ``(H, W)`` planes: ``values[t]`` the samples
    of sub-frame t and 0 elsewhere (a view of ``sparse`` where it already holds 0 off-sample; a
    cleaned copy where it holds anything else, NaN included), ``weights[t]`` the mask as 0/1.
    A mask that repeats with the sampling period (an identity code: S / K sub-frames per
    pixel) shares its K weight planes. Fresh memory is slow to come by (at 640×480 × 240
    sub-frames each full-volume temporary cost 0.1–0.5 s of page faults, measured), so the
    two volumes this saves count.
    """
    vals = np.asarray(sparse, np.float32)
    m = np.asarray(mask, bool)
    S = len(m)
    period = sampling_period(m)
    # Compared a plane at a time: no full-volume temporary.
    periodic = 0 < period < S and S % period == 0 and all(np.array_equal(m[t], m[t - period])
                                                           for t in range(period, S))
    # Where each sub-frame's samples are (flat indices: a sixteenth of the pixels at K = 16 are read
    # to check a plane, instead of a boolean selection over all of them).
    at = [np.flatnonzero(m[p]) for p in range(period if periodic else S)]
    values = []
    for t in range(S):
        # Clean: every nonzero (NaN counts) is at a sample. Counted on the bits (8x faster than on
        # the floats; a -0.0 off the samples then counts, and the plane is cleaned: the same sums).
        bits = vals[t].view(np.uint32)
        clean = np.count_nonzero(bits) == np.count_nonzero(bits.reshape(-1)[at[t % len(at)]])
        values.append(vals[t] if clean else np.where(m[t], vals[t], np.float32(0)))
    if periodic:
        shared = m[:period].astype(np.float32)
        weights = [shared[t % period] for t in range(S)]
    else:
        weights = list(m.astype(np.float32))
    return values, weights
