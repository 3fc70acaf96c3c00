"""The errors of writing outputs (:mod:`flexvox_core.output_files`, :mod:`flexvox_core.writer_lock`)."""

from __future__ import annotations

#: What a refusal of an existing output tells a Python caller (``write_video``, ``reconstruct_batch``, recordings,
#: captures): the keyword to pass.
OVERWRITE_HINT = "choose another path, or pass overwrite=True to replace it"
#: The same for the command line, whose commands take ``--overwrite``.
CLI_OVERWRITE_HINT = "use --overwrite to replace it"


class OutputError(ValueError):
    """An output that may not be written; the message names the path and the rule."""


class OutputBusyError(OutputError):
    """Another process is writing this output; the message names it, :attr:`holder` too."""

    def __init__(self, message: str, holder: str = "another process"):
        super().__init__(message)
        self.holder = holder
