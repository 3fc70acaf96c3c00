"""Questions the application asks before it does something that cannot be undone.

One function, :func:`ask`, for every such question (replace an existing file, record uncalibrated,
quit while a recording runs, black out the only screen): a message box with a button that names
the action and one that does not do it. The question names what would happen ("Replace
/data/cal.json?").

Scripts that drive the window (the session test, ``make screenshots``) answer through
:func:`answering`; where no one can answer (Qt's offscreen platform without :func:`answering`),
:func:`ask` raises :class:`Unanswered` instead of waiting for a click that cannot come.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from PySide6.QtCore import QTimer
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QMessageBox, QWidget

_logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Question:
    """A question as it was asked: its title, its text and the button that says yes."""

    title: str
    text: str
    accept: str


class Unanswered(RuntimeError):
    """A question was asked where no one can answer it (offscreen, outside :func:`answering`)."""


class _Script:
    def __init__(self, replies, default):
        self.replies = list(replies)
        self.default = default
        self.asked: list[Question] = []

    def reply(self, q: Question) -> bool:
        self.asked.append(q)
        if self.replies:
            r = self.replies.pop(0)
        elif self.default is not None:
            r = self.default
        else:
            raise Unanswered(f"no answer was given for the question {q.title!r}: {q.text}")
        return bool(r(q) if callable(r) else r)


_SCRIPT: _Script | None = None


@contextmanager
def answering(*replies: bool | Callable[[Question], bool], default: bool | None = None) -> Iterator[list[Question]]:
    """Answer the questions asked inside the ``with`` block: ``replies`` in order (True: the accept button),
    then ``default`` (None: a further question raises :class:`Unanswered`). Yields the list of the questions
    asked."""
    global _SCRIPT
    outer, _SCRIPT = _SCRIPT, _Script(replies, default)
    try:
        yield _SCRIPT.asked
    finally:
        _SCRIPT = outer


def question_box(parent: QWidget | None, title: str, text: str, *, accept: str, reject: str = "Cancel",
                 update: Callable[[], str] | None = None) -> QMessageBox:
    """The message box :func:`ask` shows (not yet shown); with ``update``, its text follows ``update()`` twice a
    second while it is open (a recording's frame count goes on while the operator reads)."""
    box = QMessageBox(QMessageBox.Icon.Question, title, text, QMessageBox.StandardButton.NoButton, parent)
    box.yes = box.addButton(accept, QMessageBox.ButtonRole.AcceptRole)
    no = box.addButton(reject, QMessageBox.ButtonRole.RejectRole)
    box.setDefaultButton(no)
    box.setEscapeButton(no)
    if update is not None:
        timer = QTimer(box)
        timer.setInterval(500)
        timer.timeout.connect(lambda: box.setText(update()))
        timer.start()
    return box


def ask(parent: QWidget | None, title: str, text: str, *, accept: str, reject: str = "Cancel",
        update: Callable[[], str] | None = None) -> bool:
    """Ask ``text``; True when the operator pressed ``accept`` (the default button is ``reject``). ``update``: the
    text as it is now, shown while the question is open (see :func:`question_box`)."""
    question = Question(title, text, accept)
    _logger.info("asking: %s: %s", title, text)
    if _SCRIPT is not None:
        answer = _SCRIPT.reply(question)
        _logger.info("answered %s", accept if answer else reject)
        return answer
    if QGuiApplication.platformName() == "offscreen":
        raise Unanswered(f"no one can answer the question {title!r} offscreen: {text}")
    box = question_box(parent, title, text, accept=accept, reject=reject, update=update)
    box.exec()
    answer = box.clickedButton() is box.yes
    _logger.info("answered %s", accept if answer else reject)
    return answer


def replace_question(parent: QWidget | None, path, what: str) -> bool:
    """The one rule for an existing file: ask before replacing it, naming it. ``what``: "calibration",
    "recording", "export" … True: replace it."""
    return ask(parent, f"Replace the existing {what}?",
               f"{path} already exists. Replace it with the new {what}?",
               accept="Replace", reject="Keep it")
