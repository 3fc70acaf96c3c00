"""What every example shares: its sizes (tiny under FLEXVOX_EXAMPLE_TINY=1, as the tests run them) and a
simulated recording to work on when none is given."""

import os
from pathlib import Path

import flexvox_core as fv

TINY = os.environ.get("FLEXVOX_EXAMPLE_TINY") == "1"
SIZE = (32, 48) if TINY else (120, 160)
FRAMES = 4 if TINY else 12


def sample_recording(path="sample.zarr", *, scene="balls", tile=(4, 4), seed=0) -> Path:
    """A simulated recording (photon and read noise) of a built-in scene, written once."""
    path = Path(path)
    if not path.exists():
        code = fv.design_code(tile).code
        video = fv.render_scene(scene, FRAMES * code.shape[2], *SIZE, seed=seed)
        sim = fv.simulate_video(video, code, seed=seed, effects={"photon_noise": {}, "read_noise": {"sigma": 2.0}})
        fv.write_simulation(path, sim)
    return path
