"""The trajectory gather's weight rules, shared by :mod:`~flexvox_core.motion.mcnc`, its compiled kernel
(:mod:`~flexvox_core.motion.mcnc_kernel`) and the GPU's twin (:mod:`flexvox_core.motion.gpu.mcnc`).

A module of its own so that the kernel reads them without importing the gather that calls it.
"""

from __future__ import annotations

__all__ = ["CUTOFF", "MIN_WEIGHT"]

MIN_WEIGHT = 1e-6
"""A voxel whose gathered weight is below this takes its fallback (the guides' value)."""
CUTOFF = 1e-3
"""Trajectory weights below this (relative to 1 at the voxel's own sub-frame) are not gathered: they
change no PSNR of ``flexvox bench`` by 0.001 dB and cost a quarter of the gather's time. Each voxel stops
at its own cutoff (a fast voxel's weights fall off sooner than a slow neighbour's), so a box of voxels
reads about half the samples it would with one cutoff for all."""
