"""Review hands a multiplexed recording as captured to the methods that take it (Qt-free model)."""

import numpy as np

from flexvox_app.gui.models.review_session import ReviewSession
from flexvox_core.methods import Method
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.recording import write_simulation
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video


def test_review_input_per_method(tmp_path):
    mc = multiplexed_code((1, 3))
    result = simulate_video(render_scene("balls", 3 * 3, 9, 12), mc.code, seed=1)
    result.multiplexed, result.placement = True, mc.placement
    s = ReviewSession.open(write_simulation(tmp_path / "m.zarr", result))
    frames, code = s.input(Method("motion-aware"))
    np.testing.assert_array_equal(code, mc.code)
    np.testing.assert_array_equal(frames, s.raw)
    frames, code = s.input(Method("rebin"))
    assert frames is s.frames and code is s.code and not np.array_equal(code, mc.code)
