"""A status line that keeps its height: the buttons below it never move when its text changes.

A word-wrapped label grows with its text, and everything under it moves (a button the operator was
about to click moved 28 px). :class:`StatusLine` has a fixed height of ``lines`` lines: a text that
fits is shown as it is (rich text, colours kept); a longer one is cut to the lines with "…" at the
end, each part keeping its own colour and weight (a red refusal at the end never reddens what comes
before it), and the whole text is the tooltip. :meth:`StatusLine.text` returns the whole text.
"""

from __future__ import annotations

import html

from PySide6.QtCore import Qt
from PySide6.QtGui import QFont, QTextDocument
from PySide6.QtWidgets import QLabel, QSizePolicy, QWidget


def rich_prefix(doc: QTextDocument, n: int) -> str:
    """The first ``n`` characters of ``doc``'s text as rich text, each run keeping its colour and weight."""
    out: list[str] = []
    left = int(n)
    block = doc.begin()
    while block.isValid() and left > 0:
        if out:
            out.append("<br>")
            left -= 1
        for it in block:
            fragment = it.fragment()
            if left <= 0:
                break
            if not fragment.isValid():
                continue
            text = fragment.text()[:left]
            left -= len(text)
            fmt = fragment.charFormat()
            piece = html.escape(text).replace("\u2028", "<br>")
            if fmt.fontWeight() >= QFont.Weight.Bold:
                piece = f"<b>{piece}</b>"
            if fmt.foreground().style() != Qt.BrushStyle.NoBrush:
                piece = f"<span style='color:{fmt.foreground().color().name()}'>{piece}</span>"
            out.append(piece)
        block = block.next()
    return "".join(out)


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
        # The longest start of the text that fits with "…" after it (binary search on its length).
        lo, hi = 0, doc.characterCount()
        while lo < hi:
            mid = (lo + hi + 1) // 2
            super().setText(rich_prefix(doc, mid).rstrip() + "…")
            if super().heightForWidth(self.width()) <= self.height():
                lo = mid
            else:
                hi = mid - 1
        super().setText(rich_prefix(doc, lo).rstrip() + "…")
        self.setToolTip(full)
