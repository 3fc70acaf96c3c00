"""The reconstruction options that ``reconstruct``, ``export`` and ``batch`` share, and the
:class:`~flexvox_core.methods.Method` they describe.

The options are the registered methods' own (:mod:`flexvox_core.methods.registry`): one flag per
option name, typed by the option's kind, its help naming each method's default. A flag the
chosen method has no option for is refused, naming the methods it goes with. Where a command
offers it (``reconstruct``), a knob with default candidates (:data:`flexvox_core.choice.AUTO_KNOBS`:
``--time``, ``--block``) also takes ``auto``: chosen by the estimated PSNR (:func:`auto_knob`).
"""

from __future__ import annotations

from flexvox_app.cli.errors import CliError, arg_type

_FLAG_NAMES = {"refine_time": "--refine"}
"""Flags whose name is not the option's (``--refine`` is older than ``refine_time``)."""

AUTO = "auto"
"""The value of a knob flag that asks for the knob to be chosen by the estimated PSNR."""


def _options():
    """Every registered option name with the first option object and the methods that have it."""
    from flexvox_core.methods import specs

    table: dict[str, tuple] = {}
    for spec in specs():
        for o in spec.option_specs:
            first, owners = table.get(o.name, (o, []))
            owners.append(spec)
            table[o.name] = (first, owners)
    return table


def _flag(option) -> str:
    return _FLAG_NAMES.get(option.name) or option.kind.flag(option)


def flag_of(name: str) -> str:
    """The command-line flag of option ``name`` (``--time``, ``--refine``)."""
    return _flag(_options()[name][0])


def _help(option, owners) -> str:
    from flexvox_core.methods import specs

    words = option.kind.help_words(option)
    if len(owners) < len(specs()):
        words = f"{' and '.join(s.name for s in owners)}: {words}"
    defaults = []
    for s in owners:
        o = s.option(option.name)
        if "(default" in (o.help or "") or not o.kind.says_default:
            continue  # its help says the default in words (motion-aware's refinement: (K/16)²), or its flag does
        shown = o.kind.default_text(o)
        if shown:
            defaults.append(shown + (f" for {s.name}" if len(owners) > 1 else ""))
    return words + (f" (default {'; '.join(defaults)})" if defaults else "")


def _chunk(text: str) -> int:
    """``--chunk``: a whole number of camera frames, at least 1."""
    if not text.strip().isdigit() or int(text) < 1:
        raise ValueError(f"--chunk must be a whole number of camera frames >= 1; got {text!r}")
    return int(text)


def _auto_owners(name: str) -> list[str]:
    """The methods whose option ``name`` can be chosen by the estimate (``auto``)."""
    from flexvox_core.choice import AUTO_KNOBS

    return [m for m, knobs in AUTO_KNOBS.items() if name in knobs]


def _or_auto(parse):
    """``parse``, with ``auto`` read as :data:`AUTO`."""
    def read(text):
        return AUTO if str(text).strip() == AUTO else parse(text)

    return read


def method_name(text: str) -> str:
    """``--method``: a registered method's exact name; a near miss is refused with the name meant
    (:func:`flexvox_core.methods.registry.meant`, in the command line's words)."""
    from flexvox_core.methods.registry import meant, names

    if text in names():
        return text
    raise ValueError(f"--method must be one of {', '.join(names())}; got {text!r}{meant(text, flags=True)}")


def add_method_options(p, *, chunk: int, auto: bool = False) -> None:
    """Add ``--method``, every registered method's options and ``--chunk F`` (default ``chunk``
    camera frames) to parser ``p``; ``auto``: the knobs with default candidates also take ``auto``
    (:func:`auto_knob`)."""
    from flexvox_core.methods import DEFAULT, names

    p.add_argument("--method", choices=names(), type=arg_type(method_name), default=DEFAULT,
                   help=f"default: {DEFAULT}")
    for name, (o, owners) in _options().items():
        kw = o.kind.arguments(o, _flag(o))
        words = _help(o, owners)
        choosable = auto and _auto_owners(name)
        if choosable:
            if "type" in kw:
                kw["type"] = _or_auto(kw["type"])
            kw["metavar"] = f"{kw.get('metavar') or 'X'}|auto"
            words += (f"; auto ({' and '.join(choosable)}): try each candidate "
                      f"({_candidates_words(name)}), estimate each result's PSNR from the recording alone and keep "
                      "the best; prints every candidate's estimate and what choosing cost (each candidate: a "
                      "reconstruction and the estimate's probe run)")
        if "type" in kw:
            kw["type"] = arg_type(kw["type"])
        p.add_argument(_flag(o), dest=name, default=None, help=words, **kw)
    p.add_argument("--chunk", type=arg_type(_chunk), default=chunk, metavar="F",
                   help=f"camera frames per chunk (default {chunk})")
    add_device_option(p)


def method_flags_given(args) -> list[str]:
    """The method's flags on the command line: ``--method`` where the parser's default for it is None (not given),
    and every method option given (their defaults are None)."""
    given = ["--method"] if getattr(args, "method", None) is not None else []
    return given + [flag_of(name) for name in _options() if getattr(args, name, None) is not None]


