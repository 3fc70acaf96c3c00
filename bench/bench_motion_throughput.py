"""Motion-aware throughput: a 1-s, 15 Hz, 640×480 clip with the 4×4 code (K = 16, 73.7 M voxels).

For each moving built-in scene: the end-to-end time of ``motion_aware`` with its defaults, the
split between its steps (high-TR reconstruction, flow, motion-compensated diffusion), M voxels/s,
PSNR; and, as the baseline timed in the same run, the fixed-tensor normalized convolution
(``diffuse`` with the paper's high-SR tensor, n = 4) with its time, PSNR and the ratio.
It prints the M voxels/s and their ratio to 5 and to 15 M voxels/s (15 s and 5 s for the clip; docs/benchmarks.md).

Figures only, never pass/fail. Usage:
``python bench/bench_motion_throughput.py [SCENES] [--frames F] [--flow-scale S] [--slow-reach R] [--refine n]
[--no-local-choice]``
(default: balls,drummer; F = 15; S: automatic, a third at 640×480; R: motion_aware's default).

``--ab VARIANT [--rounds N] [--size HxW] [--noise σ]``: instead, the kept code against VARIANT (one of
:data:`VARIANTS`: the code as it was before one change, patched back in) on a clip of that size (default 480x640)
with that Gaussian noise added to the frames (default none), alternating in one process after a warm-up call of
each, N rounds: each stage's seconds (``stage_seconds``), the total and the PSNR per run, then the medians; and each
one's peak memory (``ru_maxrss``) in a child process that loads only the frames and runs ``motion_aware`` once, cold.

``--quality VARIANT [--size HxW] [--noise σ]``: the kept code's PSNR against VARIANT's on every moving built-in
scene, clean and with Gaussian noise of σ (default 240x320, σ = 0.01), and the difference (the issue's rule: within
0.05 dB).

``--memory``: where the memory goes, one cold ``motion_aware`` call in a child process (as ``--ab``'s peak):
the resident MB at each stage's start, its peak within the stage (the peak reset at its start:
``/proc/self/clear_refs``, Linux) and at its end.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from typing import Any
from unittest import mock

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.reconstruct import diffuse
from flexvox_core.simulate.scenes import render_scene


def _repository_on_path() -> None:
    """Put the repository's root first on ``sys.path`` (``python bench/...`` puts bench/ there): the variants that
    patch in the tests' references import ``tests``."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if root not in sys.path:
        sys.path.insert(0, root)


@contextlib.contextmanager
def _gather_by_remap() -> Iterator[None]:
    """Before the trajectory gather read the frames and the code: it remapped the sample volume (made here: no
    stage makes it now) and its mask, a list of voxels per sub-frame."""
    from flexvox_core.forward import sample_mask, sparse_volume
    from flexvox_core.gaps import interpolated_subframes
    from flexvox_core.motion import noise_aware, stages
    from flexvox_core.motion.mcnc import motion_compensated_nc


    def before(self, flow, base, still, slow, high_tr, wide, *, leave_one_out):
        w = self.window
        loo = np.full(w.frames.shape, np.nan, np.float32) if leave_one_out else None
        into = base if w.passes == 1 or base is not self.fixed else None
        sparse = sparse_volume(np.asarray(w.frames, np.float32), w.code)  # made here, as it was in `samples`
        mask = sample_mask(sparse.shape, w.code)
        if w.missing is not None:
            gap = interpolated_subframes(w.missing, w.K)
            mask[gap] = False
            sparse[gap] = 0
        gathered = stages.band(self.gathered, 0, w.S)  # held a bit per voxel now: made whole, as it was
        video = motion_compensated_nc(sparse, mask, flow.flow, c=w.gather_c, time=w.gather_time, fallback=high_tr,
                                      gathered=gathered, still_value=base, loo=loo, wide=wide,
                                      wide_sigma=noise_aware.wide_sigma(w.K), max_reach=w.gather_reach, out=into)
        gathered = gathered if loo is not None else None
        if self.last:
            self.fixed = self.still_value = None
        return video, loo, gathered

    with mock.patch.object(stages.CpuStages, "trajectory_gather", before):
        yield


@contextlib.contextmanager
def _scratch_volume() -> Iterator[None]:
    """Before the refinement and the local choice ran a band at a time: one (S, H, W) scratch volume for both, freed
    at the pass's end; the refinement's explicit steps over the whole volume, oriented nc made whole, then one blend."""
    from flexvox_core import planes
    from flexvox_core.motion import local_choice, stages
    from flexvox_core.motion.options import REFINE_C
    from flexvox_core.motion.vardiff import _KERNEL_LOCK, explicit_steps
    from flexvox_core.motion.vardiff_kernel import vardiff_step
    from flexvox_core.reconstruct.oriented_nc import oriented_nc

    kept = stages.CpuStages.refinement, stages.CpuStages.local_choice, stages.CpuStages.clip

    def spare(self):
        if getattr(self, "bench_scratch", None) is None:
            self.bench_scratch = np.empty((self.window.S, *self.window.frames.shape[1:]), np.float32)
        return self.bench_scratch

    def refinement(self, video, flow, slow):
        w = self.window
        time = w.refine_time
        if time <= 0:
            return
        g0, g1 = w.gathered
        c1, c2, c3 = REFINE_C
        steps = explicit_steps(time, REFINE_C)
        f = np.ascontiguousarray(planes.band(flow.flow, g0, g1))
        m = np.ascontiguousarray(planes.band(self._mask(), g0, g1))
        sh = np.ascontiguousarray(planes.band(slow, g0, g1))
        out, other = video[g0:g1], spare(self)[g0:g1]
        x, y = (out, other) if steps % 2 == 0 else (other, out)
        src = out
        with _KERNEL_LOCK:
            for k in range(steps):
                dst = x if (steps - 1 - k) % 2 == 0 else y
                vardiff_step(src, dst, f, m, True, c1, c2, c3, time / steps, sh, True, 0, g1 - g0)
                src = dst
        if src is not out:
            np.copyto(out, src)

    def local_choice_(self, video, loo, gathered, flow, high_tr):
        w = self.window
        if not np.isfinite(loo).any():
            return
        if w.scores_still_voxels:
            local_choice.still_voxel_loo(loo, video, w.frames, gathered, self._mask(), flow.flow, w.K)
        other, other_loo = oriented_nc(w.frames, w.code, high_tr, where=gathered, fallback=video, missing=w.missing,
                                       out=spare(self))
        local_choice.blend(video, other, local_choice.local_weights(loo, other_loo, w.frames), gathered, w.K)

    def clip(self, video):
        if self.last:
            self.bench_scratch = None
        return kept[2](self, video)

    stages.CpuStages.refinement, stages.CpuStages.local_choice, stages.CpuStages.clip = (  # type: ignore[method-assign]
        refinement, local_choice_, clip)
    try:
        yield
    finally:
        stages.CpuStages.refinement, stages.CpuStages.local_choice, stages.CpuStages.clip = kept  # type: ignore


