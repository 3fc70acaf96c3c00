"""The trajectory gather's kernel as it read every cell before, clamped into the picture (before
:func:`flexvox_core.motion.mcnc_kernel.lattice_sums` read the cells wholly in the picture without clamping):
compiled from the module's own source with that path taken out, for the tests' bit-for-bit comparison and the
benchmark's variant."""

import functools
import inspect
import types

FAST_PATH = "    if 0 <= y0 and y0 < H - 1 and 0 <= x0 and x0 < W - 1:"
CLAMPED = "    ya = min(max(y0, -1), H)"


@functools.cache
def clamped_lattice_sums():
    """``lattice_sums`` with every read clamped (numba, not cached on disk)."""
    from flexvox_core.motion import mcnc_kernel

    source = inspect.getsource(mcnc_kernel)
    start, end = source.index(FAST_PATH), source.index(CLAMPED)
    source = (source[:start] + source[end:]).replace("cache=True", "cache=False")
    module = types.ModuleType("mcnc_kernel_clamped")
    exec(compile(source, "<mcnc_kernel, every read clamped>", "exec"), module.__dict__)  # noqa: S102
    return module.lattice_sums
