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


def test_auto_on_a_multiplexed_recording_is_refused_in_words_before_anything_runs(tmp_path):
    from flexvox_app.gui.models.review_jobs import JobsModel
    from flexvox_app.gui.models.review_playback import PlaybackModel

    from .model_helpers import Settings, TurnedRunner

    mc = multiplexed_code((1, 3))
    result = simulate_video(render_scene("balls", 3 * 4, 12, 15), mc.code, seed=1)
    result.multiplexed, result.placement = True, mc.placement
    s = ReviewSession.open(write_simulation(tmp_path / "m.zarr", result))
    playback = PlaybackModel(Settings())
    jobs = JobsModel(TurnedRunner(), Settings(), None, playback)
    playback.set_session(s)
    jobs.set_session(s)
    assert jobs.reconstruct(Method("diffusion"), auto_knob="time") is None and jobs.runner.waiting == []
    assert jobs.result_line.error
    assert jobs.result_line.text.startswith("cannot choose diffusion's time by the estimate on a multiplexed "
                                            "recording: the estimate of a demultiplexed capture has not met")
    assert jobs.reconstruct(Method("diffusion")) is not None  # without auto it runs
    assert not jobs.result_line.error