@contextlib.contextmanager
def _long_reach_on_sample_planes() -> Iterator[None]:
    """Before the long reach read the frames: ``long_reach_nc``, two ``cv2.remap`` (four pixels each) of the sample
    volume's planes and its mask per read, then the samples copied back from the volume."""
    from flexvox_core.forward import sample_mask, sparse_volume
    from flexvox_core.gaps import interpolated_subframes
    from flexvox_core.motion import stages
    from flexvox_core.motion.longreach import long_reach_nc


    def before(self, flow, video, slow):
        w = self.window
        if not slow.any():
            return
        sparse, mask = getattr(self, "sparse", None), getattr(self, "mask", None)
        if sparse is None or mask is None:  # an engine without the sample volume: made here, as it was
            sparse = sparse_volume(np.asarray(w.frames, np.float32), w.code)
            mask = sample_mask(sparse.shape, w.code)
            if w.missing is not None:
                gap = interpolated_subframes(w.missing, w.K)
                mask[gap] = False
                sparse[gap] = 0
        p = w.long_reach_plan
        long_reach_nc(sparse, mask, flow.flow, video, stages.band(slow, 0, w.S), reach=p.reach, sigma_t=p.sigma_t,
                      sigma_s=p.sigma_s, h=p.h, out=video)
        np.copyto(video, sparse, where=mask)

    with mock.patch.object(stages.CpuStages, "long_reach", before):
        yield


@contextlib.contextmanager
def _refine_halo_bands() -> Iterator[None]:
    """Before the refinement carried its steps from band to band: bands of max(16, 2 threads, 8 steps) output
    sub-frames, each stepped from its input with a halo of ``steps`` sub-frames each side (the halo stepped again by
    the next band), the flow, mask and sharp planes of band and halo made in fresh memory for each band; and no
    still speed (the still voxels' tiny speeds read along the trajectory)."""
    import numba

    from flexvox_core import planes
    from flexvox_core.motion import stages
    from flexvox_core.motion.vardiff import _KERNEL_LOCK, explicit_steps
    from flexvox_core.motion.vardiff_kernel import vardiff_step


    def before(init, mask, flow, *, c, time, out, sharp, start, still_speed=None):
        c1, c2, c3 = c
        steps = explicit_steps(time, c)
        vol = init
        S, H, W = vol.shape
        L = min(max(16, 2 * numba.get_num_threads(), 8 * steps), S)
        bufs = np.empty((2, min(S, L + 2 * steps), H, W), np.float32)
        saved = np.empty((min(S, steps), H, W), np.float32)  # in place: the input a later band still reads
        with _KERNEL_LOCK:
            for a in range(0, S, L):
                b = min(a + L, S)
                c0, c1_ = max(0, a - steps), min(S, b + steps)
                n = c1_ - c0
                x = bufs[0, :n]
                if c0 < a:
                    x[:a - c0] = saved[:a - c0]
                    x[a - c0:] = vol[a:c1_]
                else:
                    x[:] = vol[c0:c1_]
                k0 = max(c0, b - steps)
                saved[:b - k0] = x[k0 - c0:b - c0]
                fb = np.ascontiguousarray(planes.band(flow, start + c0, start + c1_), dtype=np.float32)
                mb = np.ascontiguousarray(planes.band(mask, start + c0, start + c1_), dtype=bool)
                sb = np.ascontiguousarray(planes.band(sharp, start + c0, start + c1_), dtype=bool)
                src, dst = x, bufs[1, :n]
                for j in range(1, steps + 1):
                    lo, hi = max(0, a - c0 - (steps - j)), min(n, b - c0 + (steps - j))
                    vardiff_step(src, dst, fb, mb, True, c1, c2, c3, time / steps, sb, True, lo, hi)
                    src, dst = dst, src
                out[a:b] = src[a - c0:b - c0]
        return out

    with mock.patch.object(stages, "variable_tensor_diffusion", before):
        yield


@contextlib.contextmanager
def _refine_moving_still() -> Iterator[None]:
    """Before the refinement took the voxels slower than the still speed as still: their tiny speeds (the flow made
    full-size from a smaller scale) read along the trajectory, four pixels a read."""
    from flexvox_core.motion import stages

    kept = stages.variable_tensor_diffusion

    def before(*args, still_speed=None, **kwargs):
        return kept(*args, **kwargs)

    with mock.patch.object(stages, "variable_tensor_diffusion", before):
        yield


@functools.cache
def _clamped_reads_step() -> Callable[..., None]:
    """``vardiff_step`` compiled with the clamped reads everywhere (compiled once a process)."""
    import types

    import numba

    from flexvox_core.motion import vardiff_kernel as vk

    f = vk.vardiff_step.py_func
    glb = {**f.__globals__, "_bilinear": vk._clamped_bilinear, "_bicubic": vk._clamped_bicubic}
    return numba.njit(**vk.STEP_OPTIONS)(types.FunctionType(f.__code__, glb, f.__name__, f.__defaults__))


@contextlib.contextmanager
def _refine_clamped_reads() -> Iterator[None]:
    """Before the refinement's step read its trajectory neighbours without clamps where every tap is inside the
    picture: every bilinear and bicubic read clamped (the same arithmetic: the last bit or two, FMA contraction)."""
    from flexvox_core.motion import vardiff_kernel as vk

    with mock.patch.object(vk, "vardiff_step", _clamped_reads_step()):
        yield


@functools.cache
def _signed_reads_step() -> Callable[..., None]:
    """``vardiff_step`` compiled with its unclamped reads indexed by signed integers (numba wraps negative ones):
    the kept reads' source with every ``np.uint64(...)`` cast taken out (compiled once a process)."""
    import inspect
    import re
    import textwrap
    import types

    import numba

    from flexvox_core.motion import vardiff_kernel as vk

    namespace = dict(vk.__dict__)
    for name in ("_bilinear", "_bicubic"):
        src = textwrap.dedent(inspect.getsource(getattr(vk, name).py_func))
        assert "np.uint64(" in src, "the refinement's reads changed: update this variant"
        src = re.sub(r"np\.uint64\(", "(", src).replace("@numba.njit(inline=\"always\", nogil=True, cache=True)",
                                                      "@numba.njit(inline=\"always\", nogil=True)")
        exec(compile(src, vk.__file__, "exec"), namespace)
    f = vk.vardiff_step.py_func
    glb = {**f.__globals__, "_bilinear": namespace["_bilinear"], "_bicubic": namespace["_bicubic"]}
    return numba.njit(**vk.STEP_OPTIONS)(types.FunctionType(f.__code__, glb, f.__name__, f.__defaults__))


@contextlib.contextmanager
def _refine_signed_indices() -> Iterator[None]:
    """Before the refinement's unclamped reads took unsigned indices and its step was compiled with the SLP
    vectorizer: signed indices, each with numba's wraparound of negative ones, and numba's default compilation (the
    same arithmetic)."""
    from flexvox_core.motion import vardiff_kernel as vk

    with mock.patch.object(vk, "vardiff_step", _signed_reads_step()):
        yield


@contextlib.contextmanager
def _refine_no_slp() -> Iterator[None]:
    """Before the refinement's step was compiled with LLVM's SLP vectorizer on: numba's default, off (the same
    arithmetic)."""
    from flexvox_core.motion import vardiff_kernel as vk

    step = _plain_step()
    with mock.patch.object(vk, "vardiff_step", step):
        yield


@contextlib.contextmanager
def _refine_serial_glue() -> Iterator[None]:
    """Before the refinement's glue ran on the threads: its input check (the float64 sum), the carried planes and
    the mask's and the classes' bands on the calling thread alone, one after another (the flow's planes side by
    side, in ``ScaledFlow.band_into``)."""
    from flexvox_core.motion import vardiff

    def serial(fn: Callable[[int], None], count: int) -> None:
        for i in range(count):
            fn(i)

    with mock.patch.object(vardiff, "for_each", serial):
        yield


