"""What a reconstruction method is, as an object: :class:`MethodSpec`, and what it returns.

A method is one subclass of :class:`MethodSpec` in its own module of
:mod:`flexvox_core.methods`, listed once in :mod:`~flexvox_core.methods.registry`. It says

- its ``name``, a one-line ``title`` and how it trades spatial for temporal resolution (``trade``);
- its typed :attr:`~MethodSpec.option_specs` with defaults (:class:`~flexvox_core.methods.options.Option`), and
  :meth:`~MethodSpec.build`: the options object its algorithm takes, made once from their checked values
  (motion-aware's :class:`~flexvox_core.motion.options.MotionOptions`; by default a frozen dataclass of them);
- :meth:`~MethodSpec.run`: the reconstruction of one identity-code capture;
- :meth:`~MethodSpec.overlap`: the camera frames of context a time chunk needs on each side
  (None: it cannot run in chunks);
- its capabilities: :attr:`~MethodSpec.needs_sample_range` (every chunk gets the whole
  recording's sample range), :attr:`~MethodSpec.takes_missing` (dropped frames),
  :meth:`~MethodSpec.takes_multiplexed` (multiplexed captures from their own forward model)
  and :attr:`~MethodSpec.extras` (per-sub-frame arrays it can return beside the video, trimmed to a
  chunk like the video);
- :meth:`~MethodSpec.label` (a short description), :meth:`~MethodSpec.as_dict` (what metadata records and
  what keys a bench row), and how near a bench row's options are to given values
  (:attr:`~MethodSpec.bench_axis`, :meth:`~MethodSpec.bench_rank`).

Callers never compare method names: they ask these attributes. The options' values are checked by
:meth:`MethodSpec.resolve` into a dict (``values``: what labels, records and bench rows read) and built
once into the options object (``options``: what :meth:`~MethodSpec.run`, :meth:`~MethodSpec.overlap` and
the other capabilities read); :class:`~flexvox_core.methods.method.Method` holds both and is the value
users hold.
"""

from __future__ import annotations

import json
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields, make_dataclass
from functools import cache

import numpy as np

from flexvox_core.gaps import max_gap
from flexvox_core.methods.options import Option
from flexvox_core.reprs import describe_array, html_table, short_repr


@dataclass
class MethodOutput:
    """A reconstruction and its extras.

    Attributes
    ----------
    video : ndarray (S, H, W)
        The video (a method's own :meth:`MethodSpec.run` may leave it outside [0, 1]; the
        runner returns it clipped to [0, 1] as float32).
    extras : dict of str to ndarray (S, ...)
        Per-sub-frame arrays the method returned beside the video (time first), e.g.
        motion-aware's ``flow`` (S, H, W, 2) and ``tr`` (S, H, W); empty unless asked for.
    interpolated : ndarray (S,) bool or None
        Sub-frames of dropped camera frames, filled from both sides (:mod:`flexvox_core.gaps`);
        None when no frame was missing.
    device : str
        Where it ran: ``cpu`` or ``cuda``.
    device_note : str or None
        Why it ran on the CPU when the GPU was asked for (None otherwise).
    """

    video: np.ndarray
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    interpolated: np.ndarray | None = None
    device: str = "cpu"
    device_note: str | None = None

    def _facts(self) -> list[tuple[str, str]]:
        filled = 0 if self.interpolated is None else int(np.count_nonzero(self.interpolated))
        return [("video", describe_array(self.video)),
                *((f"extras[{name!r}]", describe_array(a)) for name, a in self.extras.items()),
                ("interpolated", f"{filled} sub-frames"),
                ("device", self.device + (f" ({self.device_note})" if self.device_note else ""))]

    def __repr__(self) -> str:
        facts = self._facts()
        return short_repr("MethodOutput", [f"{k} {v}" for k, v in facts[:-1]] + [f"on {facts[-1][1]}"])

    def _repr_html_(self) -> str:
        return html_table("MethodOutput", self._facts())


