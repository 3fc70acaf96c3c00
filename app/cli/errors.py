"""How the command line reports misuse: one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

EXIT_OK = 0
EXIT_FAILED = 1
"""The command ran but the answer is "no" (a code that fails a division, a damaged file)."""
EXIT_USAGE = 2
"""Bad input: a malformed option value, a missing or unreadable file."""


_CLI_WORDS = (
    # Python calls a message from the core names, said as the command line's ways (the window has its own:
    # flexvox_app.gui.models.operator_words)
    (re.compile(r"a recording is a \.zarr folder: fv\.read_video\(path\) reads a video"),
     "a recording is a .zarr folder, as flexvox simulate and flexvox capture write it"),
    (re.compile(r"read it with fv\.read_video\(path\), or lazily with fv\.open_video_store\(path\)"),
     "flexvox export writes it to TIFF, MP4, PNG or .npy"),
)


def in_cli_words(message: str) -> str:
    """``message`` with the Python calls the core's messages name (``fv.read_video(path)``) replaced by what does
    the same on the command line."""
    for pattern, words in _CLI_WORDS:
        message = pattern.sub(words, message)
    return message


class CliError(Exception):
    """Bad input on the command line; the message is printed as one line, exit status 2. Python calls the message
    names are said as the command line's ways (:func:`in_cli_words`)."""

    def __init__(self, message: object = "") -> None:
        super().__init__(in_cli_words(str(message)))


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line on stderr (no usage dump), exit 2.

    Values that start with a minus and a digit (``--tile -2x2``) are read as values, so
    their own validation names the rule instead of argparse saying "expected one argument".
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # argparse's own knob for "this looks like a negative number, not an option".
        self._negative_number_matcher = re.compile(r"^-\d")
        self._deferred: list = []

    def error(self, message: str):  # noqa: D102 - argparse's hook
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")

    def defer(self, fill) -> None:
        """Run ``fill(self)`` (it adds arguments or sets the description) only when this parser is used: when it
        parses, or prints its help or usage. A subcommand whose arguments need heavy imports (the methods'
        registry, numpy) defers them, so that another command, ``--help`` and the start-up window do not pay for
        them."""
        self._deferred.append(fill)

    def complete(self) -> None:
        """Run the deferred fills (see :meth:`defer`)."""
        while self._deferred:
            self._deferred.pop(0)(self)

    def parse_known_args(self, args=None, namespace=None):  # noqa: D102 - argparse's
        self.complete()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:  # noqa: D102 - argparse's
        self.complete()
        return super().format_help()

    def format_usage(self) -> str:  # noqa: D102 - argparse's
        self.complete()
        return super().format_usage()


def defer(parser, fill) -> None:
    """``parser.defer(fill)`` on a :class:`OneLineParser`; on another parser, ``fill(parser)`` at once."""
    if isinstance(parser, OneLineParser):
        parser.defer(fill)
    else:
        fill(parser)


def fail(prog: str, message: str) -> int:
    """Print ``prog: error: message`` on stderr and return :data:`EXIT_USAGE`."""
    print(f"{prog}: error: {in_cli_words(message)}", file=sys.stderr)
    return EXIT_USAGE


def positive_fps(text: str) -> float:
    """``--fps``: a playback rate above 0 and at most 1000 frames per second."""
    from flexvox_core.video_io import check_fps

    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--fps must be a number of frames per second; got {text!r}") from None
    try:
        return check_fps(value)
    except ValueError:
        raise ValueError(f"--fps must be above 0 and at most 1000 frames per second; got {text!r}") from None


def check_fps_output(fps: float | None, output: Path) -> None:
    """``--fps`` is an .mp4's playback rate: given with another output it would be ignored without a word, so it is
    refused (``CliError``)."""
    if fps is not None and output.suffix.lower() != ".mp4":
        raise CliError(f"--fps sets an .mp4's playback rate; -o {output} is not an .mp4 (its time step comes from the "
                       "recording's rates): leave --fps out, or write an .mp4")


def arg_type(parse):
    """Wrap a ``ValueError``-raising parser as an argparse ``type=`` (message kept)."""

    def convert(text):
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    convert.__name__ = getattr(parse, "__name__", "value")
    return convert