@contextlib.contextmanager
def _refine_band_16() -> Iterator[None]:
    """Tried and not kept: the refinement's bands of 16 sub-frames (``vardiff.MIN_BAND``; 8 kept)."""
    from flexvox_core.motion import vardiff

    with mock.patch.object(vardiff, "MIN_BAND", 16):
        yield


@contextlib.contextmanager
def _refine_float64() -> Iterator[None]:
    """Before the refinement's step computed in float32: its step as it was
    (``tests/flexvox_core/motion/vardiff_float64.py``: float64 arithmetic, each read at a float64 position y + v, no FMA
    contraction), given the eigenvalues, the step and the still speed² as Python floats."""
    _repository_on_path()  # the tests' copy of the kernel, importable however the script is started
    from flexvox_core.motion import vardiff
    from flexvox_core.motion import vardiff_kernel as vk
    from tests.flexvox_core.motion import vardiff_float64

    def float64_step(c, dt, still2):
        return (*(float(v) for v in c), float(dt), float(still2))

    with mock.patch.object(vk, "vardiff_step", vardiff_float64.vardiff_step), \
            mock.patch.object(vardiff, "float32_step", float64_step):
        yield


@functools.cache
def _plain_step() -> Callable[..., None]:
    """``vardiff_step``'s source compiled as numba compiles by default, with the step's own options (compiled once a
    process)."""
    import numba

    from flexvox_core.motion import vardiff_kernel as vk

    return numba.njit(**vk.STEP_OPTIONS)(vk.vardiff_step.py_func)


@contextlib.contextmanager
def _refine_copied_ends() -> Iterator[None]:
    """Before the refinement's first step read its input and its last wrote the result themselves: each band's
    input copied into a buffer, the last step's planes copied out of one (the same bits)."""
    import inspect
    import textwrap

    from flexvox_core.motion import stages, vardiff

    src = textwrap.dedent(inspect.getsource(vardiff.variable_tensor_diffusion))
    kept_line = "direct = vol.flags.c_contiguous and (steps > 1 or not in_place)"
    assert kept_line in src, "the refinement's ends changed: update this variant"
    namespace = dict(vardiff.__dict__)
    exec(compile(src.replace(kept_line, "direct = False"), vardiff.__file__, "exec"), namespace)
    with mock.patch.object(stages, "variable_tensor_diffusion", namespace["variable_tensor_diffusion"]):
        yield


@contextlib.contextmanager
def _guides_whole() -> Iterator[None]:
    """Before nc finished its end sub-frames as their blurred mask was made and diffuse_where read the still voxels a
    band at a time: the ends' blurred mask held (each end's r + K sub-frames: before, its whole 2r + K and a copy of
    the period too), the still voxels unpacked into one bool volume for diffuse_where."""
    from flexvox_core import planes
    from flexvox_core.motion import stages
    from flexvox_core.reconstruct import diffusion

    kept_den, kept_where = diffusion._PeriodicDenominator, diffusion.diffuse_where

    def held(den_k: np.ndarray, F: int, gt: np.ndarray | None, ends: object = None) -> diffusion._PeriodicDenominator:
        return kept_den(den_k, F, gt)

    def whole_where(frames: np.ndarray, code: np.ndarray, out: np.ndarray, where: object,
                    **kw: Any) -> np.ndarray:
        return kept_where(frames, code, out, planes.band(where, 0, len(out)), **kw)

    diffusion._PeriodicDenominator = held  # type: ignore[assignment, misc]
    setattr(stages, "diffuse_where", whole_where)  # noqa: B010 - stages imports it: patched where it is read
    try:
        yield
    finally:
        diffusion._PeriodicDenominator = kept_den  # type: ignore[misc]
        setattr(stages, "diffuse_where", kept_where)  # noqa: B010


@contextlib.contextmanager
def _reach_by_log() -> Iterator[None]:
    """Before the trajectory gather counted each voxel's reach on a table of thresholds: ``own_reach``, two
    logarithms and a square root per voxel (an empty table; the same bits)."""
    from flexvox_core.motion import mcnc_kernel

    kept = mcnc_kernel.reach_thresholds
    mcnc_kernel.reach_thresholds = lambda reach: np.zeros(0, np.float32)
    try:
        yield
    finally:
        mcnc_kernel.reach_thresholds = kept


@contextlib.contextmanager
def _high_tr_float32() -> Iterator[None]:
    """Before the high-TR video was held in float16 from the flow on: float32 to the end (the later stages read
    its values unrounded; 147 MB more from the flow on at 640x480, 240 sub-frames)."""
    from flexvox_core.motion import stages

    kept = stages.HIGH_TR_HELD
    stages.HIGH_TR_HELD = np.float32
    try:
        yield
    finally:
        stages.HIGH_TR_HELD = kept


@contextlib.contextmanager
def _gather_reach_3_sigma() -> Iterator[None]:
    """Before motion-aware's trajectory gather reached 1.25 standard deviations of its trajectory Gaussian
    (``Window.gather_reach``): 3 of them, at least a sampling period (16 sub-frames at K = 16), each voxel up to
    its weight of ``CUTOFF``."""
    from flexvox_core.motion import stages
    from flexvox_core.motion.mcnc import default_reach

    def before(self: stages.Window) -> int:
        return default_reach(self.gather_time, self.gather_c[0], self.sampling_period, self.S)

    with mock.patch.object(stages.Window, "gather_reach", property(before)):
        yield


@contextlib.contextmanager
def _gate_numpy() -> Iterator[None]:
    """Before the gated flow's gate was one compiled pass per sub-frame: numpy's dozen element-wise passes, four
    ``np.hypot`` (about 9 ns an element) among them; the same bits."""
    import cv2

    from flexvox_core.flow.estimate import sanitize_flow
    from flexvox_core.motion import gated_flow
    from flexvox_core.motion.gated_flow_kernel import takes_slow

    def one(self: Any, t: int) -> None:
        px, use_slow, slow_below, lo, width, plo, pwidth = self.numbers
        vel = self.successive[t]
        slow = self.slow.at(t, np.empty_like(vel))
        speed = np.hypot(slow[..., 0], slow[..., 1]) * px
        if use_slow:
            use = takes_slow(speed, np.hypot(vel[..., 0], vel[..., 1]) * px, float(slow_below))
            vel = np.where(use[..., None], slow, vel)
        else:
            vel = vel.copy()
        h, w = vel.shape[:2]
        steps = cv2.resize(self.steps[t] * self.step_ratio, (w, h), interpolation=cv2.INTER_LINEAR)
        speed = np.maximum(speed, np.hypot(steps[..., 0], steps[..., 1]) * px)
        ramp = np.clip((speed - lo) / width, 0, 1).astype(np.float32)
        if self.mean is not None:
            mean = self.mean[t]
            ramp = np.maximum(ramp, np.clip((np.hypot(mean[..., 0], mean[..., 1]) * px - plo) / pwidth, 0, 1))
        vel *= ramp[..., None]
        self.successive[t], self.conf[t] = sanitize_flow(vel, self.conf[t], max_magnitude=float(self.max_magnitude))

    with mock.patch.object(gated_flow._GatedFlow, "one", one):
        yield


@contextlib.contextmanager
def _gate_scalar() -> Iterator[None]:
    """Before the gated flow's gate was vector code: one scalar compiled loop a pixel, four float64 square roots in
    it, the flags and the cap branches (``tests/flexvox_core/motion/gate_scalar_reference.py``), and the
    confidences' range checked after it by numpy's min and max; the same bits."""
    _repository_on_path()
    from flexvox_core.motion import gated_flow
    from tests.flexvox_core.motion.gate_scalar_reference import gate_plane_scalar

    def gate_plane(vel: Any, conf: Any, *args: Any) -> bool:
        gate_plane_scalar(vel, conf, *args)
        return bool(conf.size and not (np.min(conf) >= 0 and np.max(conf) <= 1))

    with mock.patch.object(gated_flow, "gate_plane", gate_plane):
        yield


