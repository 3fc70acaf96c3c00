"""Optical flow between successive sub-frames (the paper's Section 4, step 2), and its pictures.

Flow arrays follow OpenCV's order: ``(..., 2)`` = (u, v) = (dx, dy) in pixels per sub-frame.
"""

from flexvox_core.flow.backends import BACKENDS, make_backend
from flexvox_core.flow.baseline import kaverage_velocity
from flexvox_core.flow.estimate import FlowField, estimate_flow
from flexvox_core.flow.visualize import flow_to_color, magnitude_image, quiver_image

__all__ = ["BACKENDS", "FlowField", "estimate_flow", "flow_to_color", "kaverage_velocity", "magnitude_image",
           "make_backend", "quiver_image"]
