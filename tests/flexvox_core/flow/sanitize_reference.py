"""``sanitize_flow`` as it was before its finite check came from the max and min it reads: the tests' reference (the
same bits), and what ``bench/bench_motion_throughput.py --ab flow-plumbing-before`` puts back."""

import numpy as np


def sanitize_reference(flow, confidence=None, *, max_magnitude=None):
    """sanitize_flow as it was (its checks from a float64 sum and a clip of any confidence): the same bits."""
    flow = np.asarray(flow, dtype=np.float32)
    conf = np.ones(flow.shape[:-1], np.float32) if confidence is None else np.array(confidence, np.float32)
    if not np.isfinite(flow.sum(dtype=np.float64)):
        bad = ~np.isfinite(flow).all(axis=-1)
        flow = flow.copy()
        flow[bad] = 0
        conf[bad] = 0
    if max_magnitude is not None and flow.size and max(flow.max(), -flow.min()) * np.sqrt(2) > max_magnitude:
        mag = np.hypot(flow[..., 0], flow[..., 1])
        over = mag > max_magnitude
        if over.any():
            flow = flow * np.where(over, max_magnitude / np.maximum(mag, 1e-12), 1)[..., None]
    if conf.size and not (np.min(conf) >= 0 and np.max(conf) <= 1):
        conf = np.clip(conf, 0, 1)
    return flow.astype(np.float32, copy=False), conf
