"""The tests' one recipe for a simulated recording with ground truth (the ``recording`` fixture of tests/conftest.py
makes it; a ``recording(...)`` mark gives its shape)."""

from __future__ import annotations

from pathlib import Path


def simulate_recording(folder: Path, scene: str = "balls", *, frames: int = 6, size: tuple[int, int] = (32, 48),
                       tile: tuple[int, int] = (2, 4), scene_seed: int = 0, noise_seed: int = 0,
                       rate_hz: float = 15.0, name: str = "rec.zarr") -> Path:
    """Write ``frames`` camera frames of ``scene`` (``size`` pixels) captured through the designed code of ``tile``
    into ``folder / name``, with the ground truth; its path."""
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    code = design_code(tile).code
    video = render_scene(scene, frames * code.shape[2], *size, seed=scene_seed)
    return write_simulation(Path(folder) / name, simulate_video(video, code, seed=noise_seed, rate_hz=rate_hz))
