"""The gated flow and the speed classes on the GPU.

:func:`gated_flow` is :func:`flexvox_core.motion.gated_flow.gated_flow` on device arrays: the high-TR video
shrunk to the flow's size (``INTER_AREA``), its successive-sub-frame flow averaged over ±1 pair, the K-average's
flow across K sub-frames every K/4 (linear in time between), the motion detector's flow between successive
sub-frames of the K-average at half that size, the period gate's average over K sub-frames, the gate itself
(one thread per flow pixel and sub-frame) and the resize to full size. The pairs' optical flow is DIS on the GPU
(:mod:`flexvox_core.gpu.dis`) or, with ``pairs="cpu"``, OpenCV's DIS on the host (the images go down, the flows
come up).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numba import cuda

from flexvox_core.flow.backends import dis_finest_scale
from flexvox_core.flow.baseline import blend, default_stride, measurements
from flexvox_core.flow.estimate import MIN_FLOW_SIDE, flow_size
from flexvox_core.gpu.filters import box_in_time
from flexvox_core.gpu.index import voxel
from flexvox_core.gpu.launch import device, kernel, launch
from flexvox_core.gpu.resize import resize_area, resize_linear, to_uint8
from flexvox_core.motion.classes_kernel import speed_class
from flexvox_core.motion.gated_flow_kernel import takes_slow
from flexvox_core.motion.stages import class_thresholds

PAIRS = ("gpu", "cpu")
"""Where the pairs' optical flow runs."""


def shrink(ws, video, scale: float, tag: str):
    """``video`` (S, H, W) at ``scale`` as :func:`~flexvox_core.flow.estimate.downscale` (the same array when
    the size does not change)."""
    S, H, W = video.shape
    h, w = flow_size(H, W, scale)
    if (h, w) == (H, W):
        return video
    out = ws.get(tag, (S, h, w))
    resize_area(ws, video, out, tag=f"{tag}.area")
    return out


class PairFlow:
    """DIS flow of pairs of uint8 images (N, h, w) on the device: ``(P, h, w, 2)`` float32 into ``out``."""

    def __init__(self, ws, where: str, dis_params: dict):
        if where not in PAIRS:
            raise ValueError(f"`pairs` must be one of {', '.join(PAIRS)}; got {where!r}")
        self.ws, self.where, self.dis_params = ws, where, dis_params

    def __call__(self, images, pairs: np.ndarray, out, tag: str) -> None:
        if not len(pairs):
            return
        if self.where == "cpu":
            self._on_host(images, pairs, out)
            return
        from flexvox_core.gpu.dis import DisWorkspace, dis_pairs

        a = self.ws.put(f"{tag}.a", np.ascontiguousarray(pairs[:, 0], np.int32))
        b = self.ws.put(f"{tag}.b", np.ascontiguousarray(pairs[:, 1], np.int32))
        params = self.params_for(images.shape[1:])
        size = (images.shape[0], len(pairs), *images.shape[1:], params)
        buffers = self.ws.held(f"{tag}.dis", lambda d: d.fits(*size), lambda: DisWorkspace(*size))
        dis_pairs(images, a, b, params, out=out, workspace=buffers)

    def params_for(self, shape):
        """The DIS parameters on images of ``shape`` (h, w): ``dis_params``, a ``finest_scale`` among them no coarser
        than the images' coarsest level, as the CPU's :class:`~flexvox_core.flow.backends.DisFlow` searches."""
        from flexvox_core.gpu.dis import DisParams

        params = DisParams(**self.dis_params)
        if "finest_scale" not in self.dis_params:
            return params
        return replace(params, finest_scale=dis_finest_scale(shape, params.finest_scale, params.patch_size))

    def _on_host(self, images, pairs, out) -> None:
        from flexvox_core.flow.backends import make_backend
        from flexvox_core.flow.estimate import run_pairs

        u8 = images.copy_to_host()
        flows = np.empty(tuple(out.shape), np.float32)
        conf = np.ones(flows.shape[:3], np.float32)
        run_pairs(make_backend("dis", **self.dis_params), u8, [tuple(p) for p in pairs], flows, conf,
                  consistency=False)
        out.copy_to_device(flows)


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1])")
def _successive_mean(fwd, vel):
    """Velocity of each sub-frame: the mean of the forward flows of pairs s − 1 … s + 1 (clamped to the pairs;
    the last sub-frame takes the last pair's), each weighted 1 + 10⁻³ as the CPU's confidence-weighted mean."""
    i = cuda.grid(1)
    S, h, w, _ = vel.shape
    if i >= S * h * w:
        return
    s, y, x = voxel(i, h, w)
    P = S - 1
    c = min(s, P - 1)
    reach = min(1, P - 1)
    wgt = np.float32(1.001)
    for k in range(2):
        num = np.float32(0)
        den = np.float32(0)
        for o in range(-reach, reach + 1):
            if max(0, -o) <= c < P - max(0, o):
                num += fwd[c + o, y, x, k] * wgt
                den += wgt
        vel[s, y, x, k] = num / den


