"""Tiny captures for the GPU engine's tests: under numba-cuda's simulator every kernel runs as Python."""

import numpy as np

from flexvox_core import capture, code_from_order
from flexvox_core.simulate.scenes import render_scene

CODE = code_from_order([[0, 2], [3, 1]])
K = 4


def tiny_capture(scene, F, H, W, noise=0.0, seed=0):
    """(truth (F·K, H, W), frames (F, H, W) float32) of a built-in scene with the 2×2 code, optionally noisy."""
    truth = render_scene(scene, F * K, H, W, seed=seed)
    frames = capture(truth, CODE)
    if noise:
        frames = np.clip(frames + np.random.default_rng(seed).normal(0, noise, frames.shape), 0, 1)
    return truth, np.asarray(frames, np.float32)
