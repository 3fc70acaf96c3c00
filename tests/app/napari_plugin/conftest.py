"""Small recordings for the napari plugin's tests."""

import pytest

from flexvox_core.design import design_code
from flexvox_core.recording import write_simulation
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.simulator import simulate_video


@pytest.fixture
def recording(tmp_path):
    """A simulated recording with ground truth: 6 frames of 24x32, 2x2 tile (K = 4), at 15 Hz."""
    video = render_scene("fan", 6 * 4, 24, 32, seed=3)
    return write_simulation(tmp_path / "rec.zarr", simulate_video(video, design_code((2, 2)).code, seed=1,
                                                                  rate_hz=15.0))


@pytest.fixture
def moving_recording(tmp_path):
    """A recording of a moving scene at 4x4 (K = 16), for motion-aware."""
    video = render_scene("balls", 3 * 16, 32, 40, seed=2)
    return write_simulation(tmp_path / "moving.zarr", simulate_video(video, design_code((4, 4)).code, seed=1))
