"""The colours status lines use, and a line of text in one of them (Qt rich text, escaped)."""

from __future__ import annotations

import html

RED = "#c0392b"
"""Refused, failed, wrong."""
GREEN = "#1e8449"
"""Done, accepted."""
AMBER = "#b7950b"
"""Worth reading: a warning or a note."""
GREY = "#7f8c8d"
"""Not run, off."""


def coloured(text: str, colour: str) -> str:
    """``text`` (escaped) in ``colour`` for a rich-text QLabel."""
    return f"<span style='color:{colour}'>{html.escape(text)}</span>"
