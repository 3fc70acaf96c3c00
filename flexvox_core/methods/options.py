"""Typed options of a reconstruction method: name, default, the rule a value must meet, its kind.

An :class:`Option` checks a value (``None`` selects its default) and says, when it refuses one,
the option's name, the rule and the value. Its ``kind`` (:mod:`flexvox_core.methods.option_kinds`)
says how a value is typed as text and read back, and how a command line or a form offers it, without
knowing which method it belongs to. One factory per kind builds an option with its rule:
:func:`number`, :func:`integer`, :func:`choice`, :func:`flag`; a ``triple`` or ``division`` option
is an :class:`Option` with its own rule.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from numbers import Integral, Real

from flexvox_core.methods.option_kinds import CHOICE, FLAG, INTEGER, KINDS, NUMBER, Kind


@dataclass(frozen=True)
class Option:
    """One knob of a method.

    Attributes
    ----------
    name : str
        Keyword of :class:`~flexvox_core.methods.method.Method` (a Python identifier).
    default : object
        The value ``None`` stands for.
    rule : str
        What a value must be, in words ("a whole number >= 1"); errors read
        "`name` must be <rule>; got <value>".
    accepts : callable(value) -> bool
        True when a (non-None) value meets the rule.
    kind : Kind
        How a value is typed and offered (:mod:`~flexvox_core.methods.option_kinds`); given by name
        (``"division"``) or as the kind.
    label : str
        A few words for a form ("diffusion time n").
    help : str
        One sentence for ``--help`` and tool tips.
    choices : tuple
        The values of a ``choice``.
    span : (low, high, step) or None
        The range a form offers for a ``number`` or ``integer`` (validation is ``accepts``).
    shown_default : float, str or None
        What a form shows for a default of None: a number the method then uses, or words for a
        default that depends on the capture ("(K/16)²"), which a form offers as its own choice.
    """

    name: str
    default: object
    rule: str
    accepts: Callable[[object], bool] = field(repr=False, compare=False)
    kind: Kind = NUMBER
    label: str = ""
    help: str = ""
    choices: tuple = ()
    span: tuple[float, float, float] | None = None
    shown_default: float | str | None = None

    def __post_init__(self):
        if isinstance(self.kind, str) and self.kind in KINDS:
            object.__setattr__(self, "kind", KINDS[self.kind])
        if not isinstance(self.kind, Kind):
            raise ValueError(f"`kind` of option {self.name!r} must be one of {', '.join(KINDS)}; got {self.kind!r}")
        if not self.name.isidentifier():
            raise ValueError(f"an option's `name` must be a Python identifier; got {self.name!r}")

    def check(self, value):
        """``value`` if it meets the rule (None: the default); ``ValueError`` naming both otherwise."""
        if value is None:
            return self.default
        value = self.kind.coerce(self, value)  # another spelling of the kind's value (a division as text)
        if not self.accepts(value):
            raise ValueError(f"`{self.name}` must be {self.rule}; got {value!r}")
        return value


def _is_number(v) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool) and math.isfinite(v)


def number(name: str, default, *, minimum: float = 0.0, strict: bool = False, maximum: float = math.inf,
           label: str = "", help: str = "", span=None, shown_default=None, rule: str | None = None) -> Option:
    """A finite real option ``>= minimum`` (``> minimum`` when ``strict``) and ``<= maximum``."""
    def accepts(v) -> bool:
        return _is_number(v) and (v > minimum if strict else v >= minimum) and v <= maximum

    words = rule or f"a finite number {'>' if strict else '>='} {minimum:g}"
    return Option(name, default, words, accepts, NUMBER, label, help, (), span, shown_default)


def integer(name: str, default: int, *, minimum: int = 1, label: str = "", help: str = "", span=None) -> Option:
    """A whole-number option ``>= minimum``."""
    def accepts(v) -> bool:
        return isinstance(v, Integral) and not isinstance(v, bool) and v >= minimum

    return Option(name, default, f"a whole number >= {minimum}", accepts, INTEGER, label, help, (), span)


def choice(name: str, default: str, choices, *, label: str = "", help: str = "") -> Option:
    """One of ``choices``."""
    choices = tuple(choices)
    return Option(name, default, f"one of {', '.join(choices)}", lambda v: v in choices, CHOICE, label, help,
                  choices)


def flag(name: str, default: bool, *, label: str = "", help: str = "") -> Option:
    """True or False."""
    return Option(name, default, "True or False", lambda v: isinstance(v, bool), FLAG, label, help)