@contextlib.contextmanager
def _flow_mean_numpy() -> Iterator[None]:
    """Before the successive-sub-frame flow's temporal mean was a compiled pass per sub-frame on every core: a
    numpy loop over the sub-frames on one thread; the same bits."""
    from flexvox_core.flow import estimate

    def pair_mean(fwd: np.ndarray, conf: np.ndarray, c: int, reach: int, out: np.ndarray) -> None:
        P = len(conf)
        num, den = np.zeros(out.shape, np.float32), np.zeros(out.shape[:2], np.float32)
        for o in range(-reach, reach + 1):
            if max(0, -o) <= c < P - max(0, o):
                num += fwd[c + o] * (conf[c + o] + np.float32(1e-3))[..., None]  # weighed as read: the same bits
                den += conf[c + o] + np.float32(1e-3)
        np.divide(num, den[..., None], out=out)

    kept = estimate.for_each

    def serial_mean(fn: Callable[[int], None], count: int) -> None:  # the mean's loop on one thread, as it was
        if not fn.__qualname__.startswith("successive_flow."):
            kept(fn, count)
            return
        for i in range(count):
            fn(i)

    with mock.patch.object(estimate, "pair_mean", pair_mean), mock.patch.object(estimate, "for_each", serial_mean):
        yield


@contextlib.contextmanager
def _flow_plumbing_before() -> Iterator[None]:
    """Before three changes to the gated flow's plumbing, the same bits: its moving averages in time (its period
    mean, the K-average) were SciPy's ``uniform_filter1d`` a band of rows per task, not a compiled running box over
    bands of columns; the detector's steps were scaled by numpy's broadcast over a last axis of 2; and each pair's
    :func:`~flexvox_core.flow.estimate.sanitize_flow` checked its values from a float64 sum and clipped a
    confidence it made."""
    _repository_on_path()  # the tests' reference, importable however the script is started
    from flexvox_core.flow import baseline, estimate
    from flexvox_core.motion import gated_flow
    from tests.flexvox_core.flow.sanitize_reference import sanitize_reference as sanitize_flow

    def box_in_time(video: np.ndarray, size: int) -> np.ndarray:
        return baseline.box_in_time_scipy(video, size)

    def scaled_vectors(plane: np.ndarray, ratio: np.ndarray) -> np.ndarray:
        return plane * ratio

    with mock.patch.object(baseline, "box_in_time", box_in_time), \
            mock.patch.object(gated_flow, "box_in_time", box_in_time), \
            mock.patch.object(gated_flow, "scaled_vectors", scaled_vectors), \
            mock.patch.object(estimate, "sanitize_flow", sanitize_flow):
        yield


@contextlib.contextmanager
def _classes_numpy() -> Iterator[None]:
    """Before the speed classes were classified per voxel into their packed bits (compiled): numpy's rule on the
    whole plane, then ``np.packbits`` of each class; the same bits."""
    from flexvox_core.motion import stages
    from flexvox_core.motion.classes_kernel import speed_class

    def classify_plane(speed: np.ndarray, still_below: Any, slow_below: Any, skipped: bool,
                       *rows: np.ndarray) -> tuple[int, ...]:
        classes = speed_class(speed, still_below, slow_below, skipped)
        for row, cls in zip(rows, classes, strict=True):
            row[...] = np.packbits(cls, axis=-1)
        return tuple(int(np.count_nonzero(cls)) for cls in classes)

    with mock.patch.object(stages, "classify_plane", classify_plane):
        yield


@contextlib.contextmanager
def _detector_finest_2() -> Iterator[None]:
    """A change tried and not kept: the motion detector's DIS searching no finer than pyramid level 2 (the kept
    code: level 1, OpenCV's "medium" preset, as the successive flow)."""
    from flexvox_core.motion import gated_flow

    with mock.patch.object(gated_flow, "DETECTOR_DIS_PARAMS", {**gated_flow.DIS_PARAMS, "finest_scale": 2}):
        yield


@contextlib.contextmanager
def _vectors_by_numpy() -> Iterator[None]:
    """Before the held flow's vectors were scaled by OpenCV: numpy's product over the last axis of 2 (the same
    bits, 0.2-0.4 ms a plane; every stage that reads the flow makes its full-size planes so)."""
    from flexvox_core.flow import estimate

    kept = estimate.scaled_vectors
    estimate.scaled_vectors = lambda plane, ratio: plane * ratio
    try:
        yield
    finally:
        estimate.scaled_vectors = kept


@contextlib.contextmanager
def _choice_whole_rows() -> Iterator[None]:
    """Before oriented nc made each sub-frame's structure tensor and time blur over bands of rows and the columns
    holding wanted voxels: one block, from the first wanted row to the last, every column (the same bits)."""
    from flexvox_core.reconstruct import oriented_nc

    def whole_rows(wanted):
        rows = np.flatnonzero(wanted.any(axis=1))
        return [(int(rows[0]), int(rows[-1]) + 1, 0, wanted.shape[1])] if len(rows) else []

    with mock.patch.object(oriented_nc, "_blocks", whole_rows):
        yield


@contextlib.contextmanager
def _choice_opencv_tensor() -> Iterator[None]:
    """Before oriented nc's structure tensor was one compiled kernel: OpenCV's filters, a pass each (the blur,
    two Sobels, three products and three blurs), per block (``oriented_reference.structure_opencv``)."""
    from flexvox_core.reconstruct import oriented_nc_kernel
    _repository_on_path()  # the tests' reference, importable however the script is started
    from tests.flexvox_core.reconstruct.oriented_reference import structure_opencv

    def by_opencv(g: np.ndarray, kp: np.ndarray, kq: np.ndarray, j: np.ndarray, b0: int, a0: int) -> None:
        j[:, b0:b0 + g.shape[0], a0:a0 + g.shape[1]] = structure_opencv(g)

    with mock.patch.object(oriented_nc_kernel, "structure_block", by_opencv):
        yield