def successive_flow(ws, small, pair_flow, tag: str):
    """Velocity (S, h, w, 2) of a shrunk video (S, h, w) from the flow of its successive sub-frames."""
    S, h, w = small.shape
    u8 = padded_uint8(ws, small, f"{tag}.u8")
    hp, wp = u8.shape[1:]
    fwd = ws.get(f"{tag}.fwd", (max(S - 1, 1), hp, wp, 2))
    pairs = np.stack([np.arange(S - 1), np.arange(1, S)], axis=1)
    pair_flow(u8, pairs, fwd, tag)
    fwd = cropped(ws, fwd, h, w, f"{tag}.crop")
    vel = ws.get(f"{tag}.vel", (S, h, w, 2))
    launch(_successive_mean, S * h * w, fwd, vel)
    return vel


@kernel("void(uint8[:, :, ::1], uint8[:, :, ::1])")
def _pad_reflect(src, dst):
    i = cuda.grid(1)
    N, H, W = dst.shape
    if i >= N * H * W:
        return
    n, y, x = voxel(i, H, W)
    h = src.shape[1]
    w = src.shape[2]
    yy = y if y < h else 2 * h - 1 - y
    xx = x if x < w else 2 * w - 1 - x
    dst[n, y, x] = src[n, max(yy, 0), max(xx, 0)]