def add_device_option(p) -> None:
    """Add ``--device auto|cpu|cuda`` to parser ``p``."""
    from flexvox_core.gpu.device import DEVICES

    p.add_argument("--device", choices=DEVICES, default="auto",
                   help="where the reconstruction runs: an NVIDIA GPU (cuda; needs the gpu extra), the CPU, or auto "
                        "(default: the GPU when one is usable). Methods without a GPU path run on the CPU and say so")


def resolved_device(args) -> str:
    """``--device`` resolved to ``cpu`` or ``cuda`` before any work; ``cuda`` without a usable GPU is a
    :class:`~flexvox_app.cli.errors.CliError` naming what is missing (exit 2)."""
    from flexvox_core.gpu.device import DeviceUnavailable, resolve_device

    try:
        return resolve_device(getattr(args, "device", "cpu"))
    except DeviceUnavailable as exc:
        raise CliError(f"--device cuda: {exc.reason}") from None


def device_line(out) -> str:
    """One line saying where a reconstruction ran (and why on the CPU when the GPU was asked for)."""
    from flexvox_core.gpu.device import describe_gpus, simulator

    if out.device == "cuda":
        if simulator():
            return f"device: cuda ({SIMULATOR})"
        gpus = describe_gpus()
        return f"device: cuda ({gpus[0].name})" if gpus else "device: cuda"
    return f"device: cpu ({out.device_note})" if out.device_note else "device: cpu"


SIMULATOR = ("numba-cuda's simulator, NUMBA_ENABLE_CUDASIM=1: the GPU kernels run on the CPU, one thread at a time; "
             "no GPU was used")
"""What the device line says when numba-cuda's simulator stands in for the GPU."""


def device_record(out) -> dict:
    """What a reconstruction's provenance records of its device."""
    from flexvox_core.gpu.device import describe_gpus, simulator

    record = {"device": out.device}
    if out.device == "cuda" and simulator():
        record["gpu"] = "numba-cuda's simulator"
    elif out.device == "cuda":
        gpus = describe_gpus()
        if gpus:
            record["gpu"] = gpus[0].name
    if out.device_note:
        record["device_note"] = out.device_note
    return record


def _foreign(given: list[str], method: str) -> str:
    """The refusal of flags ``given`` that ``method`` has no option for."""
    table = _options()
    groups: dict[tuple[str, ...], list[str]] = {}
    for name in given:
        groups.setdefault(tuple(s.name for s in table[name][1]), []).append(_flag(table[name][0]))
    parts = []
    for owners, flags in groups.items():
        verb = "goes" if len(flags) == 1 else "go"
        parts.append(f"{' and '.join(flags)} {verb} with --method {' or '.join(owners)}")
    owners, _ = next(iter(groups.items()))
    only = [_flag(o) for o, specs_ in table.values() if tuple(s.name for s in specs_) == owners]
    listed = only[0] if len(only) == 1 else f"{', '.join(only[:-1])} and {only[-1]}"
    return (f"{'; '.join(parts)}, not {method} ({listed} {'goes' if len(only) == 1 else 'go'} with "
            f"--method {' or '.join(owners)} only)")


def _candidates_words(name: str) -> str:
    from flexvox_core.choice import candidates_for

    if name != "time":
        return "every division the code supports"
    return "; ".join(f"n = {', '.join(f'{t:g}' for t in candidates_for(m, name, None))} for {m}"
                     for m in _auto_owners(name))


def auto_knob(args) -> str | None:
    """The option given as ``auto`` (to be chosen by the estimated PSNR), or None.

    Raises
    ------
    ValueError
        More than one knob given as ``auto``, or ``auto`` for a knob of ``--method`` that has no candidates to
        choose from (naming the methods whose knob has).
    """
    table = _options()
    autos = [name for name in table if getattr(args, name, None) == AUTO]
    if len(autos) > 1:
        raise ValueError(f"only one knob can be auto; got {' and '.join(_flag(table[n][0]) + ' auto' for n in autos)}")
    if not autos:
        return None
    name = autos[0]
    owners = _auto_owners(name)
    if args.method not in owners and any(s.name == args.method for s in table[name][1]):
        raise ValueError(f"{_flag(table[name][0])} auto goes with --method {' or '.join(owners)}, not {args.method} "
                         "(no candidates to choose from)")
    return name


def method_from_args(args, tile, *, auto: bool = False):
    """The :class:`~flexvox_core.methods.Method` the options describe (``auto``: a knob given as ``auto`` is left
    at its default, for :func:`auto_knob`'s choice; else ``auto`` is read as any other value, and refused).

    Raises
    ------
    ValueError
        A flag the method has no option for (naming the methods it goes with), or a bad value.
    """
    from flexvox_core.methods import Method, get

    spec = get(args.method)
    table = _options()
    given = {name: getattr(args, name) for name in table if getattr(args, name, None) is not None}
    foreign = [name for name in given if not spec.has_option(name)]
    if foreign:
        raise ValueError(_foreign(foreign, spec.name))
    if auto:
        given = {name: value for name, value in given.items() if value != AUTO}
    for name, value in given.items():
        o = spec.option(name)
        if o.kind.needs_tile:  # kept as typed: read with the recording's tile
            given[name] = o.kind.parse(o, value, name=_flag(o), tile=tile)
    try:
        return Method(spec.name, **given)
    except ValueError as exc:  # the option's rule, said with its flag (`refine_time` is --refine here)
        message = str(exc)
        for name in given:
            message = message.replace(f"`{name}`", _flag(spec.option(name)))
        raise ValueError(message) from None
