"""How each kind of option is written, read back and offered: one :class:`Kind` per kind.

An :class:`~flexvox_core.methods.options.Option` checks a value against its own rule; its kind says how
a value of that sort is typed as text and read back (:meth:`Kind.parse`, :meth:`Kind.format`), how the
command line takes it (:meth:`Kind.flag`, :meth:`Kind.arguments`, :meth:`Kind.help_words`) and which
field a form shows for it (:attr:`Kind.field`). The command line (``app/cli/method_options.py``) and the
options form that Review and the napari plugin share (``app/gui/widgets/options_form.py``) ask the kind;
neither parses, formats or picks a widget by a kind's name.

=============  ===============================================  ===============  ===============
kind           values                                           command line     form field
=============  ===============================================  ===============  ===============
``number``     a real number (``default`` may be None)          ``--name X``     ``real``
``integer``    a whole number                                   ``--name N``     ``whole``
``choice``     one of ``choices``                               ``--name C``     ``list``
``flag``       True / False                                     ``--[no-]name``  ``check``
``triple``     three numbers, e.g. a tensor (cx, cy, ct)        ``--name a,b,c`` ``text``
``division``   a :class:`~flexvox_core.divisions.Division`      ``--name a,b,c`` ``text``
=============  ===============================================  ===============  ===============

A kind reads text; whether the value meets the option's rule is the option's own check
(:meth:`Option.check <flexvox_core.methods.options.Option.check>`), which every front end reaches through
:class:`~flexvox_core.methods.Method`.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod

FIELDS = ("check", "list", "whole", "real", "text")
"""The fields a form offers: a check box, a list to pick from, a whole-number box, a real-number box, a text
line (read with :meth:`Kind.parse`)."""

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


class Kind(ABC):
    """How one kind of option is typed, shown and offered (subclasses set the class attributes)."""

    name: str = ""
    """The kind's name (what :class:`~flexvox_core.methods.options.Option` is given as ``kind``)."""
    field: str = "text"
    """The field a form shows (one of :data:`FIELDS`)."""
    metavar: str | None = None
    """How ``--help`` writes a value (None: the option takes none, or one of its choices)."""
    syntax: str = ""
    """What typed text must be, in words: "`name` must be <syntax>; got <text>" (:meth:`syntax_of`)."""
    needs_tile: bool = False
    """True: a value read from text depends on the capture's tile (:meth:`parse` takes ``tile``)."""
    says_default: bool = True
    """Whether ``--help`` quotes the default as a value (a flag's name says it; a division's default is words)."""

    def __repr__(self) -> str:
        return f"<option kind {self.name}>"

    # ------------------------------------------------------------------ text
    def parse(self, option, text, *, name: str | None = None, tile=None):
        """The value typed as ``text`` (``tile``: the capture's, for :attr:`needs_tile` kinds; None checks
        nothing against it).

        Raises
        ------
        ValueError
            Text that is not of this kind: "<name> must be <syntax>; got <text>" (``name``: how the front end
            calls the option, ``--tensor`` say; default: the option's name in backquotes).
        """
        value = self._read(option, str(text).strip(), tile)
        if value is None:
            raise ValueError(f"{name or f'`{option.name}`'} must be {self.syntax_of(option)}; got {text!r}")
        return value

    def syntax_of(self, option) -> str:
        """What typed text of ``option`` must be, in words (default :attr:`syntax`)."""
        return self.syntax

    @abstractmethod
    def _read(self, option, text: str, tile):
        """The value of ``text``, or None when it is not of this kind."""

    def coerce(self, option, value):
        """A value given in a spelling of this kind's other than its own type, as that type (a division typed
        as text or given as three numbers: a :class:`~flexvox_core.divisions.Division`); anything else as it is
        (the option's rule then judges it)."""
        return value

    def format(self, value) -> str:
        """``value`` as text that :meth:`parse` reads back ("" for None, words as they are)."""
        return "" if value is None else str(value)

    def default_text(self, option) -> str:
        """The default as a field or ``--help`` shows it: the option's ``shown_default`` for a default of None
        (a number, or words such as "(K/16)²"), else the default itself; "" when there is nothing to show."""
        shown = option.shown_default if option.default is None else option.default
        return shown if isinstance(shown, str) else self.format(shown)

    # ------------------------------------------------------------------ command line
    def flag(self, option) -> str:
        """The command-line flag: ``--name`` (underscores as dashes)."""
        return f"--{option.name.replace('_', '-')}"

    def arguments(self, option, flag: str) -> dict:
        """argparse's keywords for the flag (``type`` raises ``ValueError`` naming the flag and the syntax;
        a :attr:`needs_tile` kind keeps its text, read later with the tile)."""
        if self.needs_tile:
            return {"metavar": self.metavar}
        return {"type": lambda text: self.parse(option, text, name=flag), "metavar": self.metavar}

    def help_words(self, option) -> str:
        """What ``--help`` says of the option (before the methods it goes with and its default)."""
        return option.help or option.label or option.name


