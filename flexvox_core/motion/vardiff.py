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
monotone, stable at any anisotropy, and the result stays within the range of the data. The step
computes in float32; ``dt`` is kept a millionth inside that bound (:func:`float32_step`), a margin
for the rounding of its sums, so this holds of the float32 results too.

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
import warnings
from typing import Any

import numpy as np

from flexvox_core import planes
from flexvox_core.motion.tensors import DEFAULT_C, check_c
from flexvox_core.threads import for_each, workers

_KERNEL_LOCK = threading.Lock()
"""One call of the parallel kernel at a time: numba's fallback threading layer (``workqueue``, where
neither OpenMP nor TBB is installed) aborts the process when two threads enter a parallel region at
once (the dask batch, napari's worker and Review's jobs may). Each call uses every core anyway."""

MIN_BAND = 8
"""The fewest sub-frames of a band (:func:`band_length`)."""


STILL_READ_SPEED = 1e-3
"""The refinement's still speed, px per sub-frame (:func:`refine_still_speed`): a trajectory read this far off is
the pixel itself to a thousandth of the difference to its neighbour."""


def refine_still_speed(still_speed: float | None) -> float | None:
    """The ``still_speed`` of motion-aware's refinement (both engines) for the speed classes' ``still_speed``: the
    smaller of it and :data:`STILL_READ_SPEED` (None where there is no still class). The flow made full-size from a
    smaller scale gives the still voxels next to moving ones tiny speeds; taken as still they skip four reads each
    (the classes' still speed itself is too coarse for this: docs/benchmarks.md)."""
    return None if still_speed is None else min(float(still_speed), STILL_READ_SPEED)


def explicit_steps(time: float, c) -> int:
    """Explicit steps of :func:`variable_tensor_diffusion` for diffusion ``time`` with eigenvalues ``c``:
    ``ceil(time / dt_max)``, dt_max = 1 / (2 Σc). Each step reaches one sub-frame further in time."""
    c1, c2, c3 = check_c(c)
    return math.ceil(time / (1.0 / (2 * (c1 + c2 + c3))))


def band_length(steps: int, threads: int) -> int:
    """Sub-frames per band of :func:`variable_tensor_diffusion` at ``steps`` explicit steps on ``threads``
    threads: :data:`MIN_BAND`, or one a thread where there are more (a band's flow planes are made side by side).
    No sub-frame is stepped twice whatever the band, so it sets only the memory taken: about ``band + steps + 1``
    planes of the steps' float32 buffers (one at two steps, the refinement's, from a C-contiguous ``init``), the flow
    (two float32) and two bool volumes (14 bytes a pixel so; 4.3 MB a plane at 640×480). ``steps`` is not used."""
    return max(MIN_BAND, threads)


def _as_volume(x: Any) -> Any:
    """``x`` itself when it is read by bands (an array or a :class:`~flexvox_core.planes.Bands`), else as
    an array."""
    return x if isinstance(x, np.ndarray) or hasattr(x, "band") else np.asarray(x)


def _read_into(volume: Any, t0: int, t1: int, out: np.ndarray) -> None:
    """Sub-frames ``t0`` to ``t1`` of ``volume`` (an array or read by bands) into ``out``; a volume with
    ``band_into(t0, t1, out)`` makes them there."""
    into = getattr(volume, "band_into", None)
    if into is not None:
        into(t0, t1, out)
    else:
        out[...] = planes.band(volume, t0, t1)


def _read_bands(reads: list[tuple[Any, int, int, np.ndarray]]) -> None:
    """Each ``(volume, t0, t1, out)`` of ``reads`` as :func:`_read_into`, a volume per task on the threads: the
    mask's and the classes' bands beside the flow's (whose ``band_into`` spreads its planes over the threads too,
    a thread joining it once its own task is done)."""

    def one(k: int) -> None:
        _read_into(*reads[k])

    for_each(one, len(reads))