def _choice_per_band(oriented: Callable[..., Any]) -> Callable[..., None]:
    """The local choice's stage as it was before its bands shared one :class:`OrientedNc`: ``oriented`` (an
    ``oriented_nc``) called per band with the whole gathered volume and the video as the fallback, which checked its
    inputs again (the frames' values, the band's guide), made the bank and the time weights, unpacked the band's
    gathered voxels on the calling thread (twice: the stage's test and oriented nc's) and copied the fallback whole
    into each sub-frame."""
    from flexvox_core.motion import local_choice
    from flexvox_core.motion.stages import workers
    from flexvox_core.planes import band

    def stage(self: Any, video: np.ndarray, loo: np.ndarray, gathered: Any, flow: Any, high_tr: np.ndarray) -> None:
        w = self.window
        if not np.isfinite(loo).any():
            return
        if w.scores_still_voxels:
            local_choice.still_voxel_loo(loo, video, w.frames, gathered, self._mask(),
                                         flow if hasattr(flow, "band") else flow.flow, w.K)
        frames = np.ascontiguousarray(w.frames, np.float32)
        F, H, W = frames.shape
        per_band = max(1, -(-max(local_choice.BAND, 2 * workers()) // w.K))
        other = np.empty((min(F, per_band) * w.K, H, W), np.float32)
        other_loo = np.full(w.frames.shape, np.nan, np.float32)
        workspace: list[Any] = []
        for f0 in range(0, F, per_band):
            f1 = min(F, f0 + per_band)
            s0, s1 = f0 * w.K, f1 * w.K
            where = band(gathered, s0, s1)
            if not where.any():
                continue
            got, _ = oriented(frames, w.code, high_tr, where=gathered, fallback=video, missing=w.missing,
                              out=other[:s1 - s0], subframes=(s0, s1), loo=other_loo, workspace=workspace)
            weights = local_choice.local_weights(loo[f0:f1], other_loo[f0:f1], frames[f0:f1])
            local_choice.blend(video[s0:s1], got, weights, where, w.K)

    return stage


@contextlib.contextmanager
def _choice_bands_apart() -> Iterator[None]:
    """Before the local choice's bands shared one oriented nc (``OrientedNc``: its checks and constants made once,
    the gathered voxels unpacked a sub-frame a task, no fallback copied into oriented nc's planes): an
    ``oriented_nc`` call per band (:func:`_choice_per_band`; the same bits)."""
    from flexvox_core.motion import stages
    from flexvox_core.reconstruct.oriented_nc import oriented_nc

    with mock.patch.object(stages.CpuStages, "local_choice", _choice_per_band(oriented_nc)):
        yield


@contextlib.contextmanager
def _choice_blocks_numpy() -> Iterator[None]:
    """Before oriented nc found its blocks by a compiled row scan and made the float16 guide's blocks float32 through
    OpenCV: numpy's ``any`` along and across the rows of each band, numpy's conversion (the same bits)."""
    from flexvox_core.reconstruct import oriented_nc

    def blocks_numpy(wanted: np.ndarray) -> list[tuple[int, int, int, int]]:
        W = wanted.shape[1]
        rows = wanted.any(axis=1)
        out: list[tuple[int, int, int, int]] = []
        for r0 in range(0, wanted.shape[0], oriented_nc.BLOCK_ROWS):
            ys = np.flatnonzero(rows[r0:r0 + oriented_nc.BLOCK_ROWS])
            if not len(ys):
                continue
            y0, y1 = r0 + int(ys[0]), r0 + int(ys[-1]) + 1
            xs = np.flatnonzero(wanted[y0:y1].any(axis=0))
            x0, x1 = int(xs[0]), int(xs[-1]) + 1
            if out and oriented_nc._aligned_columns(*out[-1][2:], W) == oriented_nc._aligned_columns(x0, x1, W):
                p0, _, p2, p3 = out[-1]
                out[-1] = (p0, y1, min(p2, x0), max(p3, x1))
            else:
                out.append((y0, y1, x0, x1))
        return out

    with mock.patch.object(oriented_nc, "_blocks", blocks_numpy), \
            mock.patch.object(oriented_nc, "_as_float32", lambda block: np.ascontiguousarray(block, np.float32)):
        yield


@contextlib.contextmanager
def _choice_glue_before() -> Iterator[None]:
    """The local choice's glue before this round: ``choice-bands-apart`` and ``choice-blocks-numpy`` together."""
    with _choice_bands_apart(), _choice_blocks_numpy():
        yield


@contextlib.contextmanager
def _choice_float64() -> Iterator[None]:
    """Before oriented nc's kernel and its structure tensor were float32 vector code: the float64 kernel (its taps
    listed per kernel and summed in a fixed order, the kernels' choice per voxel with branches, the time blur per
    pixel) and OpenCV's tensor (``tests/flexvox_core/reconstruct/oriented_float64.py``), called per band as then
    (:func:`_choice_per_band`)."""
    from flexvox_core.motion import stages
    _repository_on_path()  # the tests' copy of the kernel, importable however the script is started
    from tests.flexvox_core.reconstruct.oriented_float64 import oriented_nc_float64

    with mock.patch.object(stages.CpuStages, "local_choice", _choice_per_band(oriented_nc_float64)):
        yield


@contextlib.contextmanager
def _weighed_apart(weigh_pairs: Callable[[np.ndarray, np.ndarray], None]) -> Iterator[None]:
    """The successive flow's pairs weighted by ``weigh_pairs(fwd, conf)`` in place once DIS has run, and its mean the
    scalar loop over those weighted flows (``tests/flexvox_core/flow/mean_scalar_reference.py``): as before the mean
    weighed the flows as it read them; the same bits."""
    _repository_on_path()
    from flexvox_core.flow import estimate
    from tests.flexvox_core.flow.mean_scalar_reference import pair_mean_scalar

    run_pairs = estimate.run_pairs

    def run_and_weigh(flow_fn: Any, u8: np.ndarray, pairs: Any, out: np.ndarray, conf: np.ndarray,
                      **kwargs: Any) -> None:
        run_pairs(flow_fn, u8, pairs, out, conf, **kwargs)
        weigh_pairs(out, conf)

    with mock.patch.object(estimate, "run_pairs", run_and_weigh), \
            mock.patch.object(estimate, "pair_mean", pair_mean_scalar):
        yield


@contextlib.contextmanager
def _flow_mean_unfused() -> Iterator[None]:
    """Before the successive flow's mean weighed the flows as it read them and ran as vector code: a pass that
    weighted the pairs in place (a pair per task on every core), then the scalar loop a pixel; the same bits."""
    from flexvox_core.flow.estimate import for_each

    def weigh_pairs(fwd: np.ndarray, conf: np.ndarray) -> None:
        eps = np.float32(1e-3)

        def one(i: int) -> None:
            fwd[i] *= (conf[i] + eps)[..., None]

        for_each(one, len(fwd))

    with _weighed_apart(weigh_pairs):
        yield


@contextlib.contextmanager
def _flow_glue_serial() -> Iterator[None]:
    """Before the gated flow's steps between its DIS pairs ran on every core: the videos taken to uint8, the
    K-average and the period gate's box in time, the pairs' weighting (a pass of its own before the scalar mean, as
    then: ``_weighed_apart``), the video's check and the high-TR held in float16, each a whole-volume numpy (or
    SciPy) call on one thread; the same bits."""
    from scipy.ndimage import uniform_filter1d

    from flexvox_core.flow import baseline, estimate
    from flexvox_core.motion import gated_flow, stages

    def sums_finite(v: np.ndarray) -> bool:
        with np.errstate(over="ignore"):
            return bool(np.isfinite(v.sum(dtype=np.float64)))

    def weigh_pairs(fwd: np.ndarray, conf: np.ndarray) -> None:
        fwd *= (conf + np.float32(1e-3))[..., None]

    def box_in_time(video: np.ndarray, size: int) -> np.ndarray:
        return uniform_filter1d(video, size, axis=0, mode="nearest")

    with mock.patch.object(estimate, "to_uint8_planes", estimate.to_uint8), \
            mock.patch.object(baseline, "to_uint8_planes", estimate.to_uint8), \
            mock.patch.object(estimate, "subframe_sums_finite", sums_finite), \
            _weighed_apart(weigh_pairs), \
            mock.patch.object(baseline, "box_in_time", box_in_time), \
            mock.patch.object(gated_flow, "box_in_time", box_in_time), \
            mock.patch.object(stages, "held_as", lambda volume, dtype: volume.astype(dtype)):
        yield


@contextlib.contextmanager
def _gather_finish_numpy() -> Iterator[None]:
    """Before the trajectory gather's last steps on a box were compiled (``mcnc_kernel.divide_box``) and its
    samples written by slices: numpy's leave-one-out at the samples' indices, N / D, the fallback converted over
    the box and taken where the weight is small, and the samples copied where the mask is (the same bits)."""
    from flexvox_core.motion import mcnc
    _repository_on_path()  # the tests' reference, importable however the script is started
    from tests.flexvox_core.motion.finish_reference import finish

    def numpy_finish(t, box, inside, planes, samples_of, wide, wide_sigma, sig_space, fallback, loo_f, out):
        g = mcnc._blur_box(t, box, planes, wide, wide_sigma, sig_space)
        m_t, vals_t = samples_of(t) if loo_f is not None else (None, None)
        finish(planes, inside, None if m_t is None else m_t[box], None if vals_t is None else vals_t[box], sig_space,
               g, wide_sigma, None if fallback is None else fallback[t][box], None if loo_f is None else loo_f[box],
               out[t][box])

    kept = mcnc._gather

    def masked_samples(*args, keep_samples, **kwargs):
        return kept(*args, keep_samples=bool(keep_samples), **kwargs)

    with mock.patch.object(mcnc, "_finish", numpy_finish), mock.patch.object(mcnc, "_gather", masked_samples):
        yield


@contextlib.contextmanager
def _choice_serial() -> Iterator[None]:
    """Before the local choice's serial parts were compiled and ran on every core: the blend and the weights in numpy
    on one thread (a sub-frame, a frame at a time), and oriented nc's guide checked a band at a time by a float64
    sum (the same bits; each band's copy of the fallback stays on the threads)."""
    from flexvox_core.motion import local_choice
    from flexvox_core.reconstruct import oriented_nc

    def not_finite(guide, s0, s1):  # a band at a time, one pass (no boolean volume), on one thread
        if np.isfinite(guide[s0:s1].sum(dtype=np.float64)):
            return np.zeros(s1 - s0, bool)
        return np.array([not np.isfinite(guide[s]).all() for s in range(s0, s1)])

    def weights(loo_a, loo_b, samples):
        return local_choice.local_weights_numpy(loo_a, loo_b, samples, power=local_choice.POWER,
                                                sigma=local_choice.pooling_sigma(*np.shape(samples)[1:]))

    with mock.patch.object(local_choice, "blend", local_choice.blend_numpy), \
            mock.patch.object(local_choice, "local_weights", weights), \
            mock.patch.object(oriented_nc, "_not_finite", not_finite):
        yield


@contextlib.contextmanager
def _choice_before() -> Iterator[None]:
    """The local choice before this round's changes to it: ``choice-whole-rows`` and ``choice-serial`` together."""
    with _choice_whole_rows(), _choice_serial():
        yield


@contextlib.contextmanager
def _gather_reads_clamped() -> Iterator[None]:
    """Before the trajectory gather's kernel read the cells wholly in the picture without clamping: every read's
    rows and columns clamped, a voxel at a time (``tests/flexvox_core/motion/lattice_reference.py`` compiles that
    kernel from its own source; the same bits)."""
    from flexvox_core.motion import mcnc_kernel
    _repository_on_path()
    from tests.flexvox_core.motion.lattice_reference import clamped_lattice_sums

    with mock.patch.object(mcnc_kernel, "lattice_sums", clamped_lattice_sums()):
        yield


@contextlib.contextmanager
def _gather_by_voxel() -> Iterator[None]:
    """Before the trajectory gather's kernel ran a row's voxels as a list with the offsets outside it: a voxel at a
    time, its offsets inside its loop, numba's ``math.exp`` (``tests/flexvox_core/motion/lattice_reference.py``;
    the bits of ``gather-exp-libm``)."""
    from flexvox_core.motion import mcnc_kernel
    _repository_on_path()
    from tests.flexvox_core.motion.lattice_reference import lattice_sums_by_voxel

    with mock.patch.object(mcnc_kernel, "lattice_sums", lattice_sums_by_voxel):
        yield


@contextlib.contextmanager
def _gather_exp_libm() -> Iterator[None]:
    """Before the trajectory gather's kernel took its exp by ``exp_kernel.exp32`` in a vectorized pass: numba's
    ``math.exp`` per voxel (``tests/flexvox_core/motion/lattice_reference.py`` compiles it from the module's
    source)."""
    from flexvox_core.motion import mcnc_kernel
    _repository_on_path()
    from tests.flexvox_core.motion.lattice_reference import rows_with_libm_exp

    with mock.patch.object(mcnc_kernel, "lattice_sums", rows_with_libm_exp()):
        yield


@contextlib.contextmanager
def _half_by_numpy() -> Iterator[None]:
    """Before the high-TR video was taken to float16 by OpenCV (the CPU's conversion instructions): numpy's
    conversion, a sub-frame at a time on every core; the same bits."""
    from flexvox_core.motion import stages

    def held_as(volume: np.ndarray, dtype: Any) -> np.ndarray:
        out = np.empty(volume.shape, dtype)

        def one(t: int) -> None:
            out[t] = volume[t]

        stages.for_each(one, len(volume))
        return out

    with mock.patch.object(stages, "held_as", held_as):
        yield


@contextlib.contextmanager
def _long_reach_scalar() -> Iterator[None]:
    """Before the long reach's reads ran branch-free over a row's voxels (vectorized, float32 residues, the held
    pixel as the sample, ``exp32``): every tile on the scalar reads (``_row_sums``: the corner table, a branch per
    read, n/d, math.exp), the code before bit for bit."""
    from flexvox_core.motion import longreach_kernel as lk

    kept = lk._lattice

    def scalar(*args: Any) -> tuple[Any, ...]:
        return (*kept(*args)[:-1], False)

    with mock.patch.object(lk, "_lattice", scalar):
        yield


@contextlib.contextmanager
def _nc_finish_numpy() -> Iterator[None]:
    """Before nc finished a sub-frame in one compiled pass (``nc_time_kernel.finish_plane``): numpy's compare, any,
    divide, clip and masked copy of the samples (``diffusion._finish_numpy``, the same bits; the ends' samples by a
    masked copy per band of columns, before a second pass per end sub-frame)."""
    from flexvox_core.reconstruct import diffusion

    with mock.patch.object(diffusion, "_finish_plane", diffusion._finish_numpy):
        yield


@contextlib.contextmanager
def _nc_blur_apart() -> Iterator[None]:
    """Before nc's general path blurred each interior sub-frame's numerator in space just before finishing it: every
    sub-frame blurred in a pass of its own first (beside the mask's planes and slots, on the threads as kept; before
    the change those were made on the main thread); the same bits."""
    from flexvox_core.reconstruct import diffusion

    with mock.patch.object(diffusion, "_BLUR_AT_FINISH", False):
        yield


@contextlib.contextmanager
def _where_by_bands() -> Iterator[None]:
    """Before ``diffuse_where`` read the still voxels' packed bits in its compiled time pass: the selection unpacked
    on the main thread SELECT_BAND sub-frames at a time, a pass of the kernel per band; the same bits."""
    from flexvox_core.motion import stages

    kept = stages.diffuse_where

    class Bands:
        def __init__(self, held: Any) -> None:
            self.shape, self.band = held.shape, held.band

    def by_bands(frames: Any, code: Any, out: Any, where: Any, **kw: Any) -> Any:
        return kept(frames, code, out, Bands(where) if hasattr(where, "packed") else where, **kw)

    with mock.patch.object(stages, "diffuse_where", by_bands):
        yield


@contextlib.contextmanager
def _flow_full_planes() -> Iterator[None]:
    """Before the long reach read a flow held small at its voxels (``ScaledFlow.scaled``):
    each sub-frame's full-size plane made by ``cv2.resize`` and read; the same bits."""
    from flexvox_core.flow.estimate import ScaledFlow

    with mock.patch.object(ScaledFlow, "scaled", lambda self, t: None):
        yield


VARIANTS: dict[str, Callable[[], contextlib.AbstractContextManager[None]]] = {
    "kept": contextlib.nullcontext,
    "flow-full-planes": _flow_full_planes,
    "remap-gather": _gather_by_remap,
    "scratch-volume": _scratch_volume,
    "long-reach-remap": _long_reach_on_sample_planes,
    "refine-halo-bands": _refine_halo_bands,
    "refine-moving-still": _refine_moving_still,
    "refine-clamped-reads": _refine_clamped_reads,
    "refine-copied-ends": _refine_copied_ends,
    "refine-signed-indices": _refine_signed_indices,
    "refine-no-slp": _refine_no_slp,
    "refine-float64": _refine_float64,
    "refine-serial-glue": _refine_serial_glue,
    "refine-band-16": _refine_band_16,
    "guides-whole": _guides_whole,
    "reach-by-log": _reach_by_log,
    "high-tr-float32": _high_tr_float32,
    "gather-reach-3-sigma": _gather_reach_3_sigma,
    "gate-numpy": _gate_numpy,
    "gate-scalar": _gate_scalar,
    "flow-mean-numpy": _flow_mean_numpy,
    "flow-mean-unfused": _flow_mean_unfused,
    "classes-numpy": _classes_numpy,
    "flow-plumbing-before": _flow_plumbing_before,
    "detector-finest-2": _detector_finest_2,
    "vectors-by-numpy": _vectors_by_numpy,
    "choice-whole-rows": _choice_whole_rows,
    "choice-serial": _choice_serial,
    "choice-before": _choice_before,
    "choice-float64": _choice_float64,
    "choice-opencv-tensor": _choice_opencv_tensor,
    "choice-bands-apart": _choice_bands_apart,
    "choice-blocks-numpy": _choice_blocks_numpy,
    "choice-glue-before": _choice_glue_before,
    "gather-finish-numpy": _gather_finish_numpy,
    "gather-reads-clamped": _gather_reads_clamped,
    "gather-by-voxel": _gather_by_voxel,
    "gather-exp-libm": _gather_exp_libm,
    "flow-glue-serial": _flow_glue_serial,
    "half-by-numpy": _half_by_numpy,
    "long-reach-scalar": _long_reach_scalar,
    "nc-finish-numpy": _nc_finish_numpy,
    "nc-blur-apart": _nc_blur_apart,
    "where-by-bands": _where_by_bands,
}
"""The code as it was before each change (``kept``: as it is), or a change tried and not kept, for ``--ab``."""


def _status_mb(field: str) -> float:
    """A field of /proc/self/status (VmRSS, VmHWM) in MB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024
    raise LookupError(field)


def _child(variant: str, frames_path: str, extra: dict) -> None:
    """Print the peak resident memory of one cold ``motion_aware`` call of ``variant`` (MB), and the rise over
    the resident memory before the call (the frames loaded and the code compiled)."""
    code = design_code((4, 4)).code
    frames = np.load(frames_path)
    motion_aware(frames[:2, :16, :16], code)  # load and compile what the call needs, on a tiny clip (two frames:
    # one frame takes no long reach)
    try:  # the peak so far (after fork a child's starts at its parent's): reset to the current resident size
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        before = _status_mb("VmRSS")
        with VARIANTS[variant]():
            motion_aware(frames, code, **extra)
        peak = _status_mb("VmHWM")
    except OSError:  # not Linux, or no clear_refs: the process's peak, the parent's included
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        with VARIANTS[variant]():
            motion_aware(frames, code, **extra)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"peak_mb": peak, "above_mb": peak - before}))


@contextlib.contextmanager
def _stage_memory(table: dict[str, list[float]]) -> Iterator[None]:
    """Record (start, peak, end) resident MB of every stage ``run_stages`` times into ``table`` (the peak reset at
    each stage's start; summed stages keep their first start, highest peak and last end)."""
    from flexvox_core.motion import stages

    kept = stages.StageTimes.__call__

    @contextlib.contextmanager
    def measured(self, stage: str) -> Iterator[None]:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        start = _status_mb("VmRSS")
        with kept(self, stage):
            yield
        peak, end = _status_mb("VmHWM"), _status_mb("VmRSS")
        if stage in table:
            start, peak = table[stage][0], max(peak, table[stage][1])
        table[stage] = [start, peak, end]

    with mock.patch.object(stages.StageTimes, "__call__", measured):
        yield


def _memory_child(variant: str, frames_path: str, extra: dict) -> None:
    """Print each stage's (start, peak, end) resident MB in one cold ``motion_aware`` call of ``variant``."""
    code = design_code((4, 4)).code
    frames = np.load(frames_path)
    motion_aware(frames[:2, :16, :16], code)  # two frames: one takes no long reach
    table: dict[str, list[float]] = {}
    before = _status_mb("VmRSS")
    with VARIANTS[variant](), _stage_memory(table):
        motion_aware(frames, code, **extra)
    print(json.dumps({"before_mb": before, "stages": table}))


def _memory(args, extra: dict) -> None:
    code = design_code((4, 4)).code
    variants = ["kept"] if args.memory == "kept" else ["kept", args.memory]
    for scene in args.scenes.split(","):
        frames = capture(render_scene(scene, args.frames * 16, 480, 640), code)
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "frames.npy")
            np.save(path, frames)
            for v in variants:
                out = subprocess.run([sys.executable, __file__, scene, "--frames", str(args.frames),
                                      "--memory-child", v, path, "--extra", json.dumps(extra)],
                                     capture_output=True, text=True, check=True).stdout
                got = json.loads(out.strip().splitlines()[-1])
                table = got["stages"]
                peak = max(r[1] for r in table.values())
                print(f"\n{scene}, 640x480, {args.frames} frames, {v}: resident MB at each stage's start / its peak "
                      f"within it / its end (before the call {got['before_mb']:.0f}; the call's peak {peak:.0f})")
                print("| stage | " + " | ".join(table) + " |")
                print("|---" * (len(table) + 1) + "|")
                print("| start / peak / end | " + " | ".join(
                    " / ".join(f"{x:.0f}" for x in r) for r in table.values()) + " |", flush=True)


MOVING = ("fan", "balls", "drummer", "pan", "static", "strobe")
"""The built-in scenes (``static`` holds a moving part too) ``--quality`` runs."""


def _quality(args, extra: dict) -> None:
    code = design_code((4, 4)).code
    H, W = (int(v) for v in (args.size or "240x320").split("x"))
    noise = 0.01 if args.noise is None else args.noise
    print(f"\nkept against {args.quality}, {H}x{W}, {args.frames} frames, PSNR dB (kept / {args.quality} / "
          f"difference); noisy: sigma {noise}")
    print("| scene | clean | noisy |")
    print("|---|---|---|")
    worst = 0.0
    for scene in MOVING:
        truth = render_scene(scene, args.frames * 16, H, W)
        clean = capture(truth, code)
        noisy = np.clip(clean + np.random.default_rng(0).normal(0, noise, clean.shape), 0, 1).astype(np.float32)
        cells = []
        for frames in (clean, noisy):
            got = []
            for v in ("kept", args.quality):
                with VARIANTS[v]():
                    got.append(psnr(truth, motion_aware(frames, code, **extra).video))
            diff = 0.0 if got[0] == got[1] else got[0] - got[1]  # both inf: an exact reconstruction
            worst = max(worst, abs(diff))
            cells.append(f"{got[0]:.3f} / {got[1]:.3f} / {diff:+.3f}")
        print(f"| {scene} | " + " | ".join(cells) + " |", flush=True)
    print(f"largest |difference|: {worst:.3f} dB")


def _ab(args, extra: dict) -> None:
    code = design_code((4, 4)).code
    variants = ["kept", args.ab]
    H, W = (int(v) for v in (args.size or "480x640").split("x"))
    for scene in args.scenes.split(","):
        truth = render_scene(scene, args.frames * 16, H, W)
        frames = capture(truth, code)
        if args.noise:
            frames = (frames + np.random.default_rng(0).normal(0, args.noise, frames.shape)).astype(np.float32)
        rows: dict[str, list[tuple[dict, float, float]]] = {v: [] for v in variants}
        for v in variants:  # warm-up: numba's compilation and the first touch of the process's memory
            with VARIANTS[v]():
                motion_aware(frames, code, **extra)
        for _ in range(args.rounds):
            for v in variants:
                with VARIANTS[v]():
                    t0 = time.perf_counter()
                    result = motion_aware(frames, code, **extra)
                    total = time.perf_counter() - t0
                rows[v].append((result.stage_seconds, total, psnr(truth, result.video)))
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "frames.npy")
            np.save(path, frames)
            peaks = {}
            for v in variants:
                out = subprocess.run([sys.executable, __file__, scene, "--frames", str(args.frames),
                                      "--child", v, path, "--extra", json.dumps(extra)],
                                     capture_output=True, text=True, check=True).stdout
                peaks[v] = json.loads(out.strip().splitlines()[-1])
        stages = list(rows["kept"][0][0])
        print(f"\n{scene}, {W}x{H}, noise {args.noise or 0}, {args.frames} frames, {args.rounds} rounds alternating, "
              f"load "
              f"{os.getloadavg()[0]:.1f} (1-min average at the end); medians, s")
        print("| variant | " + " | ".join(stages) + " | total | PSNR dB | peak MB (above the warm process) |")
        print("|---" * (len(stages) + 4) + "|")
        for v in variants:
            med = [statistics.median(r[0].get(k, 0.0) for r in rows[v]) for k in stages]
            total = statistics.median(r[1] for r in rows[v])
            print(f"| {v} | " + " | ".join(f"{m:.2f}" for m in med) + f" | {total:.2f} | {rows[v][0][2]:.3f} "
                  f"| {peaks[v]['peak_mb']:.0f} ({peaks[v]['above_mb']:.0f}) |")
        print("runs, total s: " + "; ".join(f"{v} " + ", ".join(f"{r[1]:.2f}" for r in rows[v]) for v in variants))
        print(f"runs, {args.focus} s: " + "; ".join(
            f"{v} " + ", ".join(f"{r[0].get(args.focus, 0.0):.2f}" for r in rows[v]) for v in variants), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="?", default="balls,drummer")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--flow-scale", type=float, default=None, help="default: auto (shorter side 160 px)")
    ap.add_argument("--refine", type=float, default=None,
                    help="refinement time (default: motion_aware's, (K/16)²; 0: none, as before it was the default)")
    ap.add_argument("--no-local-choice", action="store_true",
                    help="the trajectory gather alone, without blending in isotropic nc (motion_aware's local_choice)")
    ap.add_argument("--slow-reach", type=float, default=None,
                    help="slow voxels' reach in sampling periods (default: motion_aware's, 0.75; 0: short gather)")
    ap.add_argument("--ab", choices=[v for v in VARIANTS if v != "kept"], default=None,
                    help="the kept code against this variant, alternating in one process, per stage, with peak memory")
    ap.add_argument("--rounds", type=int, default=3, help="--ab's runs of each")
    ap.add_argument("--size", default=None, help="HxW of --ab's clip (default 480x640) and --quality's (240x320)")
    ap.add_argument("--noise", type=float, default=None,
                    help="σ of Gaussian noise added to --ab's frames (default none) and --quality's noisy ones (0.01)")
    ap.add_argument("--focus", default="trajectory_gather", help="--ab: the stage whose every run is printed too")
    ap.add_argument("--quality", choices=[v for v in VARIANTS if v != "kept"], default=None,
                    help="the kept code's PSNR against this variant's on every moving built-in scene, clean and noisy")
    ap.add_argument("--memory", nargs="?", const="kept", default=None, choices=list(VARIANTS),
                    help="each stage's resident memory (start, peak, end) in one cold call in a child process; "
                         "with a VARIANT, that variant's too")
    ap.add_argument("--memory-child", nargs=2, metavar=("VARIANT", "FRAMES"), help=argparse.SUPPRESS)
    ap.add_argument("--child", nargs=2, metavar=("VARIANT", "FRAMES"), help=argparse.SUPPRESS)
    ap.add_argument("--extra", default="{}", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        _child(args.child[0], args.child[1], json.loads(args.extra))
        return
    if args.memory_child:
        _memory_child(args.memory_child[0], args.memory_child[1], json.loads(args.extra))
        return
    if args.ab or args.memory or args.quality:
        ab_extra: dict = {"flow_scale": args.flow_scale}
        if args.slow_reach is not None:
            ab_extra["slow_reach"] = args.slow_reach
        if args.refine is not None:
            ab_extra["refine_time"] = args.refine
        if args.no_local_choice:
            ab_extra["local_choice"] = False
        if args.quality:
            _quality(args, ab_extra)
        if args.memory:
            _memory(args, ab_extra)
        if args.ab:
            _ab(args, ab_extra)
        return
    code = design_code((4, 4)).code
    scale = args.flow_scale or 'auto'
    reach = "default" if args.slow_reach is None else args.slow_reach
    print(f"640x480, K = 16, {args.frames} frames ({args.frames * 16} sub-frames), flow scale {scale}, "
          f"slow reach {reach}{', no local choice' if args.no_local_choice else ''}")
    print("| scene | motion-aware s | high-TR / flow / diffusion s | M voxels/s (÷ 5, ÷ 15) | PSNR dB "
          "| fixed nc s | fixed PSNR dB | time ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes.split(","):
        truth = render_scene(scene, args.frames * 16, 480, 640)
        frames = capture(truth, code)
        t0 = time.perf_counter()
        fixed = diffuse(frames, code, tensor=(0.05, 0.05, 1.0), time=4.0)
        t_fixed = time.perf_counter() - t0
        t0 = time.perf_counter()
        extra = {} if args.slow_reach is None else {"slow_reach": args.slow_reach}
        if args.refine is not None:
            extra["refine_time"] = args.refine
        if args.no_local_choice:
            extra["local_choice"] = False
        result = motion_aware(frames, code, flow_scale=args.flow_scale, **extra)
        t_ma = time.perf_counter() - t0
        sec = result.seconds
        rate = truth.size / t_ma / 1e6  # M voxels/s
        print(f"| {scene} | {t_ma:.1f} | {sec['high_tr']:.1f} / {sec['flow']:.1f} / {sec['diffusion']:.1f} "
              f"| {rate:.2f} ({rate / 5:.2f}, {rate / 15:.2f}) | {psnr(truth, result.video):.2f} | {t_fixed:.2f} "
              f"| {psnr(truth, fixed):.2f} | {t_ma / t_fixed:.0f}x |", flush=True)


if __name__ == "__main__":
    main()