def padded_uint8(ws, small, tag: str):
    """``small`` as uint8 images, mirror-padded at the bottom and right to at least :data:`MIN_FLOW_SIDE` px
    (as :func:`~flexvox_core.flow.estimate.run_pairs` pads for DIS)."""
    S, h, w = small.shape
    u8 = ws.get(tag, (S, h, w), np.uint8)
    to_uint8(small, u8)
    hp, wp = max(h, MIN_FLOW_SIDE), max(w, MIN_FLOW_SIDE)
    if (hp, wp) == (h, w):
        return u8
    out = ws.get(f"{tag}.pad", (S, hp, wp), np.uint8)
    launch(_pad_reflect, S * hp * wp, u8, out)
    return out


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1])")
def _crop(src, dst):
    i = cuda.grid(1)
    N, h, w, C = dst.shape
    if i >= N * h * w * C:
        return
    n = i // (h * w * C)
    p = i - n * (h * w * C)
    y = p // (w * C)
    x = (p // C) % w
    c = p % C
    dst[n, y, x, c] = src[n, y, x, c]


def cropped(ws, flow, h: int, w: int, tag: str):
    """The top-left (h, w) of a flow volume (itself when it has that size)."""
    if tuple(flow.shape[1:3]) == (h, w):
        return flow
    out = ws.get(tag, (flow.shape[0], h, w, 2))
    launch(_crop, flow.shape[0] * h * w * 2, flow, out)
    return out


def kaverage_plan(S: int, K: int, stride: int) -> tuple[int, np.ndarray, np.ndarray]:
    """The K-average's measurements as :class:`~flexvox_core.flow.baseline.KAverageFlow` makes them
    (:func:`~flexvox_core.flow.baseline.measurements`, :func:`~flexvox_core.flow.baseline.blend`): the span, the
    pairs (M, 2) and, per sub-frame, (j0, j1, a): velocity = (1 − a)·disp[j0] + a·disp[j1]."""
    span, starts = measurements(S, K, stride)
    centres = np.asarray(starts, np.float64) + span / 2
    interp = np.array([blend(centres, s) for s in range(S)], np.float32).reshape(S, 3)
    pairs = np.array([(a, a + span) for a in starts], np.int64)
    return span, pairs, interp


_takes_slow = device(takes_slow)
"""The CPU's rule (:func:`~flexvox_core.motion.gated_flow_kernel.takes_slow`) for one voxel."""


@device
def _sanitized(u, v, max_mag):
    """(u, v) with NaN or infinity as 0 and the magnitude capped at ``max_mag``
    (:func:`~flexvox_core.flow.estimate.sanitize_flow`)."""
    if not (math.isfinite(u) and math.isfinite(v)):
        return np.float32(0), np.float32(0)
    mag = math.sqrt(u * u + v * v)
    if mag > max_mag:
        return u * (max_mag / mag), v * (max_mag / mag)
    return u, v


@kernel("void(float32[:, :, :, ::1], float32[:, :, :, ::1], float32[:, ::1], float32[:, :, :, ::1], "
        "float32[:, :, :, ::1], float32, float32, float32, uint8, float32, uint8, float32, float32, float32, "
        "float32[:, :, :, ::1])")
def _gate(vel, disp, interp, steps, mean, px, lo, hi, use_slow, slow_speed, has_mean, plo, phi, max_mag, out):
    """:class:`~flexvox_core.motion.gated_flow._GatedFlow`'s ``one`` at one flow pixel of one sub-frame."""
    i = cuda.grid(1)
    S, h, w, _ = vel.shape
    if i >= S * h * w:
        return
    s, y, x = voxel(i, h, w)
    j0 = int(interp[s, 0])
    j1 = int(interp[s, 1])
    a = interp[s, 2]
    one = np.float32(1)
    su = (one - a) * disp[j0, y, x, 0] + a * disp[j1, y, x, 0]
    sv = (one - a) * disp[j0, y, x, 1] + a * disp[j1, y, x, 1]
    u = vel[s, y, x, 0]
    v = vel[s, y, x, 1]
    speed = math.sqrt(su * su + sv * sv) * px
    if use_slow and _takes_slow(speed, math.sqrt(u * u + v * v) * px, slow_speed):
        u = su
        v = sv
    tu = steps[s, y, x, 0]
    tv = steps[s, y, x, 1]
    speed = max(speed, math.sqrt(tu * tu + tv * tv) * px)
    ramp = min(max((speed - lo) / (hi - lo), np.float32(0)), one)
    if has_mean:
        mu = mean[s, y, x, 0]
        mv = mean[s, y, x, 1]
        ramp = max(ramp, min(max((math.sqrt(mu * mu + mv * mv) * px - plo) / (phi - plo), np.float32(0)), one))
    u, v = _sanitized(u * ramp, v * ramp, max_mag)
    out[s, y, x, 0] = u
    out[s, y, x, 1] = v


def gated_flow(ws, video, K: int, *, gate, scale: float, slow_speed, period_gate, pair_flow, detector_flow,
               out) -> dict:
    """The gated flow of ``video`` (S, H, W) into ``out`` (S, H, W, 2) (device arrays); returns its parameters
    (the CPU's flow parameters: the gates, the scale, whether the slow velocity was used). ``pair_flow``: the
    :class:`PairFlow` of the successive sub-frames and of the K-average's baseline
    (:data:`~flexvox_core.motion.gated_flow.DIS_PARAMS`); ``detector_flow``: the motion detector's
    (:data:`~flexvox_core.motion.gated_flow.DETECTOR_DIS_PARAMS`)."""
    S, H, W = video.shape
    lo, hi = gate
    small = shrink(ws, video, scale, "flow.small")
    h, w = small.shape[1:]
    vel = successive_flow(ws, small, pair_flow, "flow.successive")
    px = W / w
    params = {"scale": scale, "consistency": False, "temporal_window": 1}
    if not (K > 1 and S > 1):
        _to_full(ws, vel, out, max_mag=0.5 * max(h, w))
        return params
    average = ws.get("flow.average", (S, h, w))
    box_in_time(small, average, K)
    span, pairs, interp = kaverage_plan(S, K, default_stride(K))
    u8 = padded_uint8(ws, average, "flow.average.u8")
    disp = ws.get("flow.disp", (len(pairs), *u8.shape[1:], 2))
    pair_flow(u8, pairs, disp, "flow.kaverage")
    disp = cropped(ws, disp, h, w, "flow.disp.crop")
    use_slow = slow_speed is not None and span == K
    if use_slow:
        params["slow_speed"] = slow_speed
    half = shrink(ws, average, 0.5, "flow.half")
    steps_small = successive_flow(ws, half, detector_flow, "flow.steps")
    steps = ws.get("flow.steps.up", (S, h, w, 2))
    h2, w2 = half.shape[1:]
    resize_linear(ws, steps_small, steps, scale=(w / w2, h / h2), tag="flow.steps.up")
    mean = vel
    if period_gate is not None:
        mean = ws.get("flow.mean", (S, h, w, 2))
        box_in_time(vel, mean, K)
        params["period_gate"] = tuple(period_gate)
    params["gate"] = (lo, hi)
    # The slow speeds divide by the span on the host side of the CPU (disp /= span): here through `interp`'s rows.
    gated = ws.get("flow.gated", (S, h, w, 2))
    plo, phi = period_gate if period_gate is not None else (0.0, 1.0)
    launch(_gate, S * h * w, vel, _divided(ws, disp, span), ws.put("flow.interp", interp), steps, mean,
           np.float32(px), np.float32(lo), np.float32(hi), np.uint8(use_slow),
           np.float32(slow_speed if slow_speed is not None else 0.0), np.uint8(period_gate is not None),
           np.float32(plo), np.float32(phi), np.float32(0.5 * max(h, w)), gated)
    _resize_flow(ws, gated, out)
    return params


@kernel("void(float32[:, :, :, ::1], float32)")
def _scale(flow, factor):
    i = cuda.grid(1)
    if i < flow.size:
        N, h, w, C = flow.shape
        n = i // (h * w * C)
        p = i - n * (h * w * C)
        flow[n, p // (w * C), (p // C) % w, p % C] *= factor


def _divided(ws, disp, span: int):
    """The K-average's displacements over ``span`` sub-frames as velocities (in place)."""
    launch(_scale, int(math.prod(disp.shape)), disp, np.float32(1 / span))
    return disp


def _resize_flow(ws, small, out) -> None:
    """``small`` (S, h, w, 2) resized to ``out``'s size, its vectors scaled by the ratio (or copied)."""
    h, w = small.shape[1:3]
    H, W = out.shape[1:3]
    if (h, w) == (H, W):
        out.copy_to_device(small)
        return
    resize_linear(ws, small, out, scale=(W / w, H / h), tag="flow.full")


@kernel("void(float32[:, :, :, ::1], float32)")
def _sanitize(flow, max_mag):
    i = cuda.grid(1)
    S, h, w, _ = flow.shape
    if i >= S * h * w:
        return
    s, y, x = voxel(i, h, w)
    u, v = _sanitized(flow[s, y, x, 0], flow[s, y, x, 1], max_mag)
    flow[s, y, x, 0] = u
    flow[s, y, x, 1] = v


def _to_full(ws, vel, out, *, max_mag: float) -> None:
    """Sanitised (NaN to 0, magnitudes capped) and resized: :func:`~flexvox_core.flow.estimate.to_full_size`."""
    S, h, w, _ = vel.shape
    launch(_sanitize, S * h * w, vel, np.float32(max_mag))
    _resize_flow(ws, vel, out)


_speed_class = device(speed_class)


@kernel("void(float32[:, :, :, ::1], float32, float32, uint8[::1], uint8[:, :, ::1], uint8[:, :, ::1], "
        "uint8[:, :, ::1], int32[::1])")
def _classes(flow, still_below, slow_below, skip, still, slow, gather, counts):
    i = cuda.grid(1)
    S, H, W, _ = flow.shape
    if i >= S * H * W:
        return
    t, y, x = voxel(i, H, W)
    u = flow[t, y, x, 0]
    v = flow[t, y, x, 1]
    speed = math.sqrt(u * u + v * v)
    is_still, is_slow, is_gathered = _speed_class(speed, still_below, slow_below, skip[t] != 0)
    still[t, y, x] = is_still
    slow[t, y, x] = is_slow
    gather[t, y, x] = is_gathered
    if is_still:
        cuda.atomic.add(counts, 0, 1)
    if is_slow:
        cuda.atomic.add(counts, 1, 1)


def speed_classes(ws, flow, still_speed, slow_speed, skip: np.ndarray | None, still, slow, gather) -> tuple[int, int]:
    """``still``, ``slow`` and ``gather``, uint8 (S, H, W), by the CPU's rule
    (:func:`~flexvox_core.motion.classes_kernel.speed_class`: still below ``still_speed``, slow below ``slow_speed`` and
    not still nor in ``skip``, gathered when none of these); returns the counts of still and slow voxels."""
    S = flow.shape[0]
    counts = ws.put("classes.counts", np.zeros(2, np.int32))
    skip_d = ws.put("classes.skip", np.zeros(S, np.uint8) if skip is None else skip.astype(np.uint8))
    launch(_classes, int(math.prod(flow.shape[:3])), flow, *class_thresholds(still_speed, slow_speed), skip_d, still,
           slow, gather, counts)
    c = counts.copy_to_host()
    return int(c[0]), int(c[1])
