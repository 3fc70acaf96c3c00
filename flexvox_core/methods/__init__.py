"""Reconstruction methods as objects, their registry, and the one chunked runner.

- :mod:`~flexvox_core.methods.spec` — :class:`MethodSpec`, what a method is (options, run,
  overlap, capabilities, label) and :class:`MethodOutput`;
- :mod:`~flexvox_core.methods.options` — typed options with defaults and rules;
- one module per method: :mod:`~flexvox_core.methods.rebin_method`, :mod:`~flexvox_core.methods.diffusion_method`,
  :mod:`~flexvox_core.methods.gap_tv_method`, :mod:`~flexvox_core.methods.motion_aware_method` (the algorithms
  stay in :mod:`flexvox_core.reconstruct` and :mod:`flexvox_core.motion`, which never import this
  package);
- :mod:`~flexvox_core.methods.registry` — the methods by name (adding one: a module and a line there);
- :mod:`~flexvox_core.methods.method` — :class:`Method`, a method and its values (what callers hold);
- :mod:`~flexvox_core.methods.runner` — :func:`run` in time chunks with the
  overlap each method needs, and :func:`run_chunk`, the per-chunk function the batch shares.
"""

from flexvox_core.methods.method import Method
from flexvox_core.methods.options import Option
from flexvox_core.methods.registry import DEFAULT, get, names, register, specs, unregister
from flexvox_core.methods.runner import chunk_plan, reconstruct, run, run_chunk, sample_range
from flexvox_core.methods.spec import MethodOutput, MethodSpec
from flexvox_core.reconstruct.rebin import default_block

METHODS = names()
"""Names of the built-in methods (a snapshot; :func:`names` also lists methods registered later)."""


def overlap_frames(method: Method, K: int) -> int | None:
    """Camera frames of context each chunk of ``method`` needs on each side (None: cannot be chunked)."""
    return method.overlap(K)


__all__ = [
    "DEFAULT",
    "METHODS",
    "Method",
    "MethodOutput",
    "MethodSpec",
    "Option",
    "chunk_plan",
    "default_block",
    "get",
    "names",
    "overlap_frames",
    "reconstruct",
    "register",
    "run",
    "run_chunk",
    "sample_range",
    "specs",
    "unregister",
]
