"""Reconstructions that need no motion information (the paper's §§2–3) and a GAP-TV peer.

Every function takes an identity-code capture ``frames`` (F, H, W) and its ``code``
(m, n, K) and returns the full video (F·K, H, W). Multiplexed captures are demultiplexed
first with :func:`as_identity_capture`.

- :mod:`~flexvox_core.reconstruct.rebin` — re-binning at every supported division;
- :mod:`~flexvox_core.reconstruct.diffusion` — constant-tensor diffusion, solvers
  ``nc`` (normalized convolution), ``explicit`` and ``steady``;
- :mod:`~flexvox_core.reconstruct.gaptv` — GAP-TV (Yuan 2016) for any 0/1 code.

These are the algorithms. :mod:`flexvox_core.methods` wraps each as a method object (options,
overlap, label) and runs any of them in time chunks; this package never imports it (nor
:mod:`flexvox_core.motion`, which builds on it).
"""

from flexvox_core.reconstruct._common import as_identity_capture
from flexvox_core.reconstruct.diffusion import SOLVERS, diffuse, sigmas, stability_bound
from flexvox_core.reconstruct.gaptv import gap_tv, gap_tv_masks, tv_denoise
from flexvox_core.reconstruct.rebin import default_block, rebin, rebin_blocks, supported_divisions

__all__ = [
    "SOLVERS",
    "default_block",
    "diffuse",
    "gap_tv",
    "gap_tv_masks",
    "as_identity_capture",
    "rebin",
    "rebin_blocks",
    "sigmas",
    "stability_bound",
    "supported_divisions",
    "tv_denoise",
]
