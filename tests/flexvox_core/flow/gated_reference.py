"""Whole-volume forms of the flow steps that run a sub-frame at a time (the tests' references):
:func:`~flexvox_core.flow.estimate.successive_flow`'s confidence-weighted average and
:func:`~flexvox_core.motion.pipeline.gated_flow`'s gate, as they were written over whole volumes."""

import numpy as np
from scipy.ndimage import uniform_filter1d

from flexvox_core.flow import FlowField
from flexvox_core.flow.backends import backend_params, make_backend
from flexvox_core.flow.baseline import default_stride, kaverage_flow
from flexvox_core.flow.estimate import check_video, downscale, run_pairs, to_full_size, to_uint8, upsample_flow
from flexvox_core.motion.gated_flow import DETECTOR_DIS_PARAMS
from flexvox_core.motion.pipeline import DIS_PARAMS


def successive_flow_reference(small, flow_fn, *, consistency, temporal_window, memo=None):
    S, h, w = small.shape
    u8 = to_uint8(small)
    fwd = np.empty((S - 1, h, w, 2), np.float32)
    conf = np.ones((S - 1, h, w), np.float32)
    run_pairs(flow_fn, u8, list(zip(range(S - 1), range(1, S), strict=True)), fwd, conf, consistency=consistency,
              memo=memo)
    wts = conf + np.float32(1e-3)
    weighted = fwd * wts[..., None]
    P = S - 1
    num, den = np.zeros((S, h, w, 2), np.float32), np.zeros((S, h, w), np.float32)
    for o in range(-min(temporal_window, P - 1), min(temporal_window, P - 1) + 1):
        a, b = max(0, -o), P - max(0, o)
        num[a:b] += weighted[a + o: b + o]
        den[a:b] += wts[a + o: b + o]
    num[P], den[P] = num[P - 1], den[P - 1]
    return np.divide(num, den[..., None], out=num), np.concatenate([conf, conf[-1:]])


def gated_flow_reference(video, K, *, backend, gate=(0.03, 0.15), scale=0.5, consistency=False, slow_speed=0.6,
                         period_gate=(0.9, 1.5)):
    lo, hi = gate
    video = check_video(video)
    flow_fn = make_backend(backend, **(DIS_PARAMS if backend == "dis" else {}))  # as gated_flow measures
    small = downscale(video, scale)
    vel, conf = successive_flow_reference(small, flow_fn, consistency=consistency, temporal_window=1)
    successive = vel
    px = video.shape[2] / vel.shape[2]
    params = {**backend_params(flow_fn), "scale": scale, "consistency": consistency, "temporal_window": 1}
    if K > 1 and video.shape[0] > 1:
        average = uniform_filter1d(small, K, axis=0, mode="nearest")
        slow, span = kaverage_flow(small, K, flow_fn, default_stride(K), average=average)
        speed = np.hypot(slow[..., 0], slow[..., 1]) * np.float32(px)
        if slow_speed is not None and span == K:
            use_slow = (speed < slow_speed) & (np.hypot(vel[..., 0], vel[..., 1]) * np.float32(px) < 2 * slow_speed)
            vel = np.where(use_slow[..., None], slow, vel)
            params["slow_speed"] = slow_speed
        steps, _ = successive_flow_reference(downscale(average, 0.5), make_backend("dis", **DETECTOR_DIS_PARAMS),
                                             consistency=False, temporal_window=1)
        steps = upsample_flow(steps, small.shape[1:])
        speed = np.maximum(speed, np.hypot(steps[..., 0], steps[..., 1]) * np.float32(px))
        ramp = np.clip((speed - lo) / (hi - lo), 0, 1).astype(np.float32)
        if period_gate is not None:
            plo, phi = period_gate
            mean = uniform_filter1d(successive, K, axis=0, mode="nearest")
            mean_speed = np.hypot(mean[..., 0], mean[..., 1]) * np.float32(px)
            ramp = np.maximum(ramp, np.clip((mean_speed - plo) / (phi - plo), 0, 1))
            params["period_gate"] = (plo, phi)
        vel *= ramp[..., None]
        params["gate"] = (lo, hi)
    vel, conf = to_full_size(vel, conf, video.shape[1:])
    return FlowField(vel, conf, params)
