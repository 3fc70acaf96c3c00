"""A status line that keeps its height: the buttons below it never move when its text changes.

A word-wrapped label grows with its text, and everything under it moves (a button the operator was
about to click moved 28 px). :class:`StatusLine` has a fixed height of ``lines`` lines: a text that
fits is shown as it is (rich text, colours kept); a longer one is shown as plain text cut to the
lines with "…" at the end, in the text's first colour, and the whole text is the tooltip.
:meth:`StatusLine.text` returns the whole text.
"""

from __future__ import annotations

import html
import re

from PySide6.QtCore import Qt
from PySide6.QtGui import QFontMetrics, QTextDocument, QTextLayout
from PySide6.QtWidgets import QLabel, QSizePolicy, QWidget

_COLOUR = re.compile(r"color:\s*(#[0-9a-fA-F]{3,8}|[a-z]+)")


def plain_lines(text: str, width: int, metrics: QFontMetrics, font) -> list[str]:
    """``text`` (plain, with newlines) broken into the lines a label ``width`` pixels wide shows."""
    out = []
    for paragraph in text.split("\n"):
        if not paragraph:
            out.append("")
            continue
        layout = QTextLayout(paragraph, font)
        layout.beginLayout()
        while True:
            line = layout.createLine()
            if not line.isValid():
                break
            line.setLineWidth(width)
            out.append(paragraph[line.textStart(): line.textStart() + line.textLength()].rstrip())
        layout.endLayout()
    return out


class StatusLine(QLabel):
    """A rich-text status label of a fixed number of lines (see the module docstring).

    Parameters
    ----------
    text : str
        Rich text (escape plain text with :func:`html.escape`, or use
        :func:`~flexvox_app.gui.widgets.rich_text.coloured`).
    lines : int
        Its height, in lines of its font.
    """

    def __init__(self, text: str = "", *, lines: int = 2, parent: QWidget | None = None):
        super().__init__(parent)
        if lines < 1:
            raise ValueError(f"`lines` must be at least 1; got {lines}")
        self.lines = int(lines)
        self._full = ""
        self.setWordWrap(True)
        self.setTextFormat(Qt.TextFormat.RichText)
        self.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self._fix_height()
        self.setText(text)

    def _fix_height(self) -> None:
        super().setText("<br>".join(["Xg"] * self.lines))
        self.setFixedHeight(super().heightForWidth(10_000))

    def text(self) -> str:  # noqa: D102 - QLabel's, returning the whole text
        return self._full

    def shown_text(self) -> str:
        """The text as drawn (cut with "…" when the whole does not fit)."""
        return super().text()

    @property
    def elided(self) -> bool:
        """True when the text is cut to fit (its whole is the tooltip)."""
        return super().text() != self._full

    def setText(self, text: str) -> None:  # noqa: N802 - Qt's name
        """Show ``text`` (rich text); cut to the lines when it does not fit."""
        self._full = str(text)
        self._fit()

    def resizeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Fit the text again at the new width."""
        super().resizeEvent(event)
        self._fit()

    def _fit(self) -> None:
        full = self._full
        super().setText(full)
        width = self.contentsRect().width()
        if not full or width <= 0 or super().heightForWidth(self.width()) <= self.height():
            self.setToolTip("")
            return
        doc = QTextDocument()
        doc.setHtml(full)
        plain = doc.toPlainText().replace("\u2028", "\n")
        lines = plain_lines(plain, max(1, width - 4), self.fontMetrics(), self.font())
        kept = lines[: self.lines]
        if len(lines) > self.lines:
            rest = " ".join(lines[self.lines - 1:])
            kept[-1] = self.fontMetrics().elidedText(rest, Qt.TextElideMode.ElideRight, max(1, width - 4))
        colour = _COLOUR.search(full)
        body = "<br>".join(html.escape(line) for line in kept)
        super().setText(f"<span style='color:{colour.group(1)}'>{body}</span>" if colour else body)
        self.setToolTip(full)
