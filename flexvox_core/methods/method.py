"""The value users hold: a registered method and its checked option values.

``Method("motion-aware", time=3)`` looks the method up in the registry, checks every given
option against its rule (an unknown option or a bad value is a ``ValueError`` naming both),
fills the defaults, builds the options object the method's algorithm takes (``m.options``,
:meth:`MethodSpec.build <flexvox_core.methods.spec.MethodSpec.build>`), and then reads like a frozen
record: ``m.name``, ``m.time``, ``m.label``, ``m.as_dict()``. Two methods with the same name and
values are equal (and hash alike).
"""

from __future__ import annotations

from types import MappingProxyType

from flexvox_core.methods.registry import DEFAULT, get
from flexvox_core.methods.spec import MethodSpec


class Label(str):
    """A method's label (:attr:`Method.label`): a str. Calling it gives it too, as when ``label`` was a method
    (kept for one release: read ``m.label``)."""

    __slots__ = ()

    def __call__(self) -> str:
        return str(self)


def _rebuild(name: str, values: dict) -> Method:
    return Method(name, **values)


class Method:
    """A reconstruction method and its knobs.

    Parameters
    ----------
    name : str
        A registered method (:func:`flexvox_core.methods.registry.names`); default
        :data:`~flexvox_core.methods.registry.DEFAULT` (motion-aware).
    **options
        Values of the method's options (``Method(name).spec.option_specs``); None or absent: the
        option's default. For instance ``rebin``: ``block``, ``interpolate``; ``diffusion``:
        ``tensor``, ``time``, ``solver``; ``gap-tv``: ``iterations``, ``tv_weight``,
        ``tv_iterations``; ``motion-aware``: ``flow``, ``time``, ``passes``, ``refine_time``,
        ``slow_reach``, ``local_choice``, ``noise_aware``.

    Raises
    ------
    ValueError
        An unknown method or option, or a value that breaks its option's rule.
    """

    __slots__ = ("_options", "_spec", "_values")

    def __init__(self, name: str = DEFAULT, **options):
        spec = get(name)
        try:
            values = spec.resolve(options)
        except ValueError as exc:
            raise ValueError(f"{exc}{_auto_hint(spec.name, options)}") from None
        object.__setattr__(self, "_spec", spec)
        object.__setattr__(self, "_values", MappingProxyType(values))
        object.__setattr__(self, "_options", spec.build(values))

    # ------------------------------------------------------------------ record
    @property
    def name(self) -> str:
        """The method's registered name."""
        return self._spec.name

    @property
    def spec(self) -> MethodSpec:
        """The method object: options, capabilities, run, overlap."""
        return self._spec

    @property
    def values(self) -> MappingProxyType:
        """Every option's value, read-only."""
        return self._values

    @property
    def options(self):
        """The options object the method runs with, built once from :attr:`values`, frozen (motion-aware's
        :class:`~flexvox_core.motion.options.MotionOptions`; for the others a dataclass of them,
        :func:`~flexvox_core.methods.spec.options_type`)."""
        return self._options

    def __getattr__(self, key: str):
        if key.startswith("_"):
            raise AttributeError(key)
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"{self.name} has no option {key!r} (its options: "
                                 f"{self._spec.option_list()})") from None

    def __setattr__(self, key, value):
        raise AttributeError(f"a Method is read-only; make a new one (Method({self.name!r}, {key}=...))")

    def __eq__(self, other) -> bool:
        if not isinstance(other, Method):
            return NotImplemented
        return self.name == other.name and dict(self._values) == dict(other._values)

    def __hash__(self) -> int:
        return hash((self.name, tuple(self._values.items())))

    def __repr__(self) -> str:
        knobs = ", ".join(f"{k}={v!r}" for k, v in self._values.items())
        return f"Method({self.name!r}{', ' if knobs else ''}{knobs})"

    def __reduce__(self):
        return _rebuild, (self.name, dict(self._values))

    # ------------------------------------------------------------------ what it says
    @property
    def label(self) -> Label:
        """Short human-readable description (a str; ``m.label()``, from when it was a method, gives it too)."""
        return Label(self._spec.label(dict(self._values)))

    def as_dict(self) -> dict:
        """Metadata form: ``name`` and every option's value."""
        return self._spec.as_dict(dict(self._values))

    def overlap(self, K: int) -> int | None:
        """Camera frames of context each chunk needs on each side for a code of K slots
        (None: it cannot run in chunks)."""
        return self._spec.overlap(self._options, K)

    def takes_multiplexed(self) -> bool:
        """True when it reconstructs a multiplexed capture from its own forward model with these values
        (:meth:`MethodSpec.takes_multiplexed <flexvox_core.methods.spec.MethodSpec.takes_multiplexed>`);
        False: a multiplexed recording is demultiplexed per tile for it."""
        return self._spec.takes_multiplexed(self._options)

    def max_gap(self, K: int) -> int:
        """The longest run of dropped camera frames it bridges for a code of K slots."""
        return self._spec.max_gap(self._options, K)

    def gpu_voxel_bytes(self, K: int, H: int, W: int) -> float:
        """Device memory a GPU run holds per voxel of a chunk of H×W pictures at K slots
        (:meth:`MethodSpec.gpu_voxel_bytes <flexvox_core.methods.spec.MethodSpec.gpu_voxel_bytes>`; 0: not known)."""
        return self._spec.gpu_voxel_bytes(self._options, K, H, W)

    def cpu_only(self, code) -> str | None:
        """Why it runs on the CPU with this code even when the GPU is asked for, or None
        (:meth:`MethodSpec.cpu_only <flexvox_core.methods.spec.MethodSpec.cpu_only>`)."""
        return self._spec.cpu_only(self._options, code)



def _auto_hint(name: str, options: dict) -> str:
    """For ``time="auto"`` or ``block="auto"`` (the command line's spelling): where Python chooses a knob."""
    auto = [k for k, v in options.items() if isinstance(v, str) and v == "auto"]
    if not auto:
        return ""
    return (f" (`{auto[0]}=\"auto\"` is the command line's: in Python fv.choose(frames, code, {name!r}, "
            f"{auto[0]!r}) chooses it by the estimated accuracy, fv.choose_recording from a recording)")