class Number(Kind):
    """A real number, typed as Python reads a float."""

    name, field, metavar, syntax = "number", "real", "X", "a number"

    def _read(self, option, text, tile):
        try:
            return float(text)
        except ValueError:
            return None

    def format(self, value) -> str:
        if value is None or isinstance(value, str):
            return super().format(value)
        return f"{value:g}"


class Integer(Kind):
    """A whole number."""

    name, field, metavar, syntax = "integer", "whole", "N", "a whole number"

    def _read(self, option, text, tile):
        try:
            return int(text)
        except ValueError:
            return None


class Choice(Kind):
    """One of the option's choices (argparse's ``choices``)."""

    name, field = "choice", "list"

    def _read(self, option, text, tile):
        return next((c for c in option.choices if str(c) == text), None)

    def syntax_of(self, option) -> str:
        return f"one of {', '.join(map(str, option.choices))}"

    def arguments(self, option, flag: str) -> dict:
        return {"choices": option.choices}


class Flag(Kind):
    """True or False: on the command line a flag that turns the default round."""

    name, field, syntax, says_default = "flag", "check", "true or false", False
    _WORDS = {"true": True, "yes": True, "on": True, "1": True, "false": False, "no": False, "off": False, "0": False}

    def _read(self, option, text, tile):
        return self._WORDS.get(text.lower())

    def format(self, value) -> str:
        return "" if value is None else ("true" if value else "false")

    def flag(self, option) -> str:
        """``--no-name`` for a flag that is on by default, ``--name`` otherwise."""
        dashed = option.name.replace("_", "-")
        return f"--no-{dashed}" if option.default else f"--{dashed}"

    def arguments(self, option, flag: str) -> dict:
        return {"action": "store_const", "const": not option.default}

    def help_words(self, option) -> str:
        return f"{'no ' if option.default else ''}{option.label or option.name}"


class Triple(Kind):
    """Three numbers, typed ``a,b,c`` (or ``axbxc``)."""

    name, metavar, syntax = "triple", "a,b,c", "three numbers separated by commas"

    def _read(self, option, text, tile):
        parts = [p.strip() for p in re.split(r"[,xX]", text) if p.strip()]
        if len(parts) == 3 and all(_NUMBER.fullmatch(p) for p in parts):
            return tuple(float(p) for p in parts)
        return None

    def format(self, value) -> str:
        if value is None or isinstance(value, str):
            return super().format(value)
        return ",".join(f"{float(v):g}" for v in value)


class DivisionKind(Kind):
    """A :class:`~flexvox_core.divisions.Division`, typed ``a,b,c`` (or ``AxBxC``) and read
    against the capture's tile."""

    name, metavar, needs_tile, says_default = "division", "a,b,c", True, False
    syntax = "three whole numbers a,b,c (rows, columns, slots of the division), e.g. 2,2,4"

    def _read(self, option, text, tile):
        from flexvox_core.divisions import parse_division

        parts = [p.strip() for p in text.replace("x", ",").split(",")]  # a,b,c (or AxBxC)
        if len(parts) != 3 or not all(p.isdigit() for p in parts):
            return None
        return parse_division("x".join(parts), None if tile is None else tuple(tile))  # its own words on the tile

    def coerce(self, option, value):
        """``"2x2x4"``, ``"2,2,4"`` or ``(2, 2, 4)`` as the Division (:func:`~flexvox_core.divisions.parse_division`,
        its own words for a bad one); a Division or anything else as it is."""
        from numbers import Integral

        from flexvox_core.divisions import parse_division

        if isinstance(value, str):
            return self.parse(option, value)
        if (isinstance(value, tuple | list) and len(value) == 3
                and all(isinstance(v, Integral) and not isinstance(v, bool) for v in value)):
            return parse_division("x".join(str(int(v)) for v in value))
        return value

    def format(self, value) -> str:
        if value is None or isinstance(value, str):
            return super().format(value)
        return f"{value.a},{value.b},{value.c}"


NUMBER, INTEGER, CHOICE, FLAG, TRIPLE, DIVISION = Number(), Integer(), Choice(), Flag(), Triple(), DivisionKind()
KINDS: dict[str, Kind] = {k.name: k for k in (NUMBER, INTEGER, CHOICE, FLAG, TRIPLE, DIVISION)}
"""Every kind by name."""
