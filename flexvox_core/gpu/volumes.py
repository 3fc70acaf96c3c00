"""Device buffers and the element-wise kernels every stage shares.

:class:`Workspace` holds a window's device buffers by name and hands the same memory back while the shape and
type stay the same: a streaming run or the live preview allocates once, not every window (device allocations
synchronise the card and cost far more than the kernels that fill them).
"""

from __future__ import annotations

import math

import numpy as np
from numba import cuda
from numba.core.types import float16, float32

from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import kernel, launch


class Workspace:
    """Device buffers by name, reused while their shape and dtype stay the same."""

    def __init__(self):
        self._buffers: dict[str, object] = {}
        self._held: dict[str, object] = {}
        self.generation = 0
        """How many windows have run on the workspace: a result whose buffers a later window overwrote knows it."""
        self.peak_nbytes = 0
        """The most device memory the workspace has held at once (:attr:`nbytes` after each allocation): what
        :attr:`~flexvox_core.methods.spec.MethodSpec.gpu_bytes_per_voxel` is checked against."""

    def next_generation(self) -> int:
        """A new window starts on the workspace: its generation."""
        self.generation += 1
        return self.generation

    def get(self, name: str, shape, dtype=np.float32):
        """The buffer ``name`` of ``shape`` and ``dtype`` (its contents are whatever was left in it)."""
        shape = tuple(int(v) for v in shape)
        dtype = np.dtype(dtype)
        buf = self._buffers.get(name)
        if buf is None or tuple(buf.shape) != shape or np.dtype(buf.dtype) != dtype:
            buf = cuda.device_array(shape, dtype)
            self._buffers[name] = buf
            self.peak_nbytes = max(self.peak_nbytes, self.nbytes)
        return buf

    def put(self, name: str, array: np.ndarray):
        """``array`` copied into the buffer ``name`` (made or reused to fit it); returns the device buffer."""
        host = np.ascontiguousarray(array)
        buf = self.get(name, host.shape, host.dtype)
        buf.copy_to_device(host)
        return buf

    def held(self, name: str, fits, make):
        """An object ``name`` that holds device buffers of its own and says how many bytes (``nbytes``), such as
        DIS's :class:`~flexvox_core.gpu.dis.DisWorkspace`: the one held while ``fits(it)``, else ``make()``'s."""
        obj = self._held.get(name)
        if obj is None or not fits(obj):
            self._held.pop(name, None)  # freed before its successor is made
            obj = self._held[name] = make()
            self.peak_nbytes = max(self.peak_nbytes, self.nbytes)
        return obj

    def drop(self, *names: str) -> None:
        """Free these buffers or held objects (the next :meth:`get` or :meth:`held` allocates again)."""
        for name in names:
            self._buffers.pop(name, None)
            self._held.pop(name, None)

    @property
    def nbytes(self) -> int:
        """Device memory the workspace holds, its held objects' included."""
        return (sum(int(b.size) * np.dtype(b.dtype).itemsize for b in self._buffers.values())
                + sum(int(h.nbytes) for h in self._held.values()))


def flat(a):
    """A contiguous device array as 1-D (a view)."""
    return a.reshape(int(math.prod(a.shape)))


@kernel("void(float32[::1], float32)")
def _fill(a, value):
    i = cuda.grid(1)
    if i < a.shape[0]:
        a[i] = value


def fill(a, value: float) -> None:
    """Every element of the float32 device array ``a`` set to ``value``."""
    v = flat(a)
    launch(_fill, v.shape[0], v, np.float32(value))


@kernel("void(float32[::1], float32[::1])")
def _copy(dst, src):
    i = cuda.grid(1)
    if i < dst.shape[0]:
        dst[i] = src[i]


def copy(dst, src) -> None:
    """``dst[...] = src`` for two float32 device arrays of one size."""
    d, s = flat(dst), flat(src)
    if d.shape != s.shape:
        raise ValueError(f"copy: sizes differ ({d.shape[0]} and {s.shape[0]})")
    launch(_copy, d.shape[0], d, s)


@kernel("void(float32[::1], float32[::1], uint8[::1])")
def _copy_where(dst, src, where):
    i = cuda.grid(1)
    if i < dst.shape[0] and where[i]:
        dst[i] = src[i]


def copy_where(dst, src, where) -> None:
    """``dst[where] = src[where]`` (float32 volumes, a uint8 mask of one size)."""
    launch(_copy_where, int(math.prod(dst.shape)), flat(dst), flat(src), flat(where))


@kernel("void(float32[::1], float32, float32)")
def _clip(a, lo, hi):
    i = cuda.grid(1)
    if i < a.shape[0]:
        a[i] = min(max(a[i], lo), hi)


def clip(a, lo: float, hi: float) -> None:
    """``a`` clipped to [lo, hi] in place."""
    v = flat(a)
    launch(_clip, v.shape[0], v, np.float32(lo), np.float32(hi))


@kernel("void(float32[::1])")
def _through_half(a):
    i = cuda.grid(1)
    if i < a.shape[0]:
        a[i] = float32(float16(a[i]))


def through_half(a) -> None:
    """``a`` (float32) rounded in place to float16's nearest value (ties to even, as numpy's
    ``astype(np.float16)``)."""
    v = flat(a)
    launch(_through_half, v.shape[0], v)


@kernel("void(float32[:, :, ::1], int32[:, ::1], uint8[::1], float32[:, :, ::1], uint8[:, :, ::1])")
def _samples(frames, order, present, sparse, mask):
    i = cuda.grid(1)
    S, H, W = sparse.shape
    if i >= S * H * W:
        return
    s, y, x = voxel(i, H, W)
    K = S // frames.shape[0]
    f = s // K
    if order[y, x] == s - f * K and present[f]:
        sparse[s, y, x] = frames[f, y, x]
        mask[s, y, x] = 1
    else:
        sparse[s, y, x] = 0
        mask[s, y, x] = 0


def samples(frames_d, order_d, present_d, K: int, sparse, mask) -> None:
    """The sample volume (S, H, W) float32, 0 off the samples, and its mask (uint8), of an identity-code
    capture: what :func:`flexvox_core.forward.sparse_volume` and :func:`~flexvox_core.forward.sample_mask`
    give, with a dropped frame's (``present_d`` 0) sub-frames holding none."""
    launch(_samples, int(math.prod(sparse.shape)), frames_d, order_d, present_d, sparse, mask)
