"""Scene-driven simulation: turn a high-speed scene into what the rig's camera records.

Only the effects a scene declares are simulated; with none, the output is the ideal
forward model exactly (:func:`flexvox_core.forward.capture`).
"""

from flexvox_core.simulate.effects import EFFECTS, Effect, parse_effects
from flexvox_core.simulate.scene_file import SceneSpec, load_scene, scene_from_mapping
from flexvox_core.simulate.scenes import SCENES, render_scene
from flexvox_core.simulate.simulator import SimulationResult, simulate, simulate_video
from flexvox_core.simulate.sources import load_video

__all__ = [
    "EFFECTS",
    "SCENES",
    "Effect",
    "SceneSpec",
    "SimulationResult",
    "load_scene",
    "load_video",
    "parse_effects",
    "render_scene",
    "scene_from_mapping",
    "simulate",
    "simulate_video",
]
