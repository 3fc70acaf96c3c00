"""The ```python blocks of a Markdown page, and which of them a CPU machine runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NEEDS = re.compile(r"#\s*needs (a GPU|hardware|a display|a cluster)\b")
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def python_blocks(page: Path) -> list[tuple[int, str]]:
    """``(line, source)`` of every python block of ``page`` (line: where its code starts)."""
    text = page.read_text(encoding="utf-8")
    return [(text.count("\n", 0, m.start(1)) + 1, m.group(1)) for m in _BLOCK.finditer(text)]


def skipped(source: str) -> bool:
    """True for a block whose first line says it needs a GPU, hardware, a display or a cluster."""
    first = source.lstrip().splitlines()[0] if source.strip() else ""
    return bool(NEEDS.fullmatch(first.strip()))