class MethodSpec(ABC):
    """Base of every reconstruction method (see the module docstring).

    Subclasses set the class attributes and implement :meth:`run`, :meth:`overlap` and
    :meth:`label`; the rest have defaults.
    """

    name: str = ""
    """What users type (``--method NAME``) and what metadata records."""
    title: str = ""
    """One line: what the method is."""
    trade: str = ""
    """How it trades spatial for temporal resolution, in one sentence."""
    option_specs: tuple[Option, ...] = ()
    """Its knobs, in the order forms show them."""
    needs_sample_range: bool = False
    """True: :meth:`run` takes ``sample_range``, the whole recording's (lo, hi) sample range,
    so that a run in chunks equals the whole."""
    extras: tuple[str, ...] = ()
    """Names of the per-sub-frame arrays :meth:`run` returns when ``extras=True``."""
    bench_axis: str | None = None
    """The option the bench sweeps on a log scale (figures are interpolated along it), if any."""
    takes_missing: bool = False
    """True: :meth:`run` takes ``missing`` (dropped frames) itself, leaves them out of its samples
    and fills their sub-frames from both sides (:mod:`flexvox_core.gaps`). False: the runner gives
    it the dropped frames interpolated from their neighbours and bridges their sub-frames after."""
    # ------------------------------------------------------------------ options
    def option(self, name: str) -> Option:
        """The option called ``name``; ``ValueError`` naming this method's options otherwise."""
        for o in self.option_specs:
            if o.name == name:
                return o
        raise ValueError(f"`{name}` is not an option of {self.name} (its options: {self.option_list()})")

    def has_option(self, name: str) -> bool:
        """True when the method has an option called ``name``."""
        return any(o.name == name for o in self.option_specs)

    def option_list(self) -> str:
        """The option names in words ("none" when there are none)."""
        return ", ".join(o.name for o in self.option_specs) or "none"

    def resolve(self, given: dict) -> dict:
        """Every option's value: ``given`` checked, the defaults for the rest (and for None).

        Raises
        ------
        ValueError
            An unknown option or a value that breaks its option's rule (naming both).
        """
        for name in given:
            if not self.has_option(name):
                raise ValueError(f"`{name}` is not an option of {self.name} (its options: {self.option_list()})")
        values = {o.name: o.check(given.get(o.name)) for o in self.option_specs}
        self.validate(values)
        return values

    def validate(self, values: dict) -> None:  # noqa: B027 - an optional hook: most methods have no such check
        """Checks across options (``ValueError``); the default has none."""

    def build(self, values: dict):
        """The options object :meth:`run` and the capabilities below take, made once from checked ``values``
        (``ValueError`` where it checks more): frozen, its attributes the option names. Default: a frozen
        dataclass of one field per option (:func:`options_type`)."""
        return options_type(type(self))(**values)

    # ------------------------------------------------------------------ running
    # ``options`` below is what :meth:`build` made.
    @abstractmethod
    def overlap(self, options, K: int) -> int | None:
        """Camera frames of context a chunk needs on each side (None: cannot run in chunks)."""

    def takes_multiplexed(self, options) -> bool:
        """True: :meth:`run` also takes a multiplexed capture with these options (the normalised camera frames, each
        a sum of its open slots, and their 0/1 code) and reconstructs it from that forward model
        (:mod:`flexvox_core.reconstruct.multiplexed`). False (the default): the reader demultiplexes a multiplexed
        recording per tile for it (the fallback, which assumes the scene constant over a tile). Dropped frames of a
        multiplexed capture are always interpolated by the runner."""
        return False

    def accepts_multiplexed(self, options) -> bool:
        """Deprecated name of :meth:`takes_multiplexed` (removed in the next release)."""
        warnings.warn("MethodSpec.accepts_multiplexed is deprecated and will be removed in the next release: call "
                      "takes_multiplexed(options)", DeprecationWarning, stacklevel=2)
        return self.takes_multiplexed(options)

    def __init_subclass__(cls, **kwargs) -> None:
        """Adapt a subclass written against the deprecated names: a ``takes_multiplexed = True`` class flag, or an
        ``accepts_multiplexed(options)`` method, becomes :meth:`takes_multiplexed` (with a ``DeprecationWarning``)."""
        super().__init_subclass__(**kwargs)
        own = vars(cls)
        if "accepts_multiplexed" in own:
            warnings.warn(f"{cls.__name__}.accepts_multiplexed is deprecated and will be removed in the next release: "
                          "name the method takes_multiplexed(self, options)", DeprecationWarning, stacklevel=2)
            cls.takes_multiplexed = own["accepts_multiplexed"]  # type: ignore[method-assign]
        elif isinstance(own.get("takes_multiplexed"), bool):
            flag = own["takes_multiplexed"]
            warnings.warn(f"{cls.__name__}.takes_multiplexed as a class flag ({flag}) is deprecated and will be "
                          "removed in the next release: define takes_multiplexed(self, options) returning it",
                          DeprecationWarning, stacklevel=2)
            cls.takes_multiplexed = lambda self, options: flag  # type: ignore[method-assign]

    def max_gap(self, options, K: int) -> int:
        """The longest run of dropped frames it bridges (:func:`flexvox_core.gaps.max_gap`)."""
        return max_gap(self.overlap(options, K))

    gpu_bytes_per_voxel: int = 0
    """Device memory a GPU run holds per voxel of a chunk (its context included); the runner shortens chunks that
    would not fit the card's free memory (:meth:`gpu_voxel_bytes`)."""

    def gpu_voxel_bytes(self, options, K: int, H: int, W: int) -> float:
        """Device memory a GPU run holds per voxel of a chunk of H×W pictures at K slots (its context included);
        0: not known. Default: :attr:`gpu_bytes_per_voxel`."""
        return self.gpu_bytes_per_voxel

    def cpu_only(self, options, code) -> str | None:
        """Why this method runs on the CPU with these options and code even when the GPU is asked for (a short
        phrase), or None when it runs on the GPU (:mod:`flexvox_core.gpu`). Default: it has no GPU path."""
        return f"{self.name} has no GPU path"

    @abstractmethod
    def run(self, frames: np.ndarray, code: np.ndarray, options, *, sample_range=None,
            extras: bool = False, missing=None, device: str = "cpu") -> MethodOutput:
        """Reconstruct an identity-code capture (or, when :meth:`takes_multiplexed`, a multiplexed one).

        Parameters
        ----------
        frames : ndarray (F, H, W)
        code : ndarray (m, n, K) bool, identity code (or any 0/1 code, see :meth:`takes_multiplexed`)
        options
            What :meth:`build` made of every option's value.
        sample_range : (lo, hi) or None
            Methods with :attr:`needs_sample_range`: the whole recording's sample range. (A method written with
            ``value_range``, its deprecated name, still gets it for one release, with a ``DeprecationWarning``.)
        extras : bool
            Also return the arrays named in :attr:`extras`.
        missing : ndarray (F,) bool or None
            Methods with :attr:`takes_missing`: the frames the camera dropped.
        device : {"cpu", "cuda"}
            ``cuda`` only when :meth:`cpu_only` is None for these values and code.

        Returns
        -------
        MethodOutput
            ``video`` (F·K, H, W), not yet clipped. The runner clips a writable float32 ``video`` in place
            (unless it shares memory with ``frames`` or an extra): return memory the method owns, or a
            read-only array.
        """

    # ------------------------------------------------------------------ description
    @abstractmethod
    def label(self, values: dict) -> str:
        """Short human-readable description (also the bench's method column)."""

    def as_dict(self, values: dict) -> dict:
        """Metadata form: the name and every option's value (JSON-friendly); a bench row carries it."""
        return {"name": self.name, **values}

    def bench_rank(self, row: dict, values: dict, code) -> tuple[tuple, bool]:
        """How near a bench row's options (the :meth:`as_dict` it carries) are to ``values``, apart from
        :attr:`bench_axis`: a sort key (smaller is nearer; rows with the smallest key form the family
        figures are taken from) and whether the row matches exactly. Default: the options that differ,
        counted (none: exact)."""
        differ = sum(_json(row.get(k)) != _json(v) for k, v in self.as_dict(values).items() if k != self.bench_axis)
        return (differ,), differ == 0

    def __repr__(self) -> str:
        return f"<method {self.name}>"


@cache
def options_type(spec_type: type[MethodSpec]) -> type:
    """The frozen dataclass ``<Method>Options`` of a method class: one field per option spec, its default the
    option's. What :meth:`MethodSpec.build` makes by default."""
    return make_dataclass(f"{spec_type.__name__}Options",
                          [(o.name, object, field(default=o.default)) for o in spec_type.option_specs], frozen=True)


def keywords(options) -> dict:
    """A frozen options object's values by name (the keywords of an algorithm whose parameters they are)."""
    return {f.name: getattr(options, f.name) for f in fields(options)}


def _json(value) -> str:
    """A value as a bench row's JSON holds it (tuples as lists), for comparison."""
    return json.dumps(value, sort_keys=True)
