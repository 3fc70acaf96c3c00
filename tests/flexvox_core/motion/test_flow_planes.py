"""Motion-aware reads the flow held at its own scale a sub-frame at a time: the bits of a run on the whole flow."""

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.flow.estimate import FlowField, ScaledFlow
from flexvox_core.forward import capture
from flexvox_core.motion import motion_aware
from flexvox_core.motion.options import MotionOptions
from flexvox_core.motion.pipeline import run_window
from flexvox_core.simulate.scenes import render_scene

CODE = design_code((4, 4)).code


def _run(frames, kwargs):
    """motion_aware, or with ``keep`` the stages on a part of the window (as a streaming run's)."""
    if "keep" not in kwargs:
        return motion_aware(frames, CODE, **kwargs)
    options = {k: v for k, v in kwargs.items() if k != "keep"}
    return run_window(frames, CODE, MotionOptions(**options), (0.0, 1.0), keep=kwargs["keep"])


def _frames(scene, noise=0.0):
    frames = capture(render_scene(scene, 16 * 4, 40, 52), CODE)
    if noise:
        frames = np.clip(frames + np.random.default_rng(0).normal(0, noise, frames.shape), 0, 1).astype(np.float32)
    return frames


CASES = {
    "balls": ("balls", 0.0, {"flow_scale": 0.5}),
    "pan, slow voxels": ("pan", 0.0, {"flow_scale": 0.5}),
    "noisy": ("balls", 0.01, {"flow_scale": 0.5}),
    "dropped frames": ("balls", 0.0, {"flow_scale": 0.5, "missing": np.array([False, True, False, False])}),
    "dropped at the end": ("pan", 0.0, {"flow_scale": 0.4, "missing": np.array([False, False, False, True])}),
    "second pass": ("balls", 0.0, {"flow_scale": 0.5, "passes": 2}),
    "kept part": ("balls", 0.0, {"flow_scale": 0.5, "keep": (16, 40)}),
    "flow at full size": ("balls", 0.0, {"flow_scale": 1.0}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_motion_aware_on_the_held_flow_gives_the_whole_flows_bits(monkeypatch, case):
    import flexvox_core.motion.stages as P

    scene, noise, kwargs = CASES[case]
    frames = _frames(scene, noise)
    slow_seen = []
    long_reach = P.CpuStages.long_reach

    def spy(self, flow, video, slow):
        slow_seen.append(bool(np.any(P.band(slow, 0, self.window.S))))
        return long_reach(self, flow, video, slow)

    monkeypatch.setattr(P.CpuStages, "long_reach", spy)
    got = _run(frames, kwargs)
    held = got.flow
    if kwargs["flow_scale"] < 1:
        assert isinstance(held, ScaledFlow)
        assert "flow" not in held.__dict__  # no stage made the whole full-size flow
    else:
        assert isinstance(held, FlowField)
    kept = P.CpuStages.gated_flow

    def whole(self, current):  # the same flow (bridged as held), made whole before any stage reads it
        f = kept(self, current)
        return FlowField(np.array(f.flow), f.confidence, f.params, f.seconds)

    monkeypatch.setattr(P.CpuStages, "gated_flow", whole)
    want = _run(frames, kwargs)
    np.testing.assert_array_equal(got.video, want.video)
    np.testing.assert_array_equal(held.flow, want.flow.flow)
    if case.startswith("pan"):
        assert any(slow_seen)  # the long reach ran on slow voxels
