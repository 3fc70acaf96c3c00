"""A tiny method, defined the way a new one is (a MethodSpec subclass), for the registry tests.

``frame-mean``: every sub-frame of camera frame f is the mean of frames f - radius .. f + radius
(those that exist), rescaled by the whole recording's sample range; it returns the camera frame
each sub-frame came from as an extra.
"""

import contextlib

import numpy as np

from flexvox_core.methods import MethodOutput, MethodSpec, register, unregister
from flexvox_core.methods.options import integer


class FrameMean(MethodSpec):
    name = "frame-mean"
    title = "mean of neighbouring camera frames (a test method)"
    trade = "frame-mean keeps space and gives up time"
    option_specs = (integer("radius", 1, minimum=0, label="radius", help="camera frames averaged on each side"),)
    needs_sample_range = True
    extras = ("frame",)

    def overlap(self, options, K):
        return options.radius

    def run(self, frames, code, options, *, sample_range=None, extras=False):
        F, K, r = frames.shape[0], code.shape[2], options.radius
        lo, hi = sample_range if sample_range is not None else (float(frames.min()), float(frames.max()))
        means = np.stack([frames[max(0, f - r): f + r + 1].mean(axis=0) for f in range(F)])
        video = np.repeat((means - lo) / max(hi - lo, 1e-12), K, axis=0)
        # The camera frame of each sub-frame, counted from this chunk's first frame.
        extra = {"frame": np.repeat(np.arange(F), K).astype(np.float32)} if extras else {}
        return MethodOutput(video, extra)

    def label(self, values):
        return f"frame-mean r={values['radius']}"


@contextlib.contextmanager
def frame_mean_registered():
    """The method registered for the duration of a ``with`` block, then removed."""
    register(FrameMean())
    try:
        yield
    finally:
        unregister(FrameMean.name)