def _all_finite(vol: np.ndarray) -> bool:
    """Whether every value of the float32 ``vol`` is finite: a float64 sum per chunk of sub-frames on the threads
    (a sum of finite float32 values cannot overflow float64: NaN or inf in it is NaN or inf in the volume)."""
    n = len(vol)
    chunks = min(n, 4 * workers())
    finite = np.ones(max(chunks, 0), bool)

    def one(i: int) -> None:
        part = vol[i * n // chunks:(i + 1) * n // chunks]
        finite[i] = np.isfinite(part.sum(dtype=np.float64))

    for_each(one, chunks)
    return bool(finite.all())


STEP_MARGIN = 2.0**-20
"""The float32 step keeps 2 dt trace T ≤ 1 − this (:func:`float32_step`): the convex combination's margin for the
rounding of its dozen float32 operations (each within 2⁻²⁴ of its terms), so that the result stays within the range
of the values it combines."""


def float32_step(c, dt: float, still2: float) -> tuple[np.float32, ...]:
    """The step's scalars in float32, the kernel's arithmetic: the eigenvalues ``c``, ``dt`` (rounded down until
    2 dt trace T ≤ 1 − :data:`STEP_MARGIN` with the float32 eigenvalues: only a step within a millionth of the bound
    1 / (2 trace T) changes) and the still speed² ``still2``."""
    c32 = tuple(np.float32(v) for v in c)
    dt32 = np.float32(dt)
    while dt32 > 0 and 2.0 * float(dt32) * sum(float(v) for v in c32) > 1.0 - STEP_MARGIN:
        dt32 = np.nextafter(dt32, np.float32(0))
    return (*c32, dt32, np.float32(still2))


def _check(init, mask, flow, time, c, start: int = 0):
    c1, c2, c3 = check_c(c)
    vol = np.asarray(init, dtype=np.float32)  # read only: the steps write to new volumes
    if vol.ndim != 3:
        raise ValueError(f"`init` must have shape (S, H, W); got {vol.shape}")
    S, H, W = vol.shape
    m, f = _as_volume(mask), _as_volume(flow)
    ms, fs = tuple(m.shape), tuple(f.shape)
    if (len(ms) != 3 or ms[1:] != (H, W) or len(fs) != 4 or fs[1:] != (H, W, 2) or ms[0] != fs[0]
            or not 0 <= start <= ms[0] - S):
        raise ValueError(
            f"`mask` {ms} and `flow` {fs} must match `init` {vol.shape} (flow with a last axis of 2)"
            + (f" from sub-frame `start` = {start} on" if start else ""))
    if not _all_finite(vol):  # one pass, no boolean volume
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
    sharp: Any = None,
    start: int = 0,
    band: int | None = None,
    still_speed: float | None = None,
    **deprecated: Any,
) -> np.ndarray:
    """Diffuse ``init`` for diffusion time ``time`` with the motion tensor field of ``flow``.

    Parameters
    ----------
    init : ndarray, shape (S, H, W)
        Starting volume (for example the motion-compensated normalized convolution).
    mask : ndarray of bool, shape (S, H, W), or a volume read by bands
        Measured voxels; kept fixed when ``keep_samples`` (data consistency).
    flow : ndarray, shape (S, H, W, 2), or a volume read by bands
        (u, v) per voxel in pixels per sub-frame; NaN/inf are treated as zero flow.
    c : (c1, c2, c3)
        Eigenvalues along λ, ψ, γ, with c1 ≥ c2 ≥ c3 ≥ 0.
    time : float
        Diffusion time n ≥ 0 (the accuracy knob). Steps: ``ceil(n / dt_max)``, dt_max = 1/(2 trace T).
    out : ndarray (S, H, W) float32 C-contiguous, optional
        Where the result goes: ``init`` itself, or an array that shares no memory with it.
    sharp : ndarray of bool, shape (S, H, W), or a volume read by bands, optional
        Voxels that read their neighbours along the trajectory by Catmull-Rom bicubic interpolation,
        clipped to the range of the four pixels the bilinear read would take (still a convex
        combination of them: the result stays within the data's range), instead of bilinear. A
        bilinear read at a fractional offset is a blur: along a slow trajectory (a fraction of a
        pixel per sub-frame) every step blurs the texture a long-reach gather has kept.
    start : int
        ``mask``, ``flow`` and ``sharp`` may be longer volumes: their sub-frames ``start`` to ``start + S`` are
        ``init``'s. The ends of time are ``init``'s.
    still_speed : float, optional
        Voxels slower than this (px per sub-frame: u² + v² < still_speed²) are taken as still, their flow as zero
        (the flow made full-size from a smaller scale gives the still voxels next to moving ones tiny speeds; a
        trajectory read a hundredth of a pixel off is the pixel itself, blurred a little, at the cost of four
        reads). None: only a zero flow is.
    band : int, optional
        Input sub-frames read per band (default :func:`band_length`); the result does not depend on it.

    Returns
    -------
    ndarray, shape (S, H, W), float32 (``out`` when given)

    The volume is diffused a band of sub-frames at a time, each step running behind the one before: step j is
    known up to sub-frame e − j once the input is read up to e (each step reads one sub-frame either side). A
    band reads the input over [e0, e1) and takes each step j from e0 − j to e1 − j; the last step's sub-frames
    are written to ``out``. The first step reads ``init`` and the last writes ``out`` themselves (where ``out`` is
    ``init`` with one step only, or ``init`` is not C-contiguous, through a buffer: a step writes sub-frames the
    next band's first step reads). The steps between them go in buffers that hold a window of
    ``band + steps + 1`` sub-frames (they alternate between two of them; the planes a later band still reads are
    moved to the front), so no sub-frame is stepped twice and every plane of ``mask``, ``flow`` and ``sharp`` is
    read once (:func:`~flexvox_core.planes.band`, or ``band_into(t0, t1, out)`` where the volume has it: they may
    be volumes made on demand): the same bits as stepping the whole volume. No volume-sized memory is taken beyond
    the result (none with ``out``); the buffers are taken once a call. Each step is one compiled pass
    (:func:`~flexvox_core.motion.vardiff_kernel.vardiff_step`);
    ``tests/flexvox_core/motion/vardiff_reference.py`` is the same in plain numpy (the tests' reference).

    The keyword ``scratch`` (a working volume) is deprecated and ignored: no working volume is needed.
    """
    from flexvox_core.motion.vardiff_kernel import vardiff_step

    if "scratch" in deprecated:
        deprecated.pop("scratch")
        warnings.warn("`scratch` of variable_tensor_diffusion is deprecated and will be removed in the next "
                      "release: it is ignored (the diffusion runs in band-sized buffers): call it without",
                      DeprecationWarning, stacklevel=2)
    if deprecated:
        raise TypeError(f"variable_tensor_diffusion() got unexpected keyword arguments {sorted(deprecated)}")
    if isinstance(start, bool) or not isinstance(start, (int, np.integer)):
        raise ValueError(f"`start` must be a whole number of sub-frames; got {start!r}")
    (c1, c2, c3), vol, m, f, steps, dt = _check(init, mask, flow, time, c, int(start))
    start = int(start)
    S, H, W = vol.shape
    sh = None if sharp is None else _as_volume(sharp)
    if sh is not None and (tuple(sh.shape) != tuple(m.shape)):
        raise ValueError(f"`sharp` {tuple(sh.shape)} must match `init` {vol.shape}"
                         + (f" from sub-frame `start` = {start} on" if start else ""))
    if out is not None and (not isinstance(out, np.ndarray) or out.shape != vol.shape or out.dtype != np.float32
                            or not out.flags.c_contiguous or not out.flags.writeable):
        raise ValueError(f"`out` must be a writable C-contiguous float32 array of shape {vol.shape}")
    in_place = out is not None and np.may_share_memory(out, vol)
    if in_place and not (out.__array_interface__["data"][0] == vol.__array_interface__["data"][0]
                         and out.strides == vol.strides):
        raise ValueError("`out` must be `init` itself or share no memory with it")
    if still_speed is not None and not (math.isfinite(still_speed) and still_speed >= 0):
        raise ValueError(f"`still_speed` must be a finite number >= 0 or None; got {still_speed!r}")
    still2 = 0.0 if still_speed is None else float(still_speed) ** 2
    if band is None:
        import numba

        band = band_length(steps, numba.get_num_threads())
    if isinstance(band, bool) or not isinstance(band, (int, np.integer)) or band < 1:
        raise ValueError(f"`band` must be a whole number of sub-frames >= 1; got {band!r}")
    k1, k2, k3, kdt, kstill2 = float32_step((c1, c2, c3), dt, still2)
    result = out if out is not None else np.empty_like(vol)
    if not steps:
        if result is not vol:
            np.copyto(result, vol)
        return result
    L = min(int(band), S)
    n_max = min(S, L + steps + 1)  # the window: the planes carried from the band before, and the band's own
    # The first step reads `vol` and the last writes `result` (no copy in or out) unless they are one volume and one
    # step: a band's last step writes up to sub-frame e1 − steps, the next band's first step reads from e1 − 2 on.
    direct = vol.flags.c_contiguous and (steps > 1 or not in_place)
    # The steps in turn: even ones in bufs[0], odd ones in bufs[1]; only those some step writes and the next reads.
    bufs = [np.empty((n_max if needed else 0, H, W), np.float32)
            for needed in (not direct or steps > 2, not direct or steps > 1)]
    fb = np.empty((n_max, H, W, 2), np.float32)
    mb = np.empty((n_max, H, W), bool)
    sb = np.zeros((1, 1, 1), bool) if sh is None else np.empty((n_max, H, W), bool)  # the kernel never reads it
    use_sharp = sh is not None
    carried = [b for b in bufs if len(b)] + [fb, mb] + ([sb] if use_sharp else [])
    c0 = 0  # the window's first sub-frame
    with _KERNEL_LOCK:
        for e0 in range(0, S, L):  # the band: input sub-frames [e0, e1)
            e1 = min(e0 + L, S)
            k0 = max(0, e0 - steps - 1)  # from here on, each step's planes are still read
            if k0 > c0:  # the planes carried: each a task on the threads where none is moved onto another's source
                if k0 - c0 >= e0 - k0:
                    moves = [(buf, p) for buf in carried for p in range(e0 - k0)]

                    def move(i: int, moves: list = moves, shift: int = k0 - c0) -> None:
                        buf, p = moves[i]
                        buf[p] = buf[shift + p]

                    for_each(move, len(moves))
                else:
                    for buf in carried:
                        buf[:e0 - k0] = buf[k0 - c0:e0 - c0]
                c0 = k0
            n = e1 - c0
            if not direct:
                bufs[0][e0 - c0:n] = vol[e0:e1]
            _read_bands([(f, start + e0, start + e1, fb[e0 - c0:n]), (m, start + e0, start + e1, mb[e0 - c0:n])]
                         + ([(sh, start + e0, start + e1, sb[e0 - c0:n])] if use_sharp else []))
            for j in range(1, steps + 1):
                # Step j is known up to sub-frame e0 − j (each step reads one sub-frame either side); now to e1 − j,
                # or to the end of time. The buffers end at the window's end: where that is not the end of time,
                # no step is taken at the window's last plane.
                lo, hi = max(0, e0 - j), (e1 - j if e1 < S else S)
                src = vol[c0:e1] if direct and j == 1 else bufs[(j - 1) % 2][:n]
                dst = result[c0:e1] if direct and j == steps else bufs[j % 2][:n]
                vardiff_step(src, dst, fb[:n], mb[:n], bool(keep_samples), k1, k2, k3, kdt,
                             sb if not use_sharp else sb[:n], use_sharp, lo - c0, hi - c0, kstill2)
            lo, hi = max(0, e0 - steps), (e1 - steps if e1 < S else S)
            if hi > lo and not direct:
                result[lo:hi] = bufs[steps % 2][lo - c0:hi - c0]
    return result
