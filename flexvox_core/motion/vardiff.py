r"""Variable-tensor diffusion (Eq. 2 with the field of Eq. 4) that keeps the maximum principle.

The centred 19-point stencil of trace(T·H) has negative weights once the anisotropy passes
3 + 2√2 (the paper's tensor has 19), so it overshoots. flexvox instead writes, for
c1 ≥ c2 ≥ c3 ≥ 0,

.. math::

    T = c_3 I + (c_1 - c_3)\,\lambda\lambda^T + (c_2 - c_3)\,\psi\psi^T, \qquad
    \mathrm{trace}(T H) = c_3 \Delta I + (c_1 - c_3) D^2_\lambda I + (c_2 - c_3) D^2_\psi I

and discretises each term by **directional second differences with interpolation**:
``D²_λ I = [I(x + (u, v), t + 1) − 2 I(x, t) + I(x − (u, v), t − 1)] / (1 + u² + v²)`` —
the step along λ ∝ (u, v, 1) lands exactly on the neighbouring sub-frames, so only a 2-D
bilinear interpolation is needed — ``D²_ψ`` likewise within the sub-frame, and Δ by the
7-point stencil. Every neighbour weight is ≥ 0 and they add up to at most 2·trace T, so
an explicit step with ``dt ≤ 1 / (2 trace T)`` is a convex combination of neighbour values:
monotone, stable at any anisotropy, and the result stays within the range of the data.

Voxels given as ``sharp`` read their two neighbours along λ by Catmull-Rom bicubic interpolation
clipped to the range of the four pixels the bilinear read would take. Such a read is not monotone
in the pixels (raising a pixel two taps away can lower it), but it stays within the range of those
four, so each step remains a convex combination of values within the data's range: the maximum
principle holds, and stability with it.

References
----------
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Flexible voxels for motion-aware videography",
ECCV 2010 (the paper).
J. Weickert, *Anisotropic Diffusion in Image Processing*, Teubner, Stuttgart, 1998.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from flexvox_core.motion.tensors import DEFAULT_C, check_c

_KERNEL_LOCK = threading.Lock()
"""One call of the parallel kernel at a time: numba's fallback threading layer (``workqueue``, where
neither OpenMP nor TBB is installed) aborts the process when two threads enter a parallel region at
once (the dask batch, napari's worker and Review's jobs may). Each call uses every core anyway."""


def explicit_steps(time: float, c) -> int:
    """Explicit steps of :func:`variable_tensor_diffusion` for diffusion ``time`` with eigenvalues ``c``:
    ``ceil(time / dt_max)``, dt_max = 1 / (2 Σc). Each step reaches one sub-frame further in time."""
    c1, c2, c3 = check_c(c)
    return math.ceil(time / (1.0 / (2 * (c1 + c2 + c3))))


def _check(init, mask, flow, time, c):
    c1, c2, c3 = check_c(c)
    vol = np.asarray(init, dtype=np.float32)  # read only: the steps write to new volumes
    if vol.ndim != 3:
        raise ValueError(f"`init` must have shape (S, H, W); got {vol.shape}")
    S, H, W = vol.shape
    m = np.asarray(mask, dtype=bool)
    f = np.asarray(flow, dtype=np.float32)
    if m.shape != vol.shape or f.shape != (S, H, W, 2):
        raise ValueError(
            f"`mask` {m.shape} and `flow` {f.shape} must match `init` {vol.shape} (flow with a last axis of 2)"
        )
    if not np.isfinite(vol.sum(dtype=np.float64)):  # one pass, no boolean volume
        raise ValueError("`init` holds NaN or infinite values")
    if not math.isfinite(time) or time < 0:
        raise ValueError(f"`time` must be a finite number >= 0; got {time!r}")
    steps = explicit_steps(time, (c1, c2, c3))
    return (c1, c2, c3), vol, m, f, steps, (time / steps if steps else 0.0)


def variable_tensor_diffusion(
    init,
    mask,
    flow,
    *,
    c=DEFAULT_C,
    time: float = 1.0,
    keep_samples: bool = True,
    out: np.ndarray | None = None,
    scratch: np.ndarray | None = None,
    sharp: np.ndarray | None = None,
) -> np.ndarray:
    """Diffuse ``init`` for diffusion time ``time`` with the motion tensor field of ``flow``.

    Parameters
    ----------
    init : ndarray, shape (S, H, W)
        Starting volume (for example the motion-compensated normalized convolution).
    mask : ndarray of bool, shape (S, H, W)
        Measured voxels; kept fixed when ``keep_samples`` (data consistency).
    flow : ndarray, shape (S, H, W, 2)
        (u, v) per voxel in pixels per sub-frame; NaN/inf are treated as zero flow.
    c : (c1, c2, c3)
        Eigenvalues along λ, ψ, γ, with c1 ≥ c2 ≥ c3 ≥ 0.
    time : float
        Diffusion time n ≥ 0 (the accuracy knob). Steps: ``ceil(n / dt_max)``, dt_max = 1/(2 trace T).
    out : ndarray (S, H, W) float32 C-contiguous, optional
        Where the result goes; may be ``init`` itself (a step never writes the volume it reads:
        with ``out`` = ``init`` one new volume is made instead of two — fresh memory is dear).
    scratch : ndarray (S, H, W) float32 C-contiguous, optional
        A volume the caller no longer needs (its values are overwritten), used instead of the new one:
        no fresh memory at all. It must not share memory with ``init``, ``out``, ``mask`` or ``flow``.
    sharp : ndarray of bool, shape (S, H, W), optional
        Voxels that read their neighbours along the trajectory by Catmull-Rom bicubic interpolation,
        clipped to the range of the four pixels the bilinear read would take (still a convex
        combination of them: the result stays within the data's range), instead of bilinear. A
        bilinear read at a fractional offset is a blur: along a slow trajectory (a fraction of a
        pixel per sub-frame) every step blurs the texture a long-reach gather has kept.

    Returns
    -------
    ndarray, shape (S, H, W), float32 (``out`` when given)

    Each step is one compiled pass (:func:`~flexvox_core.motion.vardiff_kernel.vardiff_step`);
    ``tests/flexvox_core/motion/vardiff_reference.py`` is the same in plain numpy (the tests' reference).
    """
    from flexvox_core.motion.vardiff_kernel import vardiff_step

    (c1, c2, c3), vol, m, f, steps, dt = _check(init, mask, flow, time, c)
    sh = _check_sharp(sharp, vol.shape)
    vol = np.ascontiguousarray(vol)
    m = np.ascontiguousarray(m)
    f = np.ascontiguousarray(f)
    if out is not None and (not isinstance(out, np.ndarray) or out.shape != vol.shape or out.dtype != np.float32
                            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ValueError(f"`out` must be a writable C-contiguous float32 array of shape {vol.shape}")
    others = [vol, m, f] + ([out] if out is not None else [])
    if scratch is not None and (not isinstance(scratch, np.ndarray) or scratch.shape != vol.shape
                                or scratch.dtype != np.float32 or not scratch.flags.c_contiguous
                                or not scratch.flags.writeable or any(np.may_share_memory(scratch, a) for a in others)):
        raise ValueError(f"`scratch` must be a writable C-contiguous float32 array of shape {vol.shape} that shares "
                         "no memory with `init`, `out`, `mask` or `flow`")
    if not steps:
        if out is None:
            return vol.copy()
        np.copyto(out, vol)
        return out
    # Steps alternate between two volumes X and Y, the first reading ``init`` itself (no copy of
    # it) and the last writing X; step k writes X when steps - 1 - k is even. ``out`` is X when it
    # is not ``init``; when it is (or overlaps it), it can be written from the second step on: X
    # for an even count of steps, else Y (X then copied into it).
    spare = [scratch] if scratch is not None else []

    def new_volume():
        return spare.pop() if spare else np.empty_like(vol)

    overlaps = out is not None and np.may_share_memory(out, vol)
    if out is None or not overlaps or steps % 2 == 0:
        x = out if out is not None else new_volume()
        y = new_volume() if steps > 1 else None
    else:
        x, y = new_volume(), out if steps > 1 else None
    src = vol
    with _KERNEL_LOCK:
        for k in range(steps):
            dst = x if (steps - 1 - k) % 2 == 0 else y
            vardiff_step(src, dst, f, m, bool(keep_samples), c1, c2, c3, dt, sh, sharp is not None)
            src = dst
    if out is not None and src is not out:
        np.copyto(out, src)
        return out
    return src


def _check_sharp(sharp, shape) -> np.ndarray:
    """``sharp`` as a C-contiguous bool volume of ``shape`` (None: a 1x1x1 placeholder the kernel never reads)."""
    if sharp is None:
        return np.zeros((1, 1, 1), bool)
    sh = np.ascontiguousarray(sharp, dtype=bool)
    if sh.shape != shape:
        raise ValueError(f"`sharp` {sh.shape} must match `init` {shape}")
    return sh
