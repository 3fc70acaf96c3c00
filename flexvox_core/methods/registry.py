"""The reconstruction methods flexvox knows, by name.

Adding a method is one module in :mod:`flexvox_core.methods` (a
:class:`~flexvox_core.methods.spec.MethodSpec` subclass and its instance) and one entry in
:data:`BUILTIN`. The command line (``--method``), the Review workspace's method form, the
runner and the batch read this registry; nothing else lists methods.
"""

from __future__ import annotations

from flexvox_core.methods.diffusion_method import DIFFUSION
from flexvox_core.methods.gap_tv_method import GAP_TV
from flexvox_core.methods.motion_aware_method import MOTION_AWARE
from flexvox_core.methods.rebin_method import REBIN
from flexvox_core.methods.spec import MethodSpec

BUILTIN: tuple[MethodSpec, ...] = (REBIN, DIFFUSION, GAP_TV, MOTION_AWARE)
"""The built-in methods, in the order menus show them."""

DEFAULT = MOTION_AWARE.name
"""The method used when none is named: motion-aware, which beats re-binning, GAP-TV and the best fixed
tensor on every group `flexvox bench` measures (docs/benchmarks.md, "flexvox bench"). Constant-tensor
diffusion (`nc`) stays the fast method: the live preview's fast choice and the answer under a 10 ms budget."""

_BY_NAME: dict[str, MethodSpec] = {m.name: m for m in BUILTIN}


def names() -> tuple[str, ...]:
    """Names of the registered methods, in registration order."""
    return tuple(_BY_NAME)


def specs() -> tuple[MethodSpec, ...]:
    """The registered methods, in registration order."""
    return tuple(_BY_NAME.values())


def get(name: str) -> MethodSpec:
    """The method called ``name``; ``ValueError`` naming the known ones otherwise, and the one meant where the name
    is a near miss (:func:`meant`)."""
    try:
        return _BY_NAME[name]
    except (KeyError, TypeError):
        hint = meant(name) if isinstance(name, str) else ""
        raise ValueError(f"`method` must be one of {', '.join(_BY_NAME)}; got {name!r}{hint}") from None


def meant(name: str, *, flags: bool = False) -> str:
    """What a near-miss method name most likely meant, as a clause ("": no guess). Names are exact (lower case,
    hyphens): another case, underscores or spaces, or a close spelling (``"gaptv"``) name the method to write; a
    diffusion solver's name (``"nc"``) names the method and option that run it, in Python's words or, with
    ``flags``, the command line's. Never a silent conversion."""
    import difflib

    from flexvox_core.reconstruct.diffusion import SOLVERS

    plain = "-".join(name.strip().lower().replace("_", " ").replace("-", " ").split())
    q = (lambda v: v) if flags else repr
    if plain in _BY_NAME:
        return f": write it {q(plain)}"
    if plain in SOLVERS:
        how = (f"--method diffusion --solver {plain}" if flags else f"('diffusion', solver={plain!r})")
        return (f": {q(plain)} is a solver of the diffusion method: {how}"
                + (" (its default)" if plain == DIFFUSION.option("solver").default else ""))
    close = difflib.get_close_matches(plain, list(_BY_NAME), n=1)
    return f": did you mean {q(close[0])}?" if close else ""


def register(spec: MethodSpec) -> MethodSpec:
    """Add a method (after the built-in ones); ``ValueError`` when its name is taken or it is no MethodSpec."""
    if not isinstance(spec, MethodSpec):
        raise ValueError(f"`spec` must be a MethodSpec instance; got {spec!r}")
    if not spec.name or spec.name in _BY_NAME:
        raise ValueError(f"a method needs a name of its own; {spec.name!r} is "
                         f"{'taken' if spec.name else 'empty'} (registered: {', '.join(_BY_NAME)})")
    _BY_NAME[spec.name] = spec
    return spec


def unregister(name: str) -> None:
    """Remove a method :func:`register` added; the built-in ones stay."""
    if any(m.name == name for m in BUILTIN):
        raise ValueError(f"{name!r} is a built-in method and cannot be removed")
    if name not in _BY_NAME:
        raise ValueError(f"no method {name!r} is registered (registered: {', '.join(_BY_NAME)})")
    del _BY_NAME[name]
